#include "common/triangle_soup.h"

#include <cmath>
#include <glm/common.hpp>
#include <sstream>

#include "common/error.h"

namespace distile {

void validateTriangleSoup(const TriangleSoup& soup, const std::string& what) {
    if (soup.triangles.empty()) {
        throw InputError(what + ": the mesh has no triangles; a detail mesh needs at least one");
    }
    for (std::size_t v = 0; v < soup.positions.size(); ++v) {
        const glm::dvec3& p = soup.positions[v];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
            std::ostringstream message;
            message << what << ": vertex " << v << " is (" << p.x << ", " << p.y << ", " << p.z
                    << "); coordinates must be finite";
            throw InputError(message.str());
        }
    }
    const std::size_t count = soup.positions.size();
    for (std::size_t t = 0; t < soup.triangles.size(); ++t) {
        const glm::uvec3& triangle = soup.triangles[t];
        for (int corner = 0; corner < 3; ++corner) {
            if (triangle[corner] >= count) {
                throw InputError(what + ": triangle " + std::to_string(t) + " refers to vertex " +
                                 std::to_string(triangle[corner]) + "; indices must be below " +
                                 std::to_string(count));
            }
        }
    }
}

Bounds3 boundsOf(const TriangleSoup& soup) {
    if (soup.positions.empty()) return {};
    Bounds3 box{soup.positions.front(), soup.positions.front()};
    for (const glm::dvec3& p : soup.positions) {
        box.min = glm::min(box.min, p);
        box.max = glm::max(box.max, p);
    }
    return box;
}

PeriodicShifts periodicShifts(const glm::dvec3& point, const Bounds3& box, const Size3& tile,
                              double reach) {
    // Copy m covers x in [min + mW, max + mW]; it comes within `reach` of point.x when
    // min + mW - reach <= x <= max + mW + reach.
    PeriodicShifts shifts;
    const double width = tile.width;
    const double height = tile.height;
    shifts.xBegin = int(std::ceil((point.x - box.max.x - reach) / width));
    shifts.xEnd = int(std::floor((point.x - box.min.x + reach) / width));
    shifts.yBegin = int(std::ceil((point.y - box.max.y - reach) / height));
    shifts.yEnd = int(std::floor((point.y - box.min.y + reach) / height));
    return shifts;
}

}  // namespace distile
