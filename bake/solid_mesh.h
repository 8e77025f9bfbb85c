/// @file
/// The one bake path for closed detail meshes, shared by every program that bakes them (the
/// `bake mesh` command, a scene's `"bake": "mesh"` tile): refuse meshes without an inside, bake
/// with the exact inside test and the exact distance of the placed mesh (truth/mesh_truth.h),
/// then verify the sign.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "common/progress.h"
#include "common/triangle_soup.h"

namespace distile {

/// A detail mesh that is a solid, and what is odd about it without stopping a bake.
struct SolidDetailMesh {
    TriangleSoup mesh;  ///< file units
    /// One line each, naming the file: degenerate (zero-area) faces, self-intersections. The
    /// caller shows them (the library writes nothing to the terminal).
    std::vector<std::string> warnings;
};

/// Reads a detail mesh (mesh/detail_mesh.h) and checks that it is a solid.
/// @throws InputError naming the file: the mesh is open, non-manifold or not orientable.
/// @throws FormatError as loadDetailMesh.
SolidDetailMesh loadSolidDetailMesh(const std::filesystem::path& file);

/// Number of voxels whose sign bakeSolidMesh verifies against the exact inside test.
inline constexpr int kSignCheckVoxels = 10000;

struct SolidMeshBake {
    BakeResult result;
    int signCheckedVoxels = 0;  ///< voxels of the sign verification (those near the surface skip)
};

/// Bakes `mesh` (file units, from loadSolidDetailMesh) placed by `placement`, with exact signs
/// near the surface and the exact distance for the conservative correction (bake/bake.h
/// bakeMesh), then verifies the sign at up to kSignCheckVoxels random voxels. `file` names the
/// mesh in messages.
/// @throws InputError as placeMesh, the mesh has no inside, or the sign verification fails (the
///   mesh's inside cannot be trusted: refused input, like an open mesh).
SolidMeshBake bakeSolidMesh(const TriangleSoup& mesh, const MeshPlacement& placement,
                            const BakeOptions& options, const std::string& file,
                            const ProgressCallback& progress = {});

}  // namespace distile
