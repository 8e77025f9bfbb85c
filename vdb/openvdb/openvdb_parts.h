/// @file
/// Internal to the OpenVDB module (vdb/detail/openvdb_module.h): the functions its table holds,
/// each defined in the file of its subject.
#pragma once

#include "vdb/detail/openvdb_module.h"

namespace distile::detail {

// level_set_grid.cpp
std::unique_ptr<LevelSetGrid> levelSetFromDistanceRows(
    const LevelSet::RowDistanceFunction& rowDistance, const Size3& tile, float halfBandTexels,
    const std::string& source, const std::string& params, const ProgressCallback& progress,
    bool fillMargins);
LevelSetParts loadLevelSet(const std::filesystem::path& file);

// mesh_level_set.cpp
std::unique_ptr<LevelSetGrid> levelSetFromMesh(const TriangleSoup& meshTexels, const Size3& tile,
                                               float halfBandTexels, const std::string& source,
                                               const std::string& params,
                                               const ProgressCallback& progress,
                                               const InsideTest& insideTest);

// displaced_level_set.cpp
DisplacedMesh buildDisplacedMesh(const DetailDistanceFunction& detail, const Size3& tile,
                                 const DisplacementShell& shell,
                                 const DisplacedMeshOptions& options);
BuiltDisplacedLevelSet buildDisplacedLevelSet(const DisplacedMesh& mesh,
                                              const DisplacedLevelSetOptions& options);

// vdb_volume.cpp
ReadVolume readVolume(const std::filesystem::path& file, const std::string& gridName,
                      std::optional<double> iso);
std::vector<VdbGridInfo> listVdbGrids(const std::filesystem::path& file);
void writeSphereVolumes(const std::filesystem::path& file,
                        const std::vector<SphereVolumeOptions>& spheres);

}  // namespace distile::detail
