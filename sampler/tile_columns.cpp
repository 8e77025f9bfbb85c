#include "sampler/tile_columns.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

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
    // Rows in parallel: every code depends on its texel only (built once per render).
    tbb::parallel_for(
        tbb::blocked_range<int>(0, size_.height), [&](const tbb::blocked_range<int>& rows) {
            for (int y = rows.begin(); y != rows.end(); ++y) {
                for (int x = 0; x < size_.width; ++x) {
                    std::int16_t* column =
                        first +
                        (std::size_t(y) * std::size_t(size_.width) + std::size_t(x)) * depth;
                    for (int z = 0; z < size_.depth; ++z) column[z] = codeOf(tile.at(x, y, z));
                }
            }
        });
    codes_ = first;
}

}  // namespace distile
