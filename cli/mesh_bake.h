/// @file
/// The one bake path for closed detail meshes, shared by `distile bake mesh` and the scene recipe
/// `"tile": {"bake": "mesh", ...}`: refuse meshes without an inside, bake with the exact inside
/// test and the exact distance of the placed mesh (truth/mesh_truth.h), then verify the sign.
#pragma once

#include <filesystem>
#include <string>

#include "common/progress.h"
#include "common/triangle_soup.h"
#include "sampler/bake.h"

namespace distile::cli {

/// Reads a detail mesh (mesh/detail_mesh.h) and checks that it is a solid; warns on stderr about
/// degenerate faces and self-intersections.
/// @throws InputError naming the file: the mesh is open, non-manifold or not orientable.
/// @throws FormatError as loadDetailMesh.
TriangleSoup loadSolidDetailMesh(const std::filesystem::path& file);

/// Number of voxels whose sign bakeSolidMesh verifies against the exact inside test.
inline constexpr int kSignCheckVoxels = 10000;

struct SolidMeshBake {
    BakeResult result;
    int signCheckedVoxels = 0;  ///< voxels of the sign verification (those near the surface skip)
};

/// Bakes `mesh` (file units, from loadSolidDetailMesh) placed by `placement`, with exact signs
/// near the surface and the exact distance for the conservative correction (sampler/bake.h
/// bakeMesh), then verifies the sign at up to kSignCheckVoxels random voxels. `file` names the
/// mesh in messages.
/// @throws InputError as placeMesh, or the mesh has no inside.
/// @throws std::runtime_error the sign verification fails.
SolidMeshBake bakeSolidMesh(const TriangleSoup& mesh, const MeshPlacement& placement,
                            const BakeOptions& options, const std::string& file,
                            const ProgressCallback& progress = {});

}  // namespace distile::cli
