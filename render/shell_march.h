/// @file
/// The march through a curved shell (common/shell_map.h): the ray is followed in world space, and
/// each distance sample is taken where the ray really is in texel space, through the shell map of
/// the prism it is in. The ray goes on from prism to prism across shared side faces, leaves the
/// shell through the top or an open border, or ends on the detail or the floor.
///
/// Each sample inverts the map at the ray's point by Newton's method (one step from the previous
/// point's prediction, in double precision) and steps the sampled distance in texels along the
/// ray's texel-space direction there: dt = distance / |J r|, with J = d texel / d world, the map's
/// local stretch along the ray. That is ch. 8's normalisation factor taken at every sample instead
/// of once at the entry. The step is exact to first order; where the stretch grows along the step
/// (the map is not affine) a budgeted step that lands inside the detail is refined by regula
/// falsi, as in the planar march.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <glm/vec3.hpp>
#include <span>

#include "common/shell_map.h"
#include "render/bvh.h"
#include "render/march.h"

namespace distile {

/// A shell: the prisms of one object's triangles, in the tracer's shell order, and for each the
/// prism across the side face opposite each corner (kNoNeighbour at an open border).
struct ShellPrisms {
    static constexpr std::uint32_t kNoNeighbour = 0xffffffffU;
    std::span<const ShellPrism> prisms;
    std::span<const std::array<std::uint32_t, 3>> neighbours;
};

/// How a curved march ended.
struct CurvedMarchEnd {
    MarchResult march;        ///< texel position in the end prism's texel space, iterations, ...
    bool leftShell = false;   ///< through the top, an open border or an open floor: no hit here
    double distanceWorld = 0.0;  ///< along the ray: the hit, or where it left the shell
    std::uint32_t prism = 0;  ///< where it ended
    PrismPoint point;         ///< the end point in that prism
    /// |J r| at the end: texels per world unit along the ray (0 when it left the shell).
    float texelsPerWorldAlongRay = 0.0f;
};

namespace detail {

/// Where a curved march is: its prism, its point there and the ray's offset from the prism's
/// corner 0 (re-based when the prism changes).
struct CurvedCursor {
    std::uint32_t prism = 0;
    PrismPoint point;
    glm::dvec3 originOffset{0.0};  ///< ray origin - P_0 of `prism`
    ShellPrism::Jacobian jacobian;  ///< the map's, at (or a hair from) `point`
};

/// The outcome of locating the ray's point at some distance.
enum class Located { Inside, AboveTop, OpenSide, Lost };

/// Moves `cursor` to the prism holding the ray's point at `distanceWorld` (walking to neighbours
/// across side faces, at most 64 of them) and inverts the map there from cursor.point as the
/// guess. AboveTop: the point is above the top (depth < 0) of the prism it is in; OpenSide: it is
/// beyond a border without a neighbour; Lost: no prism found (a fold, a walk that does not end).
Located locate(const ShellPrisms& shell, const glm::dvec3& origin, const glm::dvec3& direction,
               double distanceWorld, CurvedCursor& cursor);

/// The texel-space velocity d texel / dt of a ray along unit `direction` where the map's
/// Jacobian is `jacobian`; `prismVelocity` receives d(b1, b2, h) / dt.
inline glm::dvec3 texelVelocity(const ShellPrism& prism, const ShellPrism::Jacobian& jacobian,
                                const glm::dvec3& direction, glm::dvec3& prismVelocity) {
    prismVelocity = jacobian.solve(direction);
    return prism.texelDelta(prismVelocity);
}

}  // namespace detail

/// Marches `ray` through `shell` from its entry on the top of prism `entryPrism` (barycentrics of
/// the entry, `entryDistanceWorld` along the ray), sampling `filter` (texel space, periodic in x
/// and y). Budgeted settings take the planar march's minimum step (the path left to the floor
/// along the local texel direction over the samples left) and refine overshoots by regula falsi;
/// other sphere-tracing methods step the sampled distance. Counts one iteration per sample.
/// Preconditions: entryPrism < shell.prisms.size(); settings.maxIterations >= 1.
template <class Filter>
CurvedMarchEnd marchCurved(const Filter& filter, const ShellPrisms& shell, const Ray& ray,
                           std::uint32_t entryPrism, double b1, double b2,
                           double entryDistanceWorld, Floor floor, const MarchSettings& settings) {
    using detail::Located;
    CurvedMarchEnd end;
    const glm::dvec3 origin(ray.origin), direction(ray.direction);
    detail::CurvedCursor cursor;
    cursor.prism = entryPrism;
    cursor.point = {b1, b2, 0.0};
    cursor.originOffset = origin - shell.prisms[entryPrism].corner0;
    const bool budgeted = settings.method == MarchMethod::Budgeted;
    const float epsilon = settings.epsilonTexels;
    const int budget = settings.maxIterations;
    int& iterations = end.march.iterations;
    double distanceWorld = entryDistanceWorld;
    // The last point sampled outside the detail: where the ray was before its current point.
    double outsideWorld = entryDistanceWorld, outsideDepthWorld = 0.0;
    float outsideTexels = 0.0f;
    bool forcedStep = false;  // the step to the current point was longer than the distance there
    glm::dvec3 prismVelocity(0.0);
    double speed = 0.0;  // texels per world unit along the ray at the current point

    auto leave = [&](double atWorld) {
        end.leftShell = true;
        end.march.exitedFloor = true;
        end.distanceWorld = atWorld;
        end.prism = cursor.prism;
        end.point = cursor.point;
        return end;
    };
    // Ends at the cursor's point (a hit, converged or at the end of the budget).
    auto stop = [&](bool converged) {
        const ShellPrism& prism = shell.prisms[cursor.prism];
        end.march.texelPosition = glm::vec3(prism.texelAt(cursor.point));
        end.march.converged = converged;
        end.march.travelTexels = float((distanceWorld - entryDistanceWorld) * speed);
        end.distanceWorld = distanceWorld;
        end.prism = cursor.prism;
        end.point = cursor.point;
        end.texelsPerWorldAlongRay = float(speed);
        return end;
    };
    // The distance sample at the cursor's point (located); sets speed and the velocities.
    glm::dvec3 directionTexels(0.0, 0.0, -1.0);
    auto sample = [&]() {
        const ShellPrism& prism = shell.prisms[cursor.prism];
        const glm::dvec3 velocity =
            detail::texelVelocity(prism, cursor.jacobian, direction, prismVelocity);
        speed = glm::length(velocity);
        directionTexels = velocity * (1.0 / speed);
        ++iterations;
        return filter.distanceTexels(glm::vec3(prism.texelAt(cursor.point)));
    };
    // Regula falsi in distance along the ray between the last outside point and the current one
    // (inside, `insideTexels` < 0), with the budget left.
    auto refine = [&](float insideTexels) {
        double outside = outsideWorld, inside = distanceWorld;
        float outsideDistance = outsideTexels, insideDistance = insideTexels;
        while (iterations < budget) {
            distanceWorld =
                outside + (inside - outside) * outsideDistance / (outsideDistance - insideDistance);
            if (detail::locate(shell, origin, direction, distanceWorld, cursor) != Located::Inside)
                break;  // keeps the estimate: the crossing is within the bracket
            const float distance = sample();
            if (std::abs(distance) < epsilon) break;
            if (distance > 0.0f) {
                outside = distanceWorld;
                outsideDistance = distance;
            } else {
                inside = distanceWorld;
                insideDistance = distance;
            }
        }
        return stop(true);
    };

    for (;;) {
        const Located where = detail::locate(shell, origin, direction, distanceWorld, cursor);
        if (where == Located::AboveTop && iterations == 0) {
            cursor.point.depthWorld = 0.0;  // the entry itself, rounded above the top
        } else if (where == Located::AboveTop) {
            // Out through the top between the last two points: where the depth crosses 0.
            const double share =
                outsideDepthWorld / (outsideDepthWorld - cursor.point.depthWorld);
            return leave(outsideWorld + (distanceWorld - outsideWorld) * share);
        } else if (where != Located::Inside) {
            return leave(outsideWorld);
        }
        const ShellPrism& prism = shell.prisms[cursor.prism];
        const float distance = sample();
        if (!(speed > 0.0) || !std::isfinite(speed) || std::isnan(distance))
            return leave(outsideWorld);
        if (distance < epsilon) {
            if (distance < 0.0f && forcedStep) return refine(distance);
            return stop(true);
        }
        const double zTexels = prism.depthTexels * (1.0 - cursor.point.depthWorld / prism.depthWorld);
        const double toFloorTexels = directionTexels.z < 0.0
                                         ? std::max(zTexels, 0.0) / -directionTexels.z
                                         : std::numeric_limits<double>::infinity();
        if (double(distance) >= toFloorTexels) {
            // The floor is nearer than the detail: end where the depth reaches it (Newton in the
            // distance along the ray, from the linear estimate).
            double floorWorld = distanceWorld + toFloorTexels / speed;
            bool found = false;
            for (int step = 0; step < 8; ++step) {
                if (detail::locate(shell, origin, direction, floorWorld, cursor) !=
                    Located::Inside)
                    break;
                const ShellPrism& at = shell.prisms[cursor.prism];
                detail::texelVelocity(at, cursor.jacobian, direction, prismVelocity);
                const double below = at.depthWorld - cursor.point.depthWorld;
                if (std::abs(below) <= 1e-9 * at.depthWorld) {
                    found = true;
                    break;
                }
                if (!(prismVelocity.z > 0.0)) break;
                floorWorld += below / prismVelocity.z;
            }
            if (found) {
                distanceWorld = floorWorld;
                cursor.point.depthWorld = shell.prisms[cursor.prism].depthWorld;
                if (floor == Floor::Open) return leave(floorWorld);
                end.march.onFloor = true;
                CurvedMarchEnd onFloor = stop(true);
                onFloor.march.texelPosition.z = 0.0f;
                return onFloor;
            }
            // The ray bends away from the floor before it: on as over detail.
            if (detail::locate(shell, origin, direction, distanceWorld, cursor) != Located::Inside)
                return leave(outsideWorld);
        }
        if (iterations >= budget) return stop(false);
        double stepTexels = distance;
        forcedStep = false;
        if (budgeted) {
            // The path left in the shell: to the floor while the ray descends, to the top once it
            // rises again (a ray through a convex shell turns).
            const double pathLeftTexels =
                directionTexels.z > 0.0 ? (prism.depthTexels - zTexels) / directionTexels.z
                                        : toFloorTexels;
            const double minimum = pathLeftTexels / double(budget - iterations);
            if (minimum > stepTexels) {
                stepTexels = minimum;
                forcedStep = true;
            }
        }
        stepTexels = std::min(stepTexels, toFloorTexels);
        outsideWorld = distanceWorld;
        outsideTexels = distance;
        outsideDepthWorld = cursor.point.depthWorld;
        const double stepWorld = stepTexels / speed;
        distanceWorld += stepWorld;
        // The next point's guess: the current one moved along the ray's prism-space velocity.
        cursor.point.b1 += prismVelocity.x * stepWorld;
        cursor.point.b2 += prismVelocity.y * stepWorld;
        cursor.point.depthWorld += prismVelocity.z * stepWorld;
    }
}

}  // namespace distile
