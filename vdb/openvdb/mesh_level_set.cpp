// The OpenVDB half of vdb/mesh_level_set.h, in the module (vdb/detail/openvdb_module.h).
#include "vdb/openvdb/openvdb_parts.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "common/error.h"
#include "vdb/openvdb/openvdb_mesh.h"

namespace distile::detail {

std::unique_ptr<LevelSetGrid> levelSetFromMesh(const TriangleSoup& meshTexels, const Size3& tile,
                                               float halfBandTexels, const std::string& source,
                                               const std::string& params,
                                               const ProgressCallback& progress,
                                               const InsideTest& insideTest) {
    openvdb::initialize();

    const OpenVdbMesh mesh = toOpenVdbIndexSpace(meshTexels);
    // OpenVDB's band is ragged at its outer voxels (some just inside the half width come back
    // as background); converting with 2 texels more and clamping to the half band afterwards
    // (levelSetFromDistanceRows does) makes every voxel inside the band exact.
    const auto transform = openvdb::math::Transform::createLinearTransform(1.0);
    const openvdb::FloatGrid::Ptr meshGrid = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(
        *transform, mesh.points, mesh.triangles, halfBandTexels + 2.0f);
    if (progress) progress(0.5);

    // Tile voxel (i, j, k) takes the minimum over the copies shifted by (m W, n H) whose
    // bounding box comes within the band: voxel (i - m W, j - n H, k) of the unshifted grid.
    // Tree reads are thread-safe (no shared accessor).
    const Bounds3 box = boundsOf(meshTexels);
    const openvdb::FloatTree& tree = meshGrid->tree();
    const double reach = double(halfBandTexels) + 3.0;
    const auto distance = [&](const glm::dvec3& texel) {
        const int i = int(std::floor(texel.x));
        const int j = int(std::floor(texel.y));
        const int k = int(std::floor(texel.z));
        const PeriodicShifts shifts = periodicShifts(texel, box, tile, reach);
        float nearest = halfBandTexels + 2.0f;
        for (int m = shifts.xBegin; m <= shifts.xEnd; ++m) {
            for (int n = shifts.yBegin; n <= shifts.yEnd; ++n) {
                const openvdb::Coord voxel(i - m * tile.width, j - n * tile.height, k);
                nearest = std::min(nearest, tree.getValue(voxel));
            }
        }
        // Near the surface OpenVDB's sign may be wrong; an exact inside test overrides it.
        if (insideTest && std::abs(nearest) < 1.0f) {
            return insideTest(texel) ? -std::abs(double(nearest)) : std::abs(double(nearest));
        }
        return double(nearest);
    };
    const ProgressCallback resampleProgress =
        progress ? ProgressCallback([&](double done) { progress(0.5 + 0.5 * done); })
                 : ProgressCallback();
    return levelSetFromDistanceRows(
        [&distance](int j, int k, std::span<double> row) {
            for (std::size_t i = 0; i < row.size(); ++i)
                row[i] = distance(glm::dvec3(double(i) + 0.5, j + 0.5, k + 0.5));
        },
        tile, halfBandTexels, source, params, resampleProgress, /*fillMargins=*/true);
}

}  // namespace distile::detail
