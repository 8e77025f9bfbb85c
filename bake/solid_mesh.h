/// @file
/// The one bake path for detail meshes, shared by every program that bakes them (the
/// `bake mesh` command, a scene's `"bake": "mesh"` tile): the exact distance to the placed mesh
/// at every texel centre, signed by the generalized winding number (bake/soup_distance.h), so
/// closed solids, open meshes, soups of overlapping parts and duplicated or flipped faces all
/// bake; or the unsigned distance for sheet-like detail that has no inside.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "common/progress.h"
#include "common/triangle_soup.h"

namespace distile {

/// How the distances of a mesh bake are signed.
struct MeshSignOptions {
    /// false: negative where the generalized winding number exceeds 1/2 (inside).
    /// true: sheet-like detail without an inside: the surface is a shell of
    /// `thicknessTexels` around the triangles (distance = unsigned distance - thickness / 2), so
    /// with thickness 0 the tile is never negative and its zero set is the triangles themselves.
    bool unsignedDistance = false;
    double thicknessTexels = 0.0;  ///< unsignedDistance only: shell thickness, texels, >= 0
};

/// A detail mesh read for baking, and what is odd about it without stopping a bake.
struct SolidDetailMesh {
    TriangleSoup mesh;  ///< file units
    /// One line each, naming the file: degenerate (zero-area) faces and, for a mesh signed by
    /// its winding number, open or non-manifold parts and self-intersections. The caller shows
    /// them (the library writes nothing to the terminal).
    std::vector<std::string> warnings;
};

/// Reads a detail mesh (mesh/detail_mesh.h) and inspects it (truth/mesh_truth.h inspectMesh):
/// what is not a clean solid becomes a warning, since the winding-number sign copes with it.
/// Baked with `sign` unsigned, the mesh has no inside to find: being open, non-manifold or
/// self-intersecting is then no warning (a sheet is open).
/// @throws FormatError as loadDetailMesh.
SolidDetailMesh loadSolidDetailMesh(const std::filesystem::path& file, const MeshSignOptions& sign);

struct SolidMeshBake {
    BakeResult result;
    std::size_t insideTexels = 0;  ///< texels of the tile with a negative exact distance
};

/// Bakes `mesh` (file units) placed by `placement` (placeMesh): every voxel of the level set
/// (the tile and, when options.fillLevelSetMargins, its band margin above and below,
/// LevelSet::fromDistanceRows) takes the exact
/// periodic distance to the placed mesh's surface (signed: the boundary of its inside, i.e. the
/// triangles that bound it and caps over its holes, bake/mesh_surface.h; unsigned: its
/// triangles), signed as `sign` says, clamped to the half band; the
/// conservative correction measures against the same exact distance (bake/conservative.h).
/// Multi-threaded; the result does not depend on the thread count. `file` names the mesh in
/// messages.
/// @throws InputError as placeMesh; field "sign.thicknessTexels" when it is negative, not
///   finite or thicker than the tile depth; field "sign.unsignedDistance" when the mesh has no
///   inside (no texel with a winding number above 1/2) and unsignedDistance is false.
SolidMeshBake bakeSolidMesh(const TriangleSoup& mesh, const MeshPlacement& placement,
                            const BakeOptions& options, const std::string& file,
                            const ProgressCallback& progress = {},
                            const MeshSignOptions& sign = {});

}  // namespace distile
