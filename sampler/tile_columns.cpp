#include "sampler/tile_columns.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace distile {

TileColumns::TileColumns(const Tile& tile) : size_(tile.size()) {
    constexpr int kLargestCode = 32767;
    // The largest |distance|: a maximum, the same in any order (NaN is skipped either way).
    const std::span<const float> distances = tile.distancesTexels();
    const float largest = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, distances.size()), 0.0f,
        [&](const tbb::blocked_range<std::size_t>& range, float partial) {
            for (std::size_t i = range.begin(); i != range.end(); ++i)
                partial = std::max(partial, std::abs(distances[i]));
            return partial;
        },
        [](float a, float b) { return std::max(a, b); });
    if (largest > 0.0f && std::isfinite(largest)) texelsPerCode_ = largest / float(kLargestCode);
    // Codes round down: code x texelsPerCode <= distance (see the file note).
    const double codesPerTexel = 1.0 / double(texelsPerCode_);
    auto codeOf = [&](float distance) {
        // std::floor of the clamped value (the same as clamping the floor: the bounds are whole),
        // by truncation, exact in this range; without SSE4.1 std::floor is a libm call a texel.
        const double code = std::clamp(double(distance) * codesPerTexel, -double(kLargestCode),
                                       double(kLargestCode));
        if (!(code == code)) return std::int16_t(0);  // NaN
        const int truncated = int(code);
        return std::int16_t(double(truncated) > code ? truncated - 1 : truncated);
    };

    constexpr std::size_t kLineCodes = 64 / sizeof(std::int16_t);
    storage_.resize(size_.texelCount() + kLineCodes);
    std::int16_t* first = storage_.data();
    while (reinterpret_cast<std::uintptr_t>(first) % 64 != 0) ++first;
    const std::size_t depth = std::size_t(size_.depth);
    // Rows in parallel, each read slice by slice in the tile's order (x fastest): every code
    // depends on its texel only, so the columns are the same on any thread count.
    tbb::parallel_for(
        tbb::blocked_range<int>(0, size_.height), [&](const tbb::blocked_range<int>& rows) {
            for (int y = rows.begin(); y != rows.end(); ++y) {
                std::int16_t* row = first + std::size_t(y) * std::size_t(size_.width) * depth;
                for (int z = 0; z < size_.depth; ++z) {
                    const float* slice = &distances[tile.index(0, y, z)];
                    for (int x = 0; x < size_.width; ++x)
                        row[std::size_t(x) * depth + std::size_t(z)] = codeOf(slice[x]);
                }
            }
        });
    codes_ = first;
}

}  // namespace distile
