/// @file
/// Caps over the holes of a detail mesh that is not closed, so that its signed distance is the
/// distance to one closed surface: the boundary of its inside {w > 1/2} (bake/soup_distance.h,
/// w the generalized winding number).
///
/// Across a triangle w jumps; across a hole it changes continuously, so there the boundary of
/// {w > 1/2} is the level surface w = 1/2 spanning the hole, where the mesh has no triangle. The
/// distance to the triangles alone, signed by w, jumps from +d to -d across it. The caps are that
/// level surface as triangles; the surface of the mesh is its triangles and its caps, and its
/// distance signed by w is continuous. (A planar hole of a mesh that is otherwise a closed solid
/// has w = 1/2 exactly on the missing face: its cap is that face.)
///
/// How they are found, from the placed mesh and the tile size alone (the bake and `check` build
/// the same caps):
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
#pragma once

#include <cstddef>
#include <glm/vec3.hpp>
#include <memory>

#include "bake/soup_distance.h"
#include "common/size3.h"
#include "common/triangle_soup.h"

namespace distile {

/// How far (texels) from the middle of a tetrahedron edge that is not a cap edge the mesh's
/// border may be for a cap triangle there to reach it (a cube's diagonal plus a margin).
inline constexpr double kCapBorderReachTexels = 2.0;

class HoleCaps {
  public:
    /// The caps of `placedTexels` (positions in texel space of `tile`; `soup` built from it):
    /// none when soup.windingChangesOnlyAcrossTheSurface() (closed parts have no hole).
    /// Multi-threaded; the caps do not depend on the thread count.
    HoleCaps(const TriangleSoup& placedTexels, const SoupDistance& soup, const Size3& tile);
    /// No caps (a mesh baked as an unsigned distance has no inside to close).
    HoleCaps();
    HoleCaps(HoleCaps&&) noexcept;
    ~HoleCaps();

    /// The cap triangles, texels (periodic: corners may lie up to 1.5 texels beyond
    /// [0, W) x [0, H)); empty when there are none.
    const TriangleSoup& triangles() const { return triangles_; }

    /// The smaller of `meshDistanceTexels` (the distance to the mesh's triangles) and the
    /// periodic distance to the nearest cap triangle: the distance to the mesh's surface, texels.
    /// `meshDistanceTexels` itself when there are no caps. @pre meshDistanceTexels > 0 or 0.
    double surfaceDistance(const glm::dvec3& texelPosition, double meshDistanceTexels) const;

  private:
    TriangleSoup triangles_;
    std::unique_ptr<const SoupDistance> distance_;  ///< of triangles_; null when empty
};

/// The exact signed distance of a placed detail mesh, as every mesh bake and its `check` define
/// it: the distance to its triangles and caps (texels, periodic; `cutoffTexels` beyond),
/// negative where its winding number exceeds 1/2. @pre cutoffTexels > 0.
double surfaceSignedDistance(const SoupDistance& soup, const HoleCaps& caps,
                             const glm::dvec3& texelPosition, double cutoffTexels);

/// A placed detail mesh (texels of `tile`) with its caps, for the programs that measure against
/// the bake (`check`, reference renders). Construction as SoupDistance then HoleCaps.
class MeshSurfaceDistance {
  public:
    MeshSurfaceDistance(const TriangleSoup& placedTexels, const Size3& tile)
        : soup_(placedTexels, tile), caps_(placedTexels, soup_, tile) {}

    /// surfaceSignedDistance of the mesh.
    double signedDistance(const glm::dvec3& texelPosition, double cutoffTexels) const {
        return surfaceSignedDistance(soup_, caps_, texelPosition, cutoffTexels);
    }
    const SoupDistance& soup() const { return soup_; }
    const HoleCaps& caps() const { return caps_; }

  private:
    SoupDistance soup_;
    HoleCaps caps_;
};

}  // namespace distile
