#include "sampler/tile_columns.h"

#include <cstdint>

namespace distile {

TileColumns::TileColumns(const Tile& tile) : size_(tile.size()) {
    constexpr std::size_t kLineFloats = 64 / sizeof(float);
    storage_.resize(size_.texelCount() + kLineFloats);
    float* first = storage_.data();
    while (reinterpret_cast<std::uintptr_t>(first) % 64 != 0) ++first;
    const std::size_t depth = std::size_t(size_.depth);
    for (int y = 0; y < size_.height; ++y) {
        for (int x = 0; x < size_.width; ++x) {
            float* column =
                first + (std::size_t(y) * std::size_t(size_.width) + std::size_t(x)) * depth;
            for (int z = 0; z < size_.depth; ++z) column[z] = tile.at(x, y, z);
        }
    }
    data_ = first;
}

}  // namespace distile
