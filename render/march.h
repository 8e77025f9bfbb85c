/// @file
/// The march of distance mapping (GPU Gems 2, ch. 8) in a tile's texel space, from the entry point
/// on the top (z = D) along a direction normalised in texel space, in four methods:
/// - SphereTracing (ch. 8): step by the sampled distance; every step is safe for a distance that
///   does not overestimate.
/// - OverRelaxed (Keinert et al. 2014, "Enhanced sphere tracing"): step by relaxation x distance
///   while the unbounding spheres of consecutive points overlap, so the segment between them is
///   known to be empty; when they do not, step back to the last safe point and continue as plain
///   sphere tracing. Same hits as SphereTracing, in fewer steps along grazing rays.
/// - Budgeted (the default): sphere tracing whose steps are at least the path left to the floor
///   over the samples left, so every ray reaches the surface or the floor within the budget
///   (plain sphere tracing creeps along grazing rays and stops short); a step that lands inside
///   the detail is refined by regula falsi with the samples left. Where the sampled distance is
///   larger than that minimum, steps are as safe as sphere tracing; where it is smaller, they
///   are fixed steps and can cross a feature thinner than the step along the ray.
/// - Relief (relief mapping, Policarpo et al. 2005): fixed linear steps through the slab until the
///   first point inside the detail, then a binary search between it and the previous point. Can
///   step over features thinner than a step.
/// - FixedSteps: fixed linear steps through the slab until the first point inside, then the zero
///   crossing of the distance interpolated linearly between the last two points.
/// Every method counts one iteration per distance sample.
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/vec3.hpp>

#include "render/scene.h"

namespace distile {

enum class MarchMethod { SphereTracing, OverRelaxed, Budgeted, Relief, FixedSteps };

/// "sphere", "relaxed", "budgeted", "relief", "fixed": the names of the command line and the
/// benchmark.
inline const char* marchMethodName(MarchMethod method) {
    switch (method) {
        case MarchMethod::SphereTracing:
            return "sphere";
        case MarchMethod::OverRelaxed:
            return "relaxed";
        case MarchMethod::Budgeted:
            return "budgeted";
        case MarchMethod::Relief:
            return "relief";
        case MarchMethod::FixedSteps:
            return "fixed";
    }
    return "?";
}

struct MarchSettings {
    MarchMethod method = MarchMethod::Budgeted;
    int maxIterations = 16;       ///< distance samples per ray
    float epsilonTexels = 0.02f;  ///< a point closer than this to the surface is a hit
    /// OverRelaxed: step factor while the spheres overlap, in [1, 2) (1 is plain sphere tracing).
    float relaxation = 1.6f;
    /// Relief: share of the budget spent on the linear search, the rest on the binary search.
    float reliefLinearShare = 0.75f;
};

/// The adaptive budget (ch. 8's future work: iterations from the viewing angle): a ray gets one
/// sample per kAdaptiveTexelsPerSample texels of its path to the floor, within [budget / 4,
/// budget]. Steep rays and rays starting low (after empty-space skipping) need few samples; the
/// cut never makes the budgeted march's forced steps (path left over samples left) longer than
/// kAdaptiveTexelsPerSample, so thin detail is not stepped over for it.
inline constexpr float kAdaptiveTexelsPerSample = 1.0f;

inline int adaptiveBudget(int budget, float pathTexels) {
    const float samples = std::ceil(pathTexels / kAdaptiveTexelsPerSample);
    if (!(samples < float(budget))) return budget;  // also NaN
    return std::max({int(samples), (budget + 3) / 4, 1});
}

/// Where a march ended. Positions in texel space, lengths in texels.
struct MarchResult {
    glm::vec3 texelPosition;
    float travelTexels = 0.0f;
    int iterations = 0;
    bool converged = false;  ///< within epsilon of the detail, or on the solid floor
    bool onFloor = false;
    bool exitedFloor = false;  ///< open floor: the ray left the shell through the bottom
};

namespace detail {

/// Ends a march at the floor z = 0, `toFloor` texels along the ray from `position`.
inline void endOnFloor(MarchResult& result, const glm::vec3& position, const glm::vec3& direction,
                       float travelTexels, float toFloor, Floor floor) {
    result.texelPosition = position + direction * toFloor;
    result.texelPosition.z = 0.0f;
    result.travelTexels = travelTexels + toFloor;
    if (floor == Floor::Solid) {
        result.converged = result.onFloor = true;
    } else {
        result.exitedFloor = true;
    }
}

/// Regula falsi between a point outside (travel `outside`, distance `outsideDistance` >= epsilon)
/// and one inside (distance `insideDistance` < 0) with the budget left; ends converged at the last
/// estimate.
template <class Filter>
void refineCrossing(const Filter& filter, const glm::vec3& start, const glm::vec3& direction,
                    int maxIterations, float epsilonTexels, float outside, float outsideDistance,
                    float inside, float insideDistance, MarchResult& result) {
    float estimate =
        outside + (inside - outside) * outsideDistance / (outsideDistance - insideDistance);
    for (; result.iterations < maxIterations;) {
        ++result.iterations;
        const float distance = filter.distanceTexels(start + direction * estimate);
        if (std::abs(distance) < epsilonTexels) break;
        if (distance > 0.0f) {
            outside = estimate;
            outsideDistance = distance;
        } else {
            inside = estimate;
            insideDistance = distance;
        }
        estimate =
            outside + (inside - outside) * outsideDistance / (outsideDistance - insideDistance);
    }
    result.converged = true;
    result.travelTexels = estimate;
    result.texelPosition = start + direction * estimate;
}

/// Sphere tracing: over-relaxed when relaxation > 1; budgeted when `budgeted` (each step at least
/// the path left to the floor over the samples left, a step that lands inside refined by regula
/// falsi). The floor z = 0 is hit exactly when a safe sphere reaches it: the sphere is empty of
/// detail, so the floor crossing inside it is the first surface along the ray.
template <class Filter>
MarchResult sphereTrace(const Filter& filter, const glm::vec3& start, const glm::vec3& direction,
                        Floor floor, int maxIterations, float epsilonTexels, float relaxation,
                        bool budgeted) {
    MarchResult result;
    const float toFloorAtStart = start.z / -direction.z;
    float travel = 0.0f;        // of the current point
    float safeRadius = 0.0f;    // distance sampled at the previous point
    float previousStep = 0.0f;  // from the previous point to the current one
    float factor = relaxation;
    for (result.iterations = 1; result.iterations <= maxIterations; ++result.iterations) {
        const glm::vec3 position = start + direction * travel;
        const float distance = filter.distanceTexels(position);
        if (factor > 1.0f && previousStep > safeRadius && distance + safeRadius < previousStep) {
            // The relaxed step left the previous sphere and this one does not reach back to it:
            // the gap between them is unverified. Back to the edge of the previous sphere, as
            // plain sphere tracing from here on.
            travel -= previousStep - safeRadius;
            previousStep = safeRadius;
            factor = 1.0f;
            continue;
        }
        if (distance < epsilonTexels) {
            if (distance < 0.0f && previousStep > safeRadius) {
                // A budgeted step went past the surface: find the crossing in between.
                refineCrossing(filter, start, direction, maxIterations, epsilonTexels,
                               travel - previousStep, safeRadius, travel, distance, result);
                return result;
            }
            result.converged = true;
            result.texelPosition = position;
            result.travelTexels = travel;
            return result;
        }
        const float toFloor = toFloorAtStart - travel;
        if (distance >= toFloor) {
            endOnFloor(result, position, direction, travel, toFloor, floor);
            return result;
        }
        float step = factor * distance;
        if (budgeted && result.iterations < maxIterations)
            step = std::max(step, toFloor / float(maxIterations - result.iterations));
        safeRadius = distance;
        previousStep = std::min(step, toFloor);
        travel += previousStep;
    }
    result.iterations = maxIterations;
    // The budget ran out: the last safe point (a longer step beyond it is unverified).
    if (previousStep > safeRadius) travel -= previousStep - safeRadius;
    result.texelPosition = start + direction * travel;
    result.travelTexels = travel;
    return result;
}

/// Fixed linear steps from the top to the floor; at the first point inside (distance below
/// epsilon), Relief refines by binary search with the rest of the budget, FixedSteps by the
/// linear zero crossing of the last two distances.
template <class Filter>
MarchResult stepThroughSlab(const Filter& filter, const glm::vec3& start,
                            const glm::vec3& direction, Floor floor,
                            const MarchSettings& settings) {
    MarchResult result;
    const bool relief = settings.method == MarchMethod::Relief;
    // The last linear step lands on the floor itself, which needs no sample.
    const int linearSteps =
        relief ? std::clamp(int(float(settings.maxIterations) * settings.reliefLinearShare), 1,
                            settings.maxIterations)
               : settings.maxIterations;
    const float toFloor = start.z / -direction.z;
    const float step = toFloor / float(linearSteps + 1);
    float outsideTravel = 0.0f;
    float outsideDistance = -1.0f;  // none sampled yet
    for (result.iterations = 1; result.iterations <= linearSteps; ++result.iterations) {
        const float travel = step * float(result.iterations);
        const float distance = filter.distanceTexels(start + direction * travel);
        if (distance >= settings.epsilonTexels) {
            outsideTravel = travel;
            outsideDistance = distance;
            continue;
        }
        float hitTravel = travel;
        if (relief) {
            float insideTravel = travel;
            for (; result.iterations < settings.maxIterations; ++result.iterations) {
                hitTravel = 0.5f * (outsideTravel + insideTravel);
                if (filter.distanceTexels(start + direction * hitTravel) >=
                    settings.epsilonTexels) {
                    outsideTravel = hitTravel;
                } else {
                    insideTravel = hitTravel;
                }
            }
            hitTravel = insideTravel;
        } else if (outsideDistance > 0.0f) {
            hitTravel = outsideTravel +
                        (travel - outsideTravel) * outsideDistance / (outsideDistance - distance);
        }
        result.converged = true;
        result.travelTexels = hitTravel;
        result.texelPosition = start + direction * hitTravel;
        return result;
    }
    result.iterations = linearSteps;
    endOnFloor(result, start, direction, 0.0f, toFloor, floor);
    return result;
}

}  // namespace detail

/// Marches from `position` along `direction` with `settings` (file note). Preconditions:
/// `direction` unit length with direction.z < 0; `position` inside the tile's slab. A NaN/Inf
/// position or direction (outside the preconditions) returns at once: not converged, no
/// iterations, the position as given.
template <class Filter>
MarchResult march(const Filter& filter, const glm::vec3& position, const glm::vec3& direction,
                  Floor floor, const MarchSettings& settings) {
    // Without this check a NaN coordinate reads a finite (clamped) texel and can report a converged
    // hit at a NaN position (tests/stress_test.cpp). Once per ray, not per step.
    if (!(std::isfinite(position.x) && std::isfinite(position.y) && std::isfinite(position.z) &&
          std::isfinite(direction.x) && std::isfinite(direction.y) && std::isfinite(direction.z))) {
        MarchResult result;
        result.texelPosition = position;
        return result;
    }
    switch (settings.method) {
        case MarchMethod::SphereTracing:
        case MarchMethod::OverRelaxed:
            return detail::sphereTrace(
                filter, position, direction, floor, settings.maxIterations, settings.epsilonTexels,
                settings.method == MarchMethod::OverRelaxed ? settings.relaxation : 1.0f, false);
        case MarchMethod::Budgeted:
            return detail::sphereTrace(filter, position, direction, floor, settings.maxIterations,
                                       settings.epsilonTexels, 1.0f, true);
        case MarchMethod::Relief:
        case MarchMethod::FixedSteps:
            return detail::stepThroughSlab(filter, position, direction, floor, settings);
    }
    return {};
}

/// Plain sphere tracing (ch. 8) with `maxIterations` and `epsilonTexels`.
template <class Filter>
MarchResult march(const Filter& filter, const glm::vec3& position, const glm::vec3& direction,
                  Floor floor, int maxIterations, float epsilonTexels) {
    MarchSettings settings;
    settings.method = MarchMethod::SphereTracing;
    settings.maxIterations = maxIterations;
    settings.epsilonTexels = epsilonTexels;
    return march(filter, position, direction, floor, settings);
}

}  // namespace distile
