/// @file
/// Size of a distance tile in texels: width (x), height (y), depth (z, the detail's thickness).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <string_view>

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

/// "WxHxD" (whole numbers joined by 'x', e.g. "256x256x16") to a Size3, not validated (see
/// validateTileSize). Throws InputError::inField(field, "'text' is not a size; write WxHxD, e.g.
/// 256x256x16") for any other text.
Size3 parseSize3(std::string_view text, const std::string& field);

/// "WxH" (e.g. "2x3") to {W, H}, not validated; InputError::inField(field, ...) as parseSize3.
std::array<int, 2> parseSize2(std::string_view text, const std::string& field);

/// Largest tile distile allocates: 2^28 texels (1 GiB of float distances).
inline constexpr std::size_t kMaxTileTexels = std::size_t(1) << 28;

/// The widest narrow band a bake of a tile of `size` accepts, texels on each side of the
/// surface: twice the tile's depth, at most 1024. A tile holds distances only this far: the bake
/// clamps to its band. The cost of a bake grows with the band much faster than linearly (the
/// distance to procedural detail at a point searches the detail within that distance: a 64x64x8
/// chain mail took 11 s at a half band of 64 texels, 3.5 s at 16, on two busy cores).
float maxHalfBandTexels(const Size3& size);

/// The extents a tile may have, texels.
inline constexpr int kMinTileExtent = 2;
inline constexpr int kMaxTileExtent = 65536;

/// Throws InputError unless every extent is in [2, 65536] and the texel count is at most
/// kMaxTileTexels. `what` names the value in the message and is the error's field() (a library
/// passes its options' field, e.g. "size"; a program its flag or JSON path).
void validateTileSize(const Size3& size, const std::string& what);

}  // namespace distile
