/// @file
/// Internal to vdb/: the part of it that uses OpenVDB, built as the module
/// libdistile_vdb_openvdb.so (common/detail/module_loader.h) and loaded the first time a level
/// set is built, read or written. OpenVDB's library alone took 0.05-0.07 s of dynamic linking at
/// the start of every process (68 thousand symbol relocations), most of `distile --help` and of
/// a render's start, which never touch it. vdb/'s classes keep their interfaces; their OpenVDB
/// halves are the interfaces below, made by the module's table of functions.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/progress.h"
#include "common/size3.h"
#include "common/triangle_soup.h"
#include "vdb/displaced_level_set.h"
#include "vdb/level_set.h"
#include "vdb/mesh_level_set.h"
#include "vdb/vdb_volume.h"

namespace distile::detail {

/// A level set's sparse grid (vdb/level_set.h: texel space, named, with its metadata).
class LevelSetGrid {
  public:
    virtual ~LevelSetGrid() = default;
    virtual float halfBandTexels() const = 0;
    virtual std::size_t activeVoxelCount() const = 0;
    virtual float voxelDistanceTexels(int i, int j, int k) const = 0;
    /// The voxels of the tile `tile` (x fastest), into `texels`.
    virtual void copyTileVoxels(const Size3& tile, std::span<float> texels) const = 0;
    /// LevelSet::repeated's grid, the counts already checked.
    virtual std::unique_ptr<LevelSetGrid> repeated(const Size3& tile, int repeatX, int repeatY,
                                                   const std::string& source,
                                                   const std::string& params) const = 0;
    /// Writes the grid to `file` (a .vdb of one grid).
    virtual void write(const std::filesystem::path& file) const = 0;
};

/// A level set: its grid and what its metadata says (LevelSet holds one).
struct LevelSetParts {
    std::unique_ptr<LevelSetGrid> grid;
    Size3 tile;
    std::string source, params;
};

/// The samples of a volume in texel space (vdb/vdb_volume.h, VdbSourceSampler).
class VolumeSampler {
  public:
    virtual ~VolumeSampler() = default;
    virtual VdbSourceSampler::Sample sample(const glm::dvec3& texelPosition) const = 0;
    virtual double bandTexels() const = 0;
};

/// A volume's grid (vdb/vdb_volume.h, VdbVolume).
class VolumeGrid {
  public:
    virtual ~VolumeGrid() = default;
    virtual glm::dvec3 voxelSizeWorld() const = 0;
    /// VdbVolume::refinedSurfaceWorld of the volume whose iso surface is `coarse` at `iso`.
    virtual TriangleSoup refinedSurfaceWorld(const TriangleSoup& coarse, double iso,
                                             double maxEdgeWorld,
                                             const Bounds3& regionWorld) const = 0;
    /// A sampler of the volume (a level set, or else a fog volume whose iso is `iso`), the
    /// placement already checked.
    virtual std::unique_ptr<VolumeSampler> sampler(bool levelSet, double iso,
                                                   const TexelPlacement& placement) const = 0;
};

/// A volume read from a file (VdbVolume::read), with what VdbVolume reports of it.
struct ReadVolume {
    std::unique_ptr<VolumeGrid> grid;
    std::string name;
    bool levelSet = true;
    double iso = 0.0;
    Bounds3 activeBounds, surfaceBounds;
    TriangleSoup surface;  ///< the polygonised iso crossing, world units
};

/// Voxels coarser than four texels miss the detail altogether (and rays take ever longer to
/// cross them).
inline constexpr double kMinVoxelsPerTexel = 0.25;

/// Throws InputError unless `options` are accepted (before the mesh is built, and again by the
/// module).
inline void validateDisplacedLevelSetOptions(const DisplacedLevelSetOptions& options) {
    if (options.voxelsPerTexel != 0.0 &&
        !(options.voxelsPerTexel >= kMinVoxelsPerTexel && options.voxelsPerTexel <= 16.0)) {
        throw InputError(
            "world reference mesh: voxels per texel: " + numberText(options.voxelsPerTexel) +
            " is not in [0.25, 16] (or 0: the finest up to 2 that fits 1 GiB)");
    }
    if (!(options.halfBandVoxels >= 2.0f && options.halfBandVoxels <= 16.0f)) {
        throw InputError("world reference mesh: half band: " +
                         std::to_string(options.halfBandVoxels) + " voxels is not in [2, 16]");
    }
}

/// A displaced mesh's world level set (vdb/displaced_level_set.h).
class DisplacedGrid {
  public:
    virtual ~DisplacedGrid() = default;
    virtual bool intersect(const glm::dvec3& origin, const glm::dvec3& unitDirection,
                           double maxDistanceWorld, double& distanceWorld,
                           glm::dvec3& normalWorld) const = 0;
};

/// A displaced level set as built, with its figures.
struct BuiltDisplacedLevelSet {
    std::unique_ptr<DisplacedGrid> grid;
    DisplacedLevelSetStats stats;
};

/// The module's functions: each does what the vdb/ function or constructor of the same name
/// does (and throws the same errors); the callers check what needs no OpenVDB first.
struct OpenVdbFunctions {
    std::unique_ptr<LevelSetGrid> (*levelSetFromDistanceRows)(
        const LevelSet::RowDistanceFunction& rowDistance, const Size3& tile, float halfBandTexels,
        const std::string& source, const std::string& params, const ProgressCallback& progress,
        bool fillMargins);
    LevelSetParts (*loadLevelSet)(const std::filesystem::path& file);
    std::unique_ptr<LevelSetGrid> (*levelSetFromMesh)(const TriangleSoup& meshTexels,
                                                      const Size3& tile, float halfBandTexels,
                                                      const std::string& source,
                                                      const std::string& params,
                                                      const ProgressCallback& progress,
                                                      const InsideTest& insideTest);
    DisplacedMesh (*buildDisplacedMesh)(const DetailDistanceFunction& detail, const Size3& tile,
                                        const DisplacementShell& shell,
                                        const DisplacedMeshOptions& options);
    BuiltDisplacedLevelSet (*buildDisplacedLevelSet)(const DisplacedMesh& mesh,
                                                     const DisplacedLevelSetOptions& options);
    ReadVolume (*readVolume)(const std::filesystem::path& file, const std::string& gridName,
                             std::optional<double> iso);
    std::vector<VdbGridInfo> (*listVdbGrids)(const std::filesystem::path& file);
    void (*writeSphereVolumes)(const std::filesystem::path& file,
                               const std::vector<SphereVolumeOptions>& spheres);
};

/// The name the module exports its table under: `const void* NAME()`, an OpenVdbFunctions.
inline constexpr const char* kOpenVdbModuleEntry = "distile_vdb_openvdb_module";

/// The module's table, loaded on the first call. Throws InternalError if it cannot be loaded.
const OpenVdbFunctions& openVdb();

/// requireRegularFile for a .vdb file the module is about to read, on this side of it: the
/// module holds its own copy of common/'s record of the command's inputs, so without this a
/// command could write an output over the .vdb file it read.
void requireVdbInput(const std::filesystem::path& file);

}  // namespace distile::detail
