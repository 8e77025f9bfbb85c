#include "bake/solid_mesh.h"

#include <random>
#include <sstream>
#include <stdexcept>
#include <string>

#include "common/error.h"
#include "mesh/detail_mesh.h"
#include "truth/mesh_truth.h"

namespace distile {

namespace {

/// Voxels nearer the surface than this (texels) are skipped by the check: there OpenVDB's inside
/// test is approximate (the bake takes their sign from the exact test anyway).
constexpr double kSignCheckSkipTexels = 0.1;

}  // namespace

SolidDetailMesh loadSolidDetailMesh(const std::filesystem::path& path) {
    const std::string file = path.string();
    SolidDetailMesh solid{loadDetailMesh(path), {}};
    const MeshTopology topology = inspectMesh(solid.mesh);
    if (!topology.closed || !topology.manifold) {
        std::ostringstream message;
        message << file << ": the mesh is ";
        if (!topology.closed) message << "open (" << topology.boundaryEdges << " boundary edges)";
        if (!topology.closed && !topology.manifold) message << " and ";
        if (!topology.manifold) message << "non-manifold or not orientable";
        message << "; bake mesh accepts closed, manifold triangle meshes (a solid with an inside)";
        throw InputError(message.str());
    }
    if (topology.degenerateFaces > 0) {
        solid.warnings.push_back(file + ": " + std::to_string(topology.degenerateFaces) +
                                 " degenerate (zero-area) faces");
    }
    if (topology.selfIntersecting) {
        solid.warnings.push_back(file +
                                 ": the mesh intersects itself; inside is where the exact test "
                                 "says");
    }
    return solid;
}

SolidMeshBake bakeSolidMesh(const TriangleSoup& mesh, const MeshPlacement& placement,
                            const BakeOptions& options, const std::string& file,
                            const ProgressCallback& progress) {
    const TriangleSoup placed = placeMesh(mesh, placement, options.size);
    const MeshDistance truth(placed, MeshDistance::Periodic{options.size});
    if (!truth.hasSign()) {
        throw InputError(
            file +
            ": the mesh has no inside (CGAL could not close it); bake mesh accepts closed, "
            "manifold triangle meshes");
    }
    // The exact inside test fixes the signs near the surface; the exact distance lets the
    // conservative correction measure the trilinear overestimate (bake/conservative.h).
    SolidMeshBake bake{bakeMesh(
        mesh, placement, options, progress,
        [&truth](const glm::dvec3& p) { return truth.isInside(p); },
        [&truth](const glm::dvec3& p) { return truth.signedDistance(p); })};

    // Verify the sign at random voxels of the footprint against the exact inside test.
    const Size3& size = options.size;
    std::mt19937 random(20240603u);
    std::uniform_int_distribution<int> pickX(0, size.width - 1), pickY(0, size.height - 1),
        pickZ(0, size.depth - 1);
    int wrong = 0;
    glm::dvec3 firstWrong(0.0);
    for (int n = 0; n < kSignCheckVoxels; ++n) {
        const int x = pickX(random), y = pickY(random), z = pickZ(random);
        const glm::dvec3 centre(x + 0.5, y + 0.5, z + 0.5);
        if (truth.unsignedDistance(centre) < kSignCheckSkipTexels) continue;
        ++bake.signCheckedVoxels;
        const bool bakedInside = bake.result.levelSet.voxelDistanceTexels(x, y, z) < 0.0f;
        if (bakedInside != truth.isInside(centre)) {
            if (wrong++ == 0) firstWrong = centre;
        }
    }
    if (wrong > 0) {
        std::ostringstream message;
        message << file << ": sign verification failed: " << wrong << " of "
                << bake.signCheckedVoxels
                << " voxels have the wrong sign against the exact inside test (first at texel "
                << firstWrong.x << ", " << firstWrong.y << ", " << firstWrong.z
                << "); its inside cannot be trusted, nothing written";
        throw InputError(message.str());
    }
    return bake;
}

}  // namespace distile
