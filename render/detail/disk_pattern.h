/// @file
/// The stratified disk of a soft shadow-map lookup (render/shadow_map.cpp): 8 x 8 samples, one per
/// cell of 8 angular by 8 radial strata, jittered inside its cell by the lookup's seed and warped
/// to the unit disk with angle 2 pi u and radius sqrt(v), which keeps the cells' areas equal; the
/// lookup's rotation turns the whole pattern. The trigonometry is taken once per lookup (the
/// middles of the angular strata, turned); a sample turns its stratum's middle by its jitter, an
/// angle of at most pi / 8 either way, whose cosine and sine are short polynomials.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <glm/vec2.hpp>
#include <numbers>

namespace distile::detail {

/// A 32-bit integer hash with good avalanche (the "lowbias32" constants of C. Wellons).
inline constexpr std::uint32_t mixBits(std::uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

/// The top 24 bits of `bits` as a float in [0, 1).
inline float unitFloat(std::uint32_t bits) {
    return float(bits >> 8) * (1.0f / 16777216.0f);
}

/// (cos, sin) of an angle in [-pi / 8, pi / 8] by Taylor polynomials: the first terms left out
/// are below 1.5e-8 there, under a float's rounding.
inline glm::vec2 smallAngleCosSin(float angle) {
    const float a2 = angle * angle;
    const float cosine = 1.0f + a2 * (-1.0f / 2 + a2 * (1.0f / 24 + a2 * (-1.0f / 720)));
    const float sine = angle * (1.0f + a2 * (-1.0f / 6 + a2 * (1.0f / 120 + a2 * (-1.0f / 5040))));
    return {cosine, sine};
}

/// `direction` turned by the angle whose (cos, sin) is `turn`.
inline glm::vec2 turned(const glm::vec2& direction, const glm::vec2& turn) {
    return {direction.x * turn.x - direction.y * turn.y,
            direction.x * turn.y + direction.y * turn.x};
}

/// The disk of one lookup (file note).
class DiskPattern {
  public:
    static constexpr int kStrata = 8;  ///< angular strata, and radial strata
    /// The angle an angular stratum spans, radians.
    static constexpr float kStratumAngle = 2.0f * std::numbers::pi_v<float> / float(kStrata);

    /// The pattern of seed `seed` turned by `rotation` radians.
    DiskPattern(std::uint32_t seed, float rotation) : seed_(seed) {
        const glm::vec2 turn(std::cos(rotation), std::sin(rotation));
        for (int angular = 0; angular < kStrata; ++angular)
            strataMiddles_[std::size_t(angular)] =
                turned(kStrataMiddles[std::size_t(angular)], turn);
    }

    /// Offset in the unit disk of the sample in angular stratum `angular` (counter-clockwise from
    /// the rotation) and radial stratum `radial` (0 at the centre, kStrata - 1 the outer ring).
    glm::vec2 offset(int angular, int radial) const {
        const std::uint32_t bits =
            mixBits(seed_ ^ kCellKeys[std::size_t(radial * kStrata + angular)]);
        const float jitterAngle = (unitFloat(bits) - 0.5f) * kStratumAngle;
        const float radius = std::sqrt((float(radial) + unitFloat(mixBits(bits))) / float(kStrata));
        return radius * turned(strataMiddles_[std::size_t(angular)], smallAngleCosSin(jitterAngle));
    }

    /// The unit direction of the middle of angular stratum `angular`, turned by the rotation.
    glm::vec2 direction(int angular) const { return strataMiddles_[std::size_t(angular)]; }

  private:
    /// Per cell, the key its jitter is hashed from with the seed.
    static constexpr std::array<std::uint32_t, kStrata* kStrata> kCellKeys = [] {
        std::array<std::uint32_t, kStrata * kStrata> keys{};
        for (std::uint32_t cell = 0; cell < keys.size(); ++cell)
            keys[cell] = mixBits(cell + 0x9e3779b9U);
        return keys;
    }();
    /// Unit directions of the middles of the angular strata, unturned.
    static inline const std::array<glm::vec2, kStrata> kStrataMiddles = [] {
        std::array<glm::vec2, kStrata> middles;
        for (int angular = 0; angular < kStrata; ++angular) {
            const double angle = 2.0 * std::numbers::pi * (angular + 0.5) / kStrata;
            middles[std::size_t(angular)] = glm::vec2(std::cos(angle), std::sin(angle));
        }
        return middles;
    }();

    std::uint32_t seed_;
    std::array<glm::vec2, kStrata> strataMiddles_;
};

}  // namespace distile::detail
