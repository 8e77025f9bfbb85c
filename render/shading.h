/// @file
/// The shading the renderer and the world reference share (render/renderer.cpp,
/// render/world_reference.cpp): the sky behind everything, an ambient term darkened low in the
/// detail shell, Lambert + Blinn-Phong from directional lights, and the dim colour of back
/// faces. Linear RGB; directions are unit world-space vectors.
#pragma once

#include <algorithm>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
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
