/// @file
/// Polygons of mesh files split into triangles: convex ones as a fan, concave ones by ear
/// clipping in their plane, so that no triangle covers what lies outside the polygon.
#pragma once

#include <array>
#include <cstdint>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

namespace distile {

/// What ear clipping may spend on the polygons of one file: containment tests of corners
/// against candidate ears. A simple polygon takes about (corners x reflex corners) of them; a
/// pathological one, corners^2 x reflex corners.
struct PolygonTriangulationBudget {
    std::uint64_t testsLeft = std::uint64_t(1) << 26;  ///< a quarter of a second on one core
};

/// Appends the triangles of the polygon with corners `corners` (in order, at least 3) to
/// `triangles`, as triples of corner indices (0 ... size - 1), wound as the polygon is. A convex
/// polygon (seen along its Newell normal, collinear corners allowed) and a triangle give the fan
/// from corner 0: (0, k, k + 1). A concave one is ear-clipped in its plane (the one perpendicular
/// to its Newell normal), every triangle inside the polygon, none overlapping. Where no ear is
/// left (a polygon crossing itself, or no area at all) the rest is fanned from where clipping
/// stopped. False, with `triangles` unchanged, when ear clipping would exceed `budget` (which
/// is charged for the tests made).
bool triangulatePolygon(std::span<const glm::dvec3> corners,
                        std::vector<std::array<std::uint32_t, 3>>& triangles,
                        PolygonTriangulationBudget& budget);

}  // namespace distile
