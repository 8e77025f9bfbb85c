/// @file
/// Size of a distance tile in texels: width (x), height (y), depth (z, the detail's thickness).
#pragma once

#include <cstddef>
#include <string>

namespace distile {

struct Size3 {
    int width = 256;
    int height = 256;
    int depth = 16;

    /// Number of texels, as a 64-bit count (a Size3 is validated before anything is allocated).
    std::size_t texelCount() const {
        return std::size_t(width) * std::size_t(height) * std::size_t(depth);
    }
    bool operator==(const Size3&) const = default;
};

/// "256x256x16".
std::string toString(const Size3& size);

/// Largest tile distile allocates: 2^28 texels (1 GiB of float distances).
inline constexpr std::size_t kMaxTileTexels = std::size_t(1) << 28;

/// Throws InputError unless every extent is in [2, 65536] and the texel count is at most
/// kMaxTileTexels. `what` names the value in the message and is the error's field() (a library
/// passes its options' field, e.g. "size"; a program its flag or JSON path).
void validateTileSize(const Size3& size, const std::string& what);

}  // namespace distile
