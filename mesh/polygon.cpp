#include "mesh/polygon.h"

#include <cmath>
#include <cstddef>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <utility>

namespace distile {

namespace {

/// Twice the signed area of triangle (a, b, c): positive when counter-clockwise.
double cross(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
    return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

/// How corner b turns between a and c: +1 left (convex in a counter-clockwise polygon), -1
/// right (reflex), 0 straight: within a relative 1e-12 of straight, as rounding leaves the
/// straight corners of a polygon whose plane is not an axis plane.
int turn(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
    const double twiceArea = cross(a, b, c);
    const double straight = 1e-12 * glm::length(b - a) * glm::length(c - b);
    return twiceArea > straight ? 1 : twiceArea < -straight ? -1 : 0;
}

/// Whether `p` lies in the counter-clockwise triangle (a, b, c) or on its boundary.
bool inTriangle(const glm::dvec2& p, const glm::dvec2& a, const glm::dvec2& b,
                const glm::dvec2& c) {
    return cross(a, b, p) >= 0.0 && cross(b, c, p) >= 0.0 && cross(c, a, p) >= 0.0;
}

/// The plane a polygon is seen in: the two coordinates other than the largest of its Newell
/// normal (its area vector), in the order that makes the polygon wind counter-clockwise.
struct PolygonPlane {
    int first = 0, second = 1;
    bool hasArea = false;  ///< false: no area (or a non-finite corner), no plane to see it in

    explicit PolygonPlane(std::span<const glm::dvec3> corners) {
        glm::dvec3 normal(0.0);
        for (std::size_t i = 1; i + 1 < corners.size(); ++i)
            normal += glm::cross(corners[i] - corners[0], corners[i + 1] - corners[0]);
        const glm::dvec3 size = glm::abs(normal);
        const int largest = size.x >= size.y && size.x >= size.z ? 0 : size.y >= size.z ? 1 : 2;
        hasArea = size[largest] > 0.0 && std::isfinite(size[largest]);
        first = (largest + 1) % 3;
        second = (largest + 2) % 3;
        if (normal[largest] < 0.0) std::swap(first, second);
    }
    glm::dvec2 operator()(const glm::dvec3& corner) const {
        return {corner[first], corner[second]};
    }
};

}  // namespace

bool triangulatePolygon(std::span<const glm::dvec3> corners,
                        std::vector<std::array<std::uint32_t, 3>>& triangles,
                        PolygonTriangulationBudget& budget) {
    const std::uint32_t count = std::uint32_t(corners.size());
    // Triangles (most faces of most files) and convex polygons need no working memory.
    const auto fanFromFirst = [&] {
        for (std::uint32_t k = 1; k + 1 < count; ++k) triangles.push_back({0, k, k + 1});
        return true;
    };
    if (count == 3) return fanFromFirst();
    const PolygonPlane plane(corners);
    if (!plane.hasArea) return fanFromFirst();
    bool concave = false;
    for (std::uint32_t i = 0; i < count && !concave; ++i) {
        concave = turn(plane(corners[(i + count - 1) % count]), plane(corners[i]),
                       plane(corners[(i + 1) % count])) < 0;
    }
    if (!concave) return fanFromFirst();

    // Ear clipping on the corners left, a ring of previous and next.
    std::vector<glm::dvec2> points(count);
    std::vector<std::uint32_t> next(count), previous(count);
    for (std::uint32_t i = 0; i < count; ++i) {
        points[i] = plane(corners[i]);
        next[i] = (i + 1) % count;
        previous[i] = (i + count - 1) % count;
    }
    // Corners that cannot be an ear's tip: reflex or straight ones. They are also the only ones
    // that can lie in an ear of a simple polygon.
    std::vector<bool> notConvex(count);
    std::vector<std::uint32_t> notConvexCorners;
    const auto classify = [&](std::uint32_t i) {
        notConvex[i] = turn(points[previous[i]], points[i], points[next[i]]) <= 0;
    };
    for (std::uint32_t i = 0; i < count; ++i) {
        classify(i);
        if (notConvex[i]) notConvexCorners.push_back(i);
    }
    // An ear: a strictly convex corner whose triangle holds no other corner left that is not
    // convex, other than copies of the triangle's own corners. (A clipped corner was an ear's
    // convex tip and is never classified again: the not-convex ones are all still in the ring.)
    const auto isEar = [&](std::uint32_t i) {
        if (notConvex[i]) return false;
        const glm::dvec2 &a = points[previous[i]], &b = points[i], &c = points[next[i]];
        for (const std::uint32_t j : notConvexCorners) {
            if (!notConvex[j] || j == previous[i] || j == next[i]) continue;
            const glm::dvec2& p = points[j];
            if (p == a || p == b || p == c) continue;
            if (inTriangle(p, a, b, c)) return false;
        }
        return true;
    };
    const std::size_t firstTriangle = triangles.size();
    std::uint32_t left = count, at = 0, tried = 0;  // tried: corners since the last ear
    const std::uint64_t earTestCost = notConvexCorners.size() + 1;
    while (left > 3) {
        if (budget.testsLeft < earTestCost) {
            triangles.resize(firstTriangle);
            return false;
        }
        budget.testsLeft -= earTestCost;
        if (!isEar(at)) {
            at = next[at];
            if (++tried < left) continue;
            break;  // no ear anywhere: the polygon crosses itself, or what is left has no area
        }
        const std::uint32_t before = previous[at], after = next[at];
        triangles.push_back({before, at, after});
        next[before] = after;
        previous[after] = before;
        --left;
        // Cutting an ear only narrows the corners beside it: a reflex one may turn convex.
        classify(before);
        classify(after);
        at = after;
        tried = 0;
    }
    // The last triangle, or the fan of what no ear could be cut from.
    for (std::uint32_t k = next[at]; next[k] != at; k = next[k])
        triangles.push_back({at, k, next[k]});
    return true;
}

}  // namespace distile
