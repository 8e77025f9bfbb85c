/// @file
/// Narrow-band signed distance level sets (OpenVDB FloatGrid) in texel units, and their .vdb
/// files, built with OpenVDB (loaded on first use, vdb/detail/openvdb_module.h); the rest of
/// distile uses this class.
///
/// Index and world space of the grid are texel space of the tile: voxel size 1 texel, voxel
/// (i, j, k) centred at (i + 0.5, j + 0.5, k + 0.5). The grid is a level set (grid class
/// GRID_LEVEL_SET, background = half band width), named "surface", and carries the tile size and
/// provenance as metadata, so vdb_print, Houdini and Blender read it as an ordinary level set.
#pragma once

#include <filesystem>
#include <functional>
#include <glm/vec3.hpp>
#include <memory>
#include <span>
#include <string>

#include "common/progress.h"
#include "common/size3.h"

namespace distile {

namespace detail {
struct LevelSetParts;
}

class LevelSet {
  public:
    /// Exact signed distance in texels at a texel-space position.
    using DistanceFunction = std::function<double(const glm::dvec3& texelPosition)>;

    /// Samples `distance` at every voxel of the tile, plus `halfBandTexels` voxels of margin
    /// above the top and below the floor so the band closes around detail near them. Voxels with
    /// |distance| < halfBandTexels are active; others are inactive at +/- halfBandTexels.
    /// `distance` is called concurrently from several threads. Deterministic for any thread
    /// count. Throws InputError for a bad size or a half band below 1 texel.
    static LevelSet fromDistance(const DistanceFunction& distance, const Size3& tile,
                                 float halfBandTexels, const std::string& source,
                                 const std::string& params, const ProgressCallback& progress = {});

    /// Fills `distancesTexels` (W values) with the exact signed distance, texels, at the texel
    /// centres (i + 0.5, j + 0.5, k + 0.5) of row (j, k), i = 0..W-1. A row lets the caller reuse
    /// work between neighbours (the distance is 1-Lipschitz).
    using RowDistanceFunction =
        std::function<void(int j, int k, std::span<double> distancesTexels)>;

    /// fromDistance with the distances given a row at a time; `rowDistance` is called
    /// concurrently for different rows. Same voxels, band and errors as fromDistance; with
    /// `fillMargins` false the rows of the margin are not asked for and stay inactive at the
    /// background (for a level set of which only the tile's voxels are read).
    static LevelSet fromDistanceRows(const RowDistanceFunction& rowDistance, const Size3& tile,
                                     float halfBandTexels, const std::string& source,
                                     const std::string& params,
                                     const ProgressCallback& progress = {},
                                     bool fillMargins = true);

    /// Reads the grid named "surface" (or the first float level set) of a .vdb file written by
    /// save(). Throws InputError for a missing file, FormatError for anything unreadable or not
    /// a distile level set.
    static LevelSet load(const std::filesystem::path& file);

    /// The level set tiled `repeatX` x `repeatY` times in x and y (world units = texels): voxel
    /// (i + m W, j + n H, k) holds voxel (i, j, k) for 0 <= m < repeatX, 0 <= n < repeatY. The tile
    /// is periodic, so the copy is exact and seamless; its distile:size is (repeatX W) x
    /// (repeatY H) x D, provenance and band as this one. Throws InputError unless both counts are
    /// in [1, 64] and the result has at most 2^28 voxels (1 GiB).
    LevelSet repeated(int repeatX, int repeatY) const;

    /// Throws InputError::inField("repeatX, repeatY", ...) as repeated() does, for a level set of
    /// `tile` whose half band is `halfBandTexels`: before the level set exists.
    static void checkRepeat(const Size3& tile, float halfBandTexels, int repeatX, int repeatY);

    /// Writes the grid to `file` atomically (see common/atomic_file.h).
    void save(const std::filesystem::path& file) const;

    LevelSet(LevelSet&&) noexcept;
    LevelSet& operator=(LevelSet&&) noexcept;
    ~LevelSet();

    const Size3& tileSize() const;
    float halfBandTexels() const;
    const std::string& source() const;
    const std::string& params() const;
    std::size_t activeVoxelCount() const;

    /// Distance stored at voxel (i, j, k) (background outside the band), texels.
    float voxelDistanceTexels(int i, int j, int k) const;

    /// Copies the voxels of the tile's footprint, [0,W) x [0,H) x [0,D), into `texels` (size
    /// W*H*D, x fastest: the Tile layout). Precondition: texels.size() == tileSize().texelCount().
    void copyTileVoxels(std::span<float> texels) const;

    /// Internal: a level set from its parts, as the OpenVDB module (vdb/detail/openvdb_module.h)
    /// makes them.
    explicit LevelSet(detail::LevelSetParts parts);

  private:
    std::unique_ptr<detail::LevelSetParts> parts_;
};

}  // namespace distile
