/// @file
/// A tile's texels re-laid in columns for sampling speed: texel (x, y, z) at (y W + x) D + z, z
/// fastest, each column starting on a 64-byte boundary when D x 4 bytes is a multiple of 64. A
/// march along a steep ray stays in the same few columns, and the z taps of a filter are adjacent,
/// so the texels a ray needs share cache lines (the Tile's own layout, x fastest, puts every slice
/// in other lines). The renderer samples its tiles through these (render/tracer.h); filters read
/// either layout with the same results (sampler/filters.h, ColumnTexels).
#pragma once

#include <cstddef>
#include <vector>

#include "sampler/tile.h"

namespace distile {

class TileColumns {
  public:
    explicit TileColumns(const Tile& tile);
    TileColumns(const TileColumns&) = delete;  // data() points into storage_
    TileColumns& operator=(const TileColumns&) = delete;

    const Size3& size() const { return size_; }
    /// W x H x D floats, column by column.
    const float* data() const { return data_; }
    std::size_t bytes() const { return size_.texelCount() * sizeof(float); }

  private:
    Size3 size_;
    std::vector<float> storage_;  ///< the texels plus room to align data_
    const float* data_ = nullptr;
};

}  // namespace distile
