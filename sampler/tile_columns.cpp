#include "sampler/tile_columns.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace distile {

TileColumns::TileColumns(const Tile& tile) : size_(tile.size()) {
    constexpr int kLargestCode = 32767;
    float largest = 0.0f;
    for (float distance : tile.distancesTexels()) largest = std::max(largest, std::abs(distance));
    if (largest > 0.0f && std::isfinite(largest)) texelsPerCode_ = largest / float(kLargestCode);
    // Codes round down: code x texelsPerCode <= distance (see the file note).
    const double codesPerTexel = 1.0 / double(texelsPerCode_);
    auto codeOf = [&](float distance) {
        const double code = std::floor(double(distance) * codesPerTexel);
        return std::int16_t(std::clamp(code, -double(kLargestCode), double(kLargestCode)));
    };

    constexpr std::size_t kLineCodes = 64 / sizeof(std::int16_t);
    storage_.resize(size_.texelCount() + kLineCodes);
    std::int16_t* first = storage_.data();
    while (reinterpret_cast<std::uintptr_t>(first) % 64 != 0) ++first;
    const std::size_t depth = std::size_t(size_.depth);
    for (int y = 0; y < size_.height; ++y) {
        for (int x = 0; x < size_.width; ++x) {
            std::int16_t* column =
                first + (std::size_t(y) * std::size_t(size_.width) + std::size_t(x)) * depth;
            for (int z = 0; z < size_.depth; ++z) column[z] = codeOf(tile.at(x, y, z));
        }
    }
    codes_ = first;
}

}  // namespace distile
