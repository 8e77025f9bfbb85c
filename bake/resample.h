/// @file
/// Resampling a level set into a dense tile.
#pragma once

#include "bake/conservative.h"
#include "sampler/tile.h"
#include "vdb/level_set.h"

namespace distile {

/// The tile of the level set's footprint: the level set's voxels are texel-aligned (voxel
/// (i, j, k) at texel centre (i+0.5, j+0.5, k+0.5)), so each texel takes its voxel's value,
/// exactly. Texels outside the narrow band hold +/- the half band width. Provenance comes from the
/// level set. Then, by default, the texels are lowered so trilinear interpolation does not
/// overestimate (bake/conservative.h: measured against `exactDistances`, the detail's exact
/// signed distances, when given, estimated otherwise; `conservative.enabled = false` keeps the
/// exact voxel values). Throws InputError for bad conservative options.
Tile tileFromLevelSet(const LevelSet& levelSet, const ConservativeOptions& conservative = {},
                      const ExactDistancesOnLine& exactDistances = {});

}  // namespace distile
