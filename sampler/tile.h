/// @file
/// The distance tile: a dense W x H x D block of signed distances in texel units (negative
/// inside material), periodic in x and y, with texel (i, j, k) centred at (i+0.5, j+0.5, k+0.5)
/// in texel space. z = D is the top (the base surface), z = 0 the floor. Layout: x fastest, then
/// y, then z.
#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/size3.h"

namespace distile {

/// What a tile was made from; stored in the EXR header (see docs/tile_format.md).
struct TileProvenance {
    std::string source;  ///< e.g. "chainmail", "mesh", "heightmap"
    std::string params;  ///< the source's parameters as JSON text
    /// The input file the tile was baked from (a mesh, a height map, a level set); empty for
    /// procedural detail. Absolute in memory; a tile file records it relative to its own folder
    /// (distile:source_file).
    std::filesystem::path sourceFile;
    /// FNV-1a 64 of the source file's bytes as 16 hex digits (distile:source_hash); empty when
    /// sourceFile is.
    std::string sourceHash;
    /// Half width of the narrow band the tile was resampled from, texels (distile:band_texels):
    /// its distances beyond it are clamped to +-this, so it is what the tile can tell about its
    /// source. 0 when unknown (tiles written before the attribute existed).
    double halfBandTexels = 0.0;
    /// What a check against the detail's truth found when the tile was baked (distile:check),
    /// one line: kCheckWithin or kCheckBeyond, ": ", then the figures. Bakes of procedural detail
    /// record it (check/tile_check.h recordAnalyticCheck); empty when none was made.
    std::string check;
    /// The bake cache's name of the recipe the tile was baked for (bake/bake_cache.h,
    /// distile:recipe_hash): set in the cache's own files only, so that a file of another recipe
    /// put in its place is not taken for it. Empty elsewhere.
    std::string recipeHash;
    static constexpr std::string_view kCheckWithin = "within tolerances";
    static constexpr std::string_view kCheckBeyond = "beyond tolerances";
};

class Tile {
  public:
    /// A tile of `size` texels, all distances set to `fillTexels`. Throws InputError for sizes
    /// validateTileSize() rejects.
    explicit Tile(const Size3& size, float fillTexels = 0.0f);

    const Size3& size() const { return size_; }

    /// Index of texel (x, y, z) in distancesTexels(); x fastest. Preconditions: 0 <= x < W etc.
    std::size_t index(int x, int y, int z) const {
        return std::size_t(x) + std::size_t(size_.width) *
                                    (std::size_t(y) + std::size_t(size_.height) * std::size_t(z));
    }
    float at(int x, int y, int z) const { return distances_[index(x, y, z)]; }
    float& at(int x, int y, int z) { return distances_[index(x, y, z)]; }

    std::span<const float> distancesTexels() const { return distances_; }
    std::span<float> distancesTexels() { return distances_; }

    TileProvenance provenance;

  private:
    Size3 size_;
    std::vector<float> distances_;
};

}  // namespace distile
