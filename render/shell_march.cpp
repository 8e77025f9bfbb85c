#include "render/shell_march.h"

namespace distile::detail {

Located locate(const ShellPrisms& shell, const glm::dvec3& origin, const glm::dvec3& direction,
               double distanceWorld, CurvedCursor& cursor) {
    // A point on a shared side face belongs to both prisms: rounding may put it a hair outside
    // each, so a little outside counts as inside (no walk back and forth).
    constexpr double kOnFace = 1e-9;
    constexpr int kMaxWalk = 64;
    for (int walk = 0; walk < kMaxWalk; ++walk) {
        const ShellPrism& prism = shell.prisms[cursor.prism];
        if (!prism.invert(cursor.originOffset + distanceWorld * direction, cursor.point,
                          cursor.jacobian, 12))
            return Located::Lost;
        const double weights[3] = {cursor.point.b0(), cursor.point.b1, cursor.point.b2};
        int outside = 0;
        for (int corner = 1; corner < 3; ++corner)
            if (weights[corner] < weights[outside]) outside = corner;
        const bool aboveTop = cursor.point.depthWorld < 0.0;
        if (weights[outside] >= -kOnFace) return aboveTop ? Located::AboveTop : Located::Inside;
        const std::uint32_t neighbour = shell.neighbours[cursor.prism][std::size_t(outside)];
        if (neighbour == ShellPrisms::kNoNeighbour)
            return aboveTop ? Located::AboveTop : Located::OpenSide;
        cursor.prism = neighbour;
        cursor.originOffset = origin - shell.prisms[neighbour].corner0;
        cursor.point = {1.0 / 3.0, 1.0 / 3.0, cursor.point.depthWorld};
    }
    return Located::Lost;
}

}  // namespace distile::detail
