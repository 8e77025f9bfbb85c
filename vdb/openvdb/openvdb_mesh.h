/// @file
/// Internal to vdb/: a texel-space triangle soup as OpenVDB mesh-to-volume input.
#pragma once

#include <openvdb/openvdb.h>

#include <vector>

#include "common/triangle_soup.h"

namespace distile::detail {

/// OpenVDB index space of distile's unit-voxel grids: voxel (i, j, k) is centred at texel
/// (i + 0.5, j + 0.5, k + 0.5), so a texel-space point p sits at index p - 0.5 under a unit
/// transform.
struct OpenVdbMesh {
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
};

inline OpenVdbMesh toOpenVdbIndexSpace(const TriangleSoup& meshTexels) {
    OpenVdbMesh mesh;
    mesh.points.reserve(meshTexels.positions.size());
    for (const glm::dvec3& p : meshTexels.positions) {
        mesh.points.emplace_back(float(p.x - 0.5), float(p.y - 0.5), float(p.z - 0.5));
    }
    mesh.triangles.reserve(meshTexels.triangles.size());
    for (const glm::uvec3& t : meshTexels.triangles) mesh.triangles.emplace_back(t.x, t.y, t.z);
    return mesh;
}

}  // namespace distile::detail
