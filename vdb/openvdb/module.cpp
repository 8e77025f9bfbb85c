// The OpenVDB module's one export: its table of functions (vdb/detail/openvdb_module.h).
#include "vdb/openvdb/openvdb_parts.h"

namespace distile::detail {
namespace {

constexpr OpenVdbFunctions kFunctions{
    levelSetFromDistanceRows, loadLevelSet, levelSetFromMesh, buildDisplacedMesh,
    buildDisplacedLevelSet,   readVolume,   listVdbGrids,     writeSphereVolumes};

}  // namespace
}  // namespace distile::detail

extern "C" __attribute__((visibility("default"))) const void* distile_vdb_openvdb_module() {
    return &distile::detail::kFunctions;
}
