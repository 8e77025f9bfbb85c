/// @file
/// A plain indexed triangle list without attributes: the form in which detail meshes travel
/// between mesh/ (loading), vdb/ (mesh to level set) and truth/ (exact distances). When used for
/// baking, positions are in texel space of the tile (see docs/texel_space.md: texel centres at i + 0.5,
/// z = D is the top, periodic in x and y); otherwise they are in the units of the file they came
/// from. Also the one implementation of the periodic wrap of a mesh, shared by the bake and the
/// ground truth so both measure the same thing.
#pragma once

#include <glm/vec3.hpp>
#include <string>
#include <vector>

#include "common/size3.h"

namespace distile {

struct TriangleSoup {
    std::vector<glm::dvec3> positions;  ///< texel space when baking; file units after loading
    std::vector<glm::uvec3>
        triangles;  ///< indices into positions, counter-clockwise seen from outside
};

/// Throws InputError naming `what` unless the soup has at least one triangle, every position is
/// finite and every index is in range.
void validateTriangleSoup(const TriangleSoup& soup, const std::string& what);

/// Axis-aligned bounding box of the positions (min, max); {0, 0} for an empty soup.
struct Bounds3 {
    glm::dvec3 min{0.0};
    glm::dvec3 max{0.0};
};
Bounds3 boundsOf(const TriangleSoup& soup);

/// Periodic tiles: the detail is the union of copies of a mesh shifted by (m W, n H, 0) for all
/// integers m, n (a mesh that crosses a tile edge continues on the other side). This gives the
/// inclusive ranges of m and n whose shifted `box` comes within `reach` of `point` in x and y,
/// i.e. the only copies that can be nearer to `point` than `reach` (empty ranges when there are
/// none: begin > end). The one implementation of the wrap, used by the bake (vdb/) and the
/// ground truth (truth/) so both measure the same thing. @pre tile extents >= 1, reach >= 0.
struct PeriodicShifts {
    int xBegin = 0, xEnd = -1;  ///< m, inclusive
    int yBegin = 0, yEnd = -1;  ///< n, inclusive
};
PeriodicShifts periodicShifts(const glm::dvec3& point, const Bounds3& box, const Size3& tile,
                              double reach);

}  // namespace distile
