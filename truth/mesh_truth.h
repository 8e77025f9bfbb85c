/// @file
/// Ground truth for meshes, in double precision with CGAL (the only module that sees CGAL):
/// topology checks with Polygon Mesh Processing, and exact point-to-triangle distances, inside
/// tests and ray hits with an AABB tree. Units are those of the soup's positions (texels when
/// the soup is placed in a tile).
#pragma once

#include <cstddef>
#include <glm/vec3.hpp>
#include <memory>
#include <optional>

#include "common/size3.h"
#include "common/triangle_soup.h"

namespace distile {

struct MeshTopology {
    bool closed = false;            ///< every edge has exactly two faces (no border)
    bool manifold = false;          ///< soup orientable into a mesh, no non-manifold vertex/edge
    bool selfIntersecting = false;  ///< two non-adjacent faces intersect (not tested: see below)
    bool selfIntersectionTested = false;
    std::size_t boundaryEdges = 0;
    std::size_t degenerateFaces = 0;  ///< zero-area faces (collinear or repeated corners)

    /// Closed, manifold, not self-intersecting, no degenerate face: a valid solid.
    bool isSolid() const { return closed && manifold && !selfIntersecting && degenerateFaces == 0; }
};

/// Largest face count for which inspectMesh runs CGAL's self-intersection test (it is
/// O(n log n) with a large constant; above this, selfIntersectionTested stays false).
inline constexpr std::size_t kMaxSelfIntersectionFaces = 200000;

/// Topology of a triangle soup. Precondition-free: validates the soup first.
/// @throws InputError the soup fails validateTriangleSoup.
MeshTopology inspectMesh(const TriangleSoup& soup);

/// Exact distances to a triangle mesh (CGAL AABB tree, double precision).
class MeshDistance {
  public:
    /// Periodic evaluation: measure against the union of the mesh's copies shifted by
    /// (m W, n H, 0) (common/triangle_soup.h, periodicShifts), the same truth as a periodic bake
    /// (vdb/mesh_level_set.h). Distances are exact for every query point; the sign is "inside any
    /// copy".
    struct Periodic {
        Size3 tile;
    };

    /// Builds the tree. The inside test (signedDistance, isInside) is available only when the
    /// mesh is closed; hasSign() says so.
    /// @throws InputError the soup fails validateTriangleSoup.
    explicit MeshDistance(const TriangleSoup& soup,
                          std::optional<Periodic> periodic = std::nullopt);
    MeshDistance(MeshDistance&&) noexcept;
    MeshDistance& operator=(MeshDistance&&) noexcept;
    ~MeshDistance();

    /// Distance to the nearest point on any triangle (>= 0).
    double unsignedDistance(const glm::dvec3& point) const;

    /// Unsigned distance, negative strictly inside the mesh (CGAL::Side_of_triangle_mesh;
    /// points on the boundary give 0).
    /// @throws InputError the mesh is not closed (hasSign() is false).
    double signedDistance(const glm::dvec3& point) const;

    /// True when signedDistance and isInside are available (the mesh is closed).
    bool hasSign() const;

    /// Strictly inside the closed mesh. @throws InputError if !hasSign().
    bool isInside(const glm::dvec3& point) const;

    /// Nearest hit of the ray origin + t * direction, t >= 0, with the (unshifted) mesh; on a hit
    /// stores t in units of |direction| in `distance` and returns true. Not periodic.
    /// @pre direction is non-zero and finite.
    bool rayHit(const glm::dvec3& origin, const glm::dvec3& direction, double& distance) const;

    /// A ray's first hit: how far along the ray and the hit triangle's plane.
    struct RayHit {
        double distance = 0.0;  ///< t of origin + t * direction, in units of |direction|
        /// Unit normal of the hit triangle, oriented against the ray (dot(normal, direction)
        /// <= 0): for a ray arriving from outside the solid, the outward normal, whatever the
        /// winding of the file.
        glm::dvec3 normal{0.0, 0.0, 1.0};
    };

    /// Nearest hit of origin + t * direction for t in [0, maxDistance] (t in units of
    /// |direction|). Periodic MeshDistance: the nearest hit over all copies shifted by
    /// (m W, n H, 0) that the ray meets within maxDistance; only the copies whose shifted
    /// bounding box the ray's path crosses are queried, so the cost grows with the path's length
    /// in tiles, not with its square. Otherwise the (unshifted) mesh only.
    /// @pre direction is non-zero and finite; maxDistance >= 0.
    /// @throws InputError periodic and maxDistance is not finite (the copies would not end).
    std::optional<RayHit> firstHit(const glm::dvec3& origin, const glm::dvec3& direction,
                                   double maxDistance) const;

    /// Number of triangles in the tree.
    std::size_t triangleCount() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace distile
