/// @file
/// The march of distance mapping (GPU Gems 2, ch. 8) in a tile's texel space: sphere tracing
/// from the entry point on the top (z = D) along a direction normalised in texel space, so each
/// step by the sampled distance is safe for an exact distance field.
#pragma once

#include <cmath>
#include <glm/vec3.hpp>

#include "render/scene.h"

namespace distile {

/// Where a march ended. Positions in texel space, lengths in texels.
struct MarchResult {
    glm::vec3 texelPosition;
    float travelTexels = 0.0f;
    int iterations = 0;
    bool converged = false;  ///< within epsilon of the detail, or on the solid floor
    bool onFloor = false;
    bool exitedFloor = false;  ///< open floor: the ray left the shell through the bottom
};

/// Sphere tracing in texel space (ch. 8) with an early stop below `epsilonTexels`. Preconditions:
/// `direction` unit length with direction.z < 0; `position` inside the tile's slab. The floor z = 0
/// is hit exactly when a step would cross it: the step's sphere is empty of detail, so the floor
/// crossing inside it is the first surface along the ray. A NaN/Inf position or direction (outside
/// the preconditions) returns at once: not converged, no iterations, the position as given.
template <class Filter>
MarchResult march(const Filter& filter, glm::vec3 position, const glm::vec3& direction, Floor floor,
                  int maxIterations, float epsilonTexels) {
    MarchResult result;
    // Without this check a NaN coordinate reads a finite (clamped) texel and can report a converged
    // hit at a NaN position (tests/stress_test.cpp). Once per ray, not per step.
    if (!(std::isfinite(position.x) && std::isfinite(position.y) && std::isfinite(position.z) &&
          std::isfinite(direction.x) && std::isfinite(direction.y) && std::isfinite(direction.z))) {
        result.texelPosition = position;
        return result;
    }
    for (result.iterations = 0; result.iterations < maxIterations; ++result.iterations) {
        const float distance = filter.distanceTexels(position);
        if (distance < epsilonTexels) {
            result.converged = true;
            break;
        }
        if (position.z + distance * direction.z <= 0.0f) {
            const float toFloor = position.z / -direction.z;
            position += direction * toFloor;
            result.travelTexels += toFloor;
            position.z = 0.0f;
            ++result.iterations;
            if (floor == Floor::Solid) {
                result.converged = result.onFloor = true;
            } else {
                result.exitedFloor = true;
            }
            break;
        }
        position += direction * distance;
        result.travelTexels += distance;
    }
    result.texelPosition = position;
    return result;
}

}  // namespace distile
