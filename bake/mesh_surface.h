/// @file
/// The surface of a detail mesh baked with a sign: the boundary of its inside {w > 1/2}
/// (bake/soup_distance.h, w the generalized winding number), as every signed mesh bake, `check`
/// and reference renders measure it. It is made of
/// - the triangles that bound the inside: those with w > 1/2 on one side and not on the other.
///   The walls of one closed part inside another (w = 1 and 2 on their sides, overlapping
///   parts of a soup) and sheets outside (w < 1/2 on both sides) are not surface: a texel inside
///   two overlapping spheres takes its distance to their union's surface, not to the inner
///   walls. A triangle that bounds the inside only in part (across another part's surface) is
///   split down to pieces of kSurfacePieceTexels and its pieces that do not bound it dropped.
/// - caps over the holes of a mesh that is not closed. Across a triangle w jumps; across a hole
///   it changes continuously, so there the boundary of {w > 1/2} is the level surface w = 1/2
///   spanning the hole, where the mesh has no triangle; the distance to the triangles alone,
///   signed by w, would jump from +d to -d across it. The caps are that level surface as
///   triangles. (A planar hole of a mesh that is otherwise a closed solid has w = 1/2 exactly on
///   the missing face: its cap is that face.)
///
/// The caps are found from the placed mesh and the tile size alone:
/// 1. w at the voxel centres (i + 1/2, j + 1/2, k + 1/2) of the footprint, periodic in x and y,
///    in the layers from 2 texels below the mesh to 2 above it.
/// 2. Each cube of 8 neighbouring centres is split into the 6 tetrahedra around its diagonal
///    from its lowest to its highest corner (neighbouring cubes then share their faces'
///    triangles). A tetrahedron edge whose ends differ in sign (w > 1/2 or not) is a *cap edge*
///    when its ends are farther from the mesh, together, than the edge is long: no triangle
///    can touch it, so the level surface crosses it, where w = 1/2 (found by regula falsi on w
///    along the edge). Otherwise a triangle may explain the change.
/// 3. A tetrahedron with a cap edge gives the one or two triangles of its w = 1/2 surface
///    (marching tetrahedra). Its vertices on edges that are not cap edges lie where the level
///    surface meets the triangles, i.e. on the mesh's border (edges not used as often in one
///    direction as in the other): they go to the border point nearest to the edge's middle; a
///    cap triangle with no border point within kCapBorderReachTexels of such an edge is dropped.
/// Where the border turns within a cell (a corner of a square hole) the cap may leave a sliver of
/// the hole uncovered (under 0.2 texel wide measured): the bake and `check` share it.
///
/// A closed mesh whose parts do not overlap has all its triangles as its surface and no caps:
/// it bakes exactly as its triangles do.
#pragma once

#include <cstddef>
#include <glm/vec3.hpp>
#include <memory>
#include <span>

#include "bake/soup_distance.h"
#include "common/size3.h"
#include "common/triangle_soup.h"

namespace distile {

/// How far (texels) from the middle of a tetrahedron edge that is not a cap edge the mesh's
/// border may be for a cap triangle there to reach it (a cube's diagonal plus a margin).
inline constexpr double kCapBorderReachTexels = 2.0;
/// Triangles that bound the inside only in part are split down to pieces this long, texels; a
/// piece counts whole when it bounds at one of its samples.
inline constexpr double kSurfacePieceTexels = 0.125;

class MeshSurface {
  public:
    /// The surface of `placedTexels` (positions in texel space of `tile`) as its signed bake
    /// measures it; `soup` is built from the same triangles and must outlive this object.
    /// Multi-threaded; the result does not depend on the thread count.
    MeshSurface(const TriangleSoup& placedTexels, const SoupDistance& soup, const Size3& tile);
    /// All the triangles of `soup` and no caps: the surface of an unsigned bake (a sheet has no
    /// inside to bound). `soup` must outlive this object.
    explicit MeshSurface(const SoupDistance& soup);
    MeshSurface(MeshSurface&&) noexcept;
    ~MeshSurface();

    /// Distance to the nearest point of the surface (periodic), texels; `cutoffTexels` when none
    /// is nearer. `hint` as SoupDistance::unsignedDistance (the same result, faster along a row).
    /// @pre cutoffTexels > 0.
    double unsignedDistance(const glm::dvec3& texelPosition, double cutoffTexels,
                            SoupDistance::NearestHint& hint) const;
    /// unsignedDistance at the points (x, y, z[k]) of one vertical line, each from and updating
    /// hints[k] (SoupDistance::unsignedDistancesOnLine).
    void unsignedDistancesOnLine(const glm::dvec2& xy, std::span<const double> z,
                                 double cutoffTexels, std::span<SoupDistance::NearestHint> hints,
                                 std::span<double> distances) const;
    /// unsignedDistancesOnLine, negative where the winding number exceeds 1/2 (counted from
    /// crossings where it changes only across the surface and they are clear).
    void signedDistancesOnLine(const glm::dvec2& xy, std::span<const double> z, double cutoffTexels,
                               std::span<SoupDistance::NearestHint> hints,
                               std::span<double> distances) const;
    /// unsignedDistance, negative where the winding number exceeds 1/2.
    double signedDistance(const glm::dvec3& texelPosition, double cutoffTexels) const;

    /// The cap triangles, texels (periodic: corners may lie up to 1.5 texels beyond
    /// [0, W) x [0, H)); empty when there are none.
    const TriangleSoup& caps() const { return caps_; }
    /// Triangles of the mesh that are not surface, in whole or in part (inside or outside on
    /// both sides): dropped, or split and their pieces that are not surface dropped.
    std::size_t trimmedTriangles() const { return trimmedTriangles_; }

  private:
    const SoupDistance* soup_;
    std::unique_ptr<const SoupDistance> bounding_;  ///< the surface's triangles; null: soup_'s
    std::size_t trimmedTriangles_ = 0;
    TriangleSoup caps_;
    std::unique_ptr<const SoupDistance> capDistance_;  ///< of caps_; null when there are none
};

class MeshDistance;

/// Whether CGAL's inside test (truth/mesh_truth.h; `mesh` of the same placed triangles) gives
/// the sign the surface has: the mesh is closed (mesh.hasSign()) and its parts neither intersect
/// nor nest (no triangle trimmed). Where closed parts overlap or nest, the inside test, which
/// counts crossings, says "outside" and the winding number says inside.
bool insideTestSignsAlike(const MeshDistance& mesh, const MeshSurface& surface,
                          const TriangleSoup& placedTexels);

/// A placed detail mesh (texels of `tile`) with its surface, for the programs that measure
/// against the bake (`check`, reference renders). Not movable (its surface refers to its soup).
class MeshSurfaceDistance {
  public:
    MeshSurfaceDistance(const TriangleSoup& placedTexels, const Size3& tile)
        : soup_(placedTexels, tile), surface_(placedTexels, soup_, tile) {}
    MeshSurfaceDistance(const MeshSurfaceDistance&) = delete;
    MeshSurfaceDistance& operator=(const MeshSurfaceDistance&) = delete;

    /// MeshSurface::signedDistance.
    double signedDistance(const glm::dvec3& texelPosition, double cutoffTexels) const {
        return surface_.signedDistance(texelPosition, cutoffTexels);
    }
    const MeshSurface& surface() const { return surface_; }

  private:
    SoupDistance soup_;
    MeshSurface surface_;
};

}  // namespace distile
