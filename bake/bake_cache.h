/// @file
/// Tiles that scenes bake (`"tile": {"bake": ...}`), kept on disk so that rendering a scene again
/// bakes nothing. A baked tile is a pure function of its recipe: the detail's parameters, the
/// tile size, the conservative resampling and the bake code's revision. The recipe's FNV-1a hash
/// names the file. Only tiles a scene references are baked, each once per process (TileCache).
///
/// Folder: $DISTILE_CACHE, else $XDG_CACHE_HOME/distile, else $HOME/.cache/distile;
/// DISTILE_CACHE=off disables the cache. A cache that cannot be read or written is skipped (the
/// tile is baked as without one); a cached file that fails readTileExr's checks, or was stored
/// for another recipe, is baked again and replaced.
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "sampler/tile.h"

namespace distile {

/// Bump when the bake's output for the same recipe changes (a new conservative correction, a
/// different resampling): cached tiles of older revisions are then never read.
inline constexpr int kBakeRevision = 6;

/// FNV-1a 64 of `bytes` as 16 hex digits: names a recipe's cached tile, and stands for the
/// content of an input file (a detail mesh) inside a recipe.
std::string contentHash(std::string_view bytes);

/// The cache folder as the file note says, or nothing when disabled or no home is known.
std::optional<std::filesystem::path> bakeCacheFolder();

/// The tile of `recipe`: read from the cache when present, valid and stored for this recipe
/// (distile:recipe_hash), else `bake()` (then stored, atomically). `recipe` must name everything
/// the tile depends on. A recipe that names an input file by its bytes passes their contentHash
/// as `sourceHash`: a tile whose provenance records other bytes (the file was replaced while it
/// was baked) is returned but not stored.
std::shared_ptr<const Tile> cachedBake(const std::string& recipe, const std::function<Tile()>& bake,
                                       const std::string& sourceHash = {});

}  // namespace distile
