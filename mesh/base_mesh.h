/// @file
/// Base meshes: the triangle meshes distance detail is rendered on. A BaseMesh is a plain
/// indexed triangle list whose vertices carry one UV each (vertices are split along UV seams),
/// with per-vertex tangent frames. Loading goes through OpenMesh; nothing else in distile sees it.
///
/// Tangent-frame convention (the per-vertex MikkTSpace-style convention used by game engines):
/// N is the unit outward normal; T is the unit direction of dP/du projected into the plane
/// orthogonal to N; the bitangent is not stored but rebuilt as B = w * cross(N, T), where the
/// handedness w = sign(dot(cross(N, T), dP/dv)) is +1 or -1 (never 0). For a right-handed UV
/// layout (u to the right, v up, seen from outside) w = +1; mirrored UVs give w = -1.
#pragma once

#include <cstdint>
#include <filesystem>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <vector>

namespace distile {

struct BaseMesh {
    std::vector<glm::vec3> positions;   ///< object units
    std::vector<glm::vec2> uvs;         ///< one per vertex; u along T, v along B
    std::vector<glm::vec3> normals;     ///< unit outward normal N per vertex
    std::vector<glm::vec4> tangents;    ///< xyz: unit tangent T (along +u, orthogonal to N);
                                        ///< w: bitangent sign, B = w * cross(N, T)
    std::vector<glm::uvec3> triangles;  ///< counter-clockwise seen from outside
};

/// Reads a base mesh with UVs through OpenMesh: `.obj` (texture coordinates from `vt` lines),
/// `.off` (STOFF vertex texture coordinates) or `.ply` (per-vertex u,v properties); the
/// extension picks the reader, case-insensitively. Polygons are split into triangles by
/// triangulatePolygon (convex ones as the fan from their first corner, concave ones by ear
/// clipping in their plane), each with the uvs the file gives its corners, also
/// where an edge has three or more faces or a face is wound against its neighbours. Vertices are
/// split per (position, uv) pair, so a UV seam becomes duplicated vertices with the same position.
/// Normals and tangents are computed with computeTangentFrames. Positions and UVs are returned as
/// stored in the file. OBJ files are checked line by line before OpenMesh reads them (OpenMesh
/// accepts some broken files silently): every `v`/`vt` needs finite numbers, every face at least 3
/// corners, each with an in-range vertex index and an in-range `vt` index. Not thread-safe with
/// other code that uses OpenMesh's global log streams at the same time (they are redirected during
/// the read); concurrent loadBaseMesh calls are serialised.
/// @throws InputError  the file does not exist, is not a regular file or cannot be opened.
/// @throws FormatError the extension is not one of the above, the counts a header declares do
///                     not fit in the file or in kInputMemoryBudgetBytes, a PLY/OFF value is not
///                     a number within its type's range, OpenMesh cannot read the file, the mesh
///                     has no faces or no texture coordinates, a position or UV is NaN/Inf, or
///                     an OBJ face refers to a missing vertex or texture coordinate.
BaseMesh loadBaseMesh(const std::filesystem::path& file);

/// Fills mesh.normals and mesh.tangents (resized to one per position) from positions, uvs and
/// triangles, following the convention in the file note above:
/// - N: area-weighted face normals summed over all vertices welded at one position
///   (common/position_weld.h), so duplicates along a UV seam get the same normal (no crack). Where
///   that sum cancels (e.g. a two-sided sheet), the vertex's own faces are used; where everything
///   is degenerate N = +z.
/// - T, w: per triangle dP/du and dP/dv from the edge and UV deltas; each corner adds the
///   unit projection of dP/du into its vertex's tangent plane, weighted by the corner angle.
///   Triangles with (near) zero area or zero UV area (|e1 x e2| <= 1e-7 |e1| |e2| for the edges
///   from the first corner, in 3D or in UV space) contribute nothing. Vertices welded at one
///   position whose uvs differ by a whole-number vector (a wrapping seam such as u = 0 / u = 1,
///   where the repeating texture continues unchanged) pool their sums, so both copies get the same
///   tangent. A vertex without any valid contribution gets a fixed unit vector orthogonal to N (the
///   coordinate axis least aligned with N, projected) and w = +1.
/// Results are finite and orthonormal for any finite input.
/// @pre  every position and uv is finite. Units: any (frames are unit vectors).
/// @throws InputError uvs.size() != positions.size(), a triangle index is out of range, or a
///                    position or uv is NaN/Inf.
void computeTangentFrames(BaseMesh& mesh);

/// Removes the triangles without area: those whose height above their longest edge is at most
/// the weld distance (common/position_weld.h: 1e-3 of the median edge length), such as a
/// triangle lying along an edge of its neighbour or one with two welded corners. They show
/// nothing, and in the shell they would stand between triangles that meet (an edge of three
/// faces is not crossed) and fold at every depth. Returns how many were removed; vertices stay.
std::size_t removeTrianglesWithoutArea(BaseMesh& mesh);

/// Largest segment count the built-in meshes accept (keeps them far from exhausting memory:
/// 4096 x 4096 quads are 16.8 M vertices).
inline constexpr int kMaxSegments = 4096;

/// Square of side `sizeWorld` in the z = 0 plane, centred at the origin, split into
/// segments x segments quads (two triangles each). Normal +z; u = x / sizeWorld + 0.5 along +x,
/// v = y / sizeWorld + 0.5 along +y, so T = +x, B = +y, w = +1.
/// @throws InputError sizeWorld is not finite and > 0, or segments is not in [1, kMaxSegments].
BaseMesh makePlane(float sizeWorld, int segments);

/// Sphere of radius `radiusWorld` centred at the origin with its axis along z.
/// u = φ / 2π with φ = atan2(y, x) in [0, 2π) (the seam column at φ = 0 is duplicated with
/// u = 0 and u = 1); v = polar angle from the south pole / π (v = 0 at z = -r, v = 1 at z = +r).
/// `segmentsAround` columns in φ, `ringsAlong` latitude bands from pole to pole. Each pole is a
/// fan of triangles with one pole vertex per column (at u = column centre), so no triangle is
/// degenerate. Frames (computed, approximating the analytic ones): N = p / r,
/// T = (-sin φ, cos φ, 0), B = towards the north pole = cross(N, T), w = +1.
/// @throws InputError radiusWorld is not finite and > 0, segmentsAround is not in
///                    [3, kMaxSegments] or ringsAlong is not in [2, kMaxSegments].
BaseMesh makeUvSphere(float radiusWorld, int segmentsAround, int ringsAlong);

/// Torus around the z axis, in the xy plane:
/// p(θ, ψ) = ((R + r cos ψ) cos θ, (R + r cos ψ) sin θ, r sin ψ), R = majorRadiusWorld,
/// r = minorRadiusWorld, u = θ / 2π, v = ψ / 2π (both seams duplicated). Frames (computed,
/// approximating the analytic ones): N = (cos ψ cos θ, cos ψ sin θ, sin ψ),
/// T = (-sin θ, cos θ, 0), B = dP/dψ / |dP/dψ| = cross(N, T), so w = +1.
/// @throws InputError a radius is not finite and > 0, minor >= major, or a segment count is not
///                    in [3, kMaxSegments].
BaseMesh makeTorus(float majorRadiusWorld, float minorRadiusWorld, int segmentsMajor,
                   int segmentsMinor);

}  // namespace distile
