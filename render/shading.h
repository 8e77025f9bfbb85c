/// @file
/// The shading the renderer and the world reference share (render/renderer.cpp,
/// render/world_reference.cpp): the sky behind everything, an ambient term darkened low in the
/// detail shell, Lambert + Blinn-Phong from directional lights, and the dim colour of back
/// faces; and, for the renderer alone, the share of a light's disk above a surface's horizon
/// (the reference's shadow rays find it). Linear RGB; directions are unit world-space vectors.
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>
#include <glm/vec3.hpp>

namespace distile {

inline constexpr float kSpecularStrength = 0.35f;
inline constexpr float kAmbientStrength = 0.18f;

/// Blinn-Phong exponent 48, as x^32 x^16 by squaring (a libm pow costs more than the rest of
/// the shading).
inline float shininessPower(float x) {
    const float x2 = x * x;
    const float x4 = x2 * x2;
    const float x8 = x4 * x4;
    const float x16 = x8 * x8;
    return x16 * x16 * x16;
}

/// The colour of a ray that hits nothing, by its unit direction (z up).
inline glm::vec3 skyColor(const glm::vec3& direction) {
    const float t = 0.5f + 0.5f * direction.z;
    return glm::mix(glm::vec3(0.18f, 0.19f, 0.21f), glm::vec3(0.55f, 0.62f, 0.72f), t);
}

/// Lambert + Blinn-Phong of one unit-strength directional light: `normal` the unit shading
/// normal, `toLight` the unit direction toward the light, `view` the unit ray direction.
[[gnu::always_inline]] inline glm::vec3 directLight(const glm::vec3& normal,
                                                    const glm::vec3& toLight, const glm::vec3& view,
                                                    const glm::vec3& albedo) {
    const float diffuse = std::max(glm::dot(normal, toLight), 0.0f);
    if (diffuse <= 0.0f) return glm::vec3(0.0f);
    const glm::vec3 halfway = glm::normalize(toLight - view);
    const float specular = shininessPower(std::max(glm::dot(normal, halfway), 0.0f));
    return albedo * diffuse + glm::vec3(kSpecularStrength * specular);
}

/// The share of a directional light's disk above the tangent plane of a surface with unit normal
/// N, where cos(theta) = N . toLight > 0 (a precondition): light from below that plane enters the
/// surface's own object, which neither a shadow map (its bias) nor the shading's cosine sees. The
/// disk is the one the renderer's and the world reference's shadows sample: directions toward
/// toLight + tan(half angle) (u, v), (u, v) uniform on the unit disk of the plane across toLight.
/// Along the in-plane part of N (length sin(theta)) such a direction is above the plane where u >
/// -h, h = cos(theta) / (tan(half angle) sin(theta)): all of the disk while h >= 1 (theta at most
/// 90 degrees less the half angle), else the circular segment 1 - (acos(h) - h sqrt(1 - h^2)) / pi,
/// down to half of it at theta = 90 degrees.
inline float lightDiskShareAboveHorizon(float cosToLight, float tanHalfAngle) {
    // h >= 1 as cos^2 (1 + tan^2) >= tan^2 (cos > 0): no root on the common path.
    const float cos2 = cosToLight * cosToLight, tan2 = tanHalfAngle * tanHalfAngle;
    if (cos2 * (1.0f + tan2) >= tan2) return 1.0f;
    const float sinToLight = std::sqrt(1.0f - cos2);
    // Below 1 but for rounding, which must not take the root below of a negative number.
    const float h = std::min(cosToLight / (tanHalfAngle * sinToLight), 1.0f);
    return 1.0f - (std::acos(h) - h * std::sqrt(1.0f - h * h)) / glm::pi<float>();
}

/// How much of the sky a detail point at texel height `zTexels` (of a shell `depthTexels`
/// deep) sees, the factor of its ambient term: cavities low in the shell see less.
inline float openness(float zTexels, float depthTexels) {
    return 0.35f + 0.65f * std::clamp(zTexels / depthTexels, 0.0f, 1.0f);
}

/// The colour of a back face (the inside of a closed mesh, a plane seen from below) of a
/// material of constant colour `color`.
inline glm::vec3 backFaceColor(const glm::vec3& color) {
    return color * 0.05f;
}

}  // namespace distile
