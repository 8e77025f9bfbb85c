/// @file
/// Bounding volume hierarchy over the base-mesh triangles of a scene: the primary visibility
/// of the base surfaces (the tops of the detail shells), where the sphere tracer starts.
#pragma once

#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

namespace distile {

struct Ray {
    glm::vec3 origin;
    glm::vec3 direction;  ///< unit length
};

struct TriangleHit {
    std::uint32_t triangle = 0;  ///< index into the triangle list the BVH was built from
    float distanceWorld = 0.0f;  ///< along the ray
    /// Barycentric weights of the triangle's second and third vertices, in double: a triangle may
    /// span many repeats of its tile (a ground plane of two triangles), and the tracer wraps the
    /// entry's uv into the tile from them; a float's rounding there (6e-8) times the texels the
    /// triangle spans would move the entry by texels (a texel at 1.6e7 texels across).
    double b1 = 0.0;
    double b2 = 0.0;
};

/// A triangle as Moeller-Trumbore takes it, in double precision: corner p0 and the edges p1 - p0,
/// p2 - p0 (computed in double from the float corners).
struct DoubleTriangle {
    glm::dvec3 corner0, edge1, edge2;

    DoubleTriangle() = default;
    DoubleTriangle(const glm::vec3& p0, const glm::vec3& p1, const glm::vec3& p2)
        : corner0(p0), edge1(glm::dvec3(p1) - corner0), edge2(glm::dvec3(p2) - corner0) {}
};

/// A triangle and a ray origin: what Moeller-Trumbore computes from those two alone, once for
/// every ray from that origin (camera rays share the eye).
struct TriangleFromOrigin {
    DoubleTriangle triangle;
    glm::dvec3 tvec;      ///< origin - corner0
    glm::dvec3 qvec;      ///< tvec x edge1
    double edge2DotQvec;  ///< the hit distance times the determinant

    TriangleFromOrigin(const glm::vec3& origin, const DoubleTriangle& of)
        : triangle(of),
          tvec(glm::dvec3(origin) - of.corner0),
          qvec(glm::cross(tvec, of.edge1)),
          edge2DotQvec(glm::dot(of.edge2, qvec)) {}

    /// intersectTriangle for the ray from the origin along unit `direction`.
    bool intersect(const glm::vec3& direction, double minDistance, double maxDistance,
                   double& distanceWorld, double& b1, double& b2) const {
        const glm::dvec3 along(direction);
        const glm::dvec3 pvec = glm::cross(along, triangle.edge2);
        const double determinant = glm::dot(triangle.edge1, pvec);
        if (determinant == 0.0 || !std::isfinite(determinant)) return false;
        const double inverse = 1.0 / determinant;
        b1 = glm::dot(tvec, pvec) * inverse;
        if (b1 < 0.0 || b1 > 1.0) return false;
        b2 = glm::dot(along, qvec) * inverse;
        if (b2 < 0.0 || b1 + b2 > 1.0) return false;
        distanceWorld = edge2DotQvec * inverse;
        return distanceWorld > minDistance && distanceWorld < maxDistance;
    }
};

/// A triangle and a ray direction: what Moeller-Trumbore computes from those two alone, once for
/// every ray along that direction (a shadow map's light rays). Its test gives what
/// TriangleFromOrigin's does, bit for bit: the same operations on the same values.
struct TriangleAlong {
    const DoubleTriangle& triangle;
    glm::dvec3 along;  ///< the direction
    glm::dvec3 pvec;   ///< along x edge2
    double inverse;    ///< 1 / (edge1 . pvec)
    bool parallel;     ///< the direction lies in the triangle's plane (or is not finite): no hit
    TriangleAlong(const glm::vec3& direction, const DoubleTriangle& of)
        : triangle(of), along(direction), pvec(glm::cross(along, of.edge2)) {
        const double determinant = glm::dot(of.edge1, pvec);
        parallel = determinant == 0.0 || !std::isfinite(determinant);
        inverse = 1.0 / determinant;
    }
    /// intersectTriangle for the ray from `origin` along the direction.
    bool intersect(const glm::vec3& origin, double minDistance, double maxDistance,
                   double& distanceWorld, double& b1, double& b2) const {
        if (parallel) return false;
        const glm::dvec3 tvec = glm::dvec3(origin) - triangle.corner0;
        b1 = glm::dot(tvec, pvec) * inverse;
        if (b1 < 0.0 || b1 > 1.0) return false;
        const glm::dvec3 qvec = glm::cross(tvec, triangle.edge1);
        b2 = glm::dot(along, qvec) * inverse;
        if (b2 < 0.0 || b1 + b2 > 1.0) return false;
        distanceWorld = glm::dot(triangle.edge2, qvec) * inverse;
        return distanceWorld > minDistance && distanceWorld < maxDistance;
    }
};
/// The ray against one triangle (Moeller-Trumbore in double precision, the test TriangleBvh uses):
/// true when it hits at a distance in (minDistance, maxDistance) world units, with the
/// barycentric weights b1, b2 of p1, p2. Degenerate triangles and rays in their plane miss.
inline bool intersectTriangle(const Ray& ray, const DoubleTriangle& triangle, double minDistance,
                              double maxDistance, double& distanceWorld, double& b1, double& b2) {
    return TriangleFromOrigin(ray.origin, triangle)
        .intersect(ray.direction, minDistance, maxDistance, distanceWorld, b1, b2);
}

inline bool intersectTriangle(const Ray& ray, const glm::vec3& p0, const glm::vec3& p1,
                              const glm::vec3& p2, double minDistance, double maxDistance,
                              double& distanceWorld, double& b1, double& b2) {
    return intersectTriangle(ray, DoubleTriangle(p0, p1, p2), minDistance, maxDistance,
                             distanceWorld, b1, b2);
}

class TriangleBvh {
  public:
    TriangleBvh() = default;
    /// Builds over `corners` (three per triangle, world units). Degenerate triangles are kept
    /// (they are never hit).
    explicit TriangleBvh(std::vector<glm::vec3> corners);

    /// Nearest hit with distance in (minDistance, maxDistance), or false. Intersections are
    /// computed in double precision, so rays through shared edges do not slip between triangles.
    bool intersect(const Ray& ray, float minDistance, float maxDistance, TriangleHit& hit) const;

    /// intersect for each of `rays` from `minDistances[k]`: the rays traverse the tree
    /// together, each box tested for all of them at once. Each ray's hit (`found[k]`,
    /// `hits[k]`) is bit for bit the one intersect gives it. Preconditions: at most kPacketRays
    /// rays, all with one direction (a shadow map's light rays); the spans of one size.
    static constexpr std::size_t kPacketRays = 16;
    void intersectParallel(std::span<const Ray> rays, std::span<const float> minDistances,
                           float maxDistance, std::span<TriangleHit> hits,
                           std::span<bool> found) const;

    std::size_t triangleCount() const { return order_.size(); }

  private:
    struct Node {
        glm::vec3 boundsMin;
        glm::vec3 boundsMax;
        std::uint32_t first = 0;  ///< leaf: first entry in order_; inner: right child index
        std::uint32_t count = 0;  ///< leaf: triangle count; inner: 0 (left child is next node)
    };
    /// A triangle's bounds (the min and max of its corners, in corner order) and centroid.
    struct TriangleBox {
        glm::vec3 low, high, centroid;
    };
    /// The node over order_[first, first + count) and its subtree (`boxes` per triangle), split
    /// by the surface area heuristic, appended to `nodes` (its index there returned; child
    /// indices are into `nodes`).
    std::uint32_t build(const std::vector<TriangleBox>& boxes, std::uint32_t first,
                        std::uint32_t count, int depth, std::vector<Node>& nodes);

    /// Three per triangle: in the order given while the tree is built, then in leaf order
    /// (entry i of order_ has corners 3 i to 3 i + 2).
    std::vector<glm::vec3> corners_;
    std::vector<std::uint32_t> order_;  ///< the triangles' indices in leaf order
    std::vector<Node> nodes_;
};

}  // namespace distile
