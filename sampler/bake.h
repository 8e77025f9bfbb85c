/// @file
/// Baking: detail source -> exact narrow-band level set -> dense tile.
#pragma once

#include "common/progress.h"
#include "sampler/tile.h"
#include "vdb/chainmail.h"
#include "vdb/level_set.h"

namespace distile {

struct BakeOptions {
    Size3 size{256, 256, 16};
    /// Half width of the level set's narrow band, texels; 0 means the tile depth, so the band
    /// covers every texel of the tile.
    float halfBandTexels = 0.0f;
};

struct BakeResult {
    LevelSet levelSet;
    Tile tile;
};

/// Chain mail (vdb/chainmail.h) baked into a level set and its tile. Throws InputError for bad
/// sizes or chain-mail options.
BakeResult bakeChainmail(const ChainmailOptions& chainmail, const BakeOptions& options,
                         const ProgressCallback& progress = {});

}  // namespace distile
