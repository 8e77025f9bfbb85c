/// @file
/// A tile's texels re-laid in columns for sampling speed: texel (x, y, z) at (y W + x) D + z, z
/// fastest, as 16-bit codes (distance = code x texelsPerCode), the data starting on a 64-byte
/// boundary. A march along a steep ray stays in the same few columns, and the z taps of a filter
/// are adjacent, so the texels a ray needs share cache lines; at 2 bytes a texel a 16-deep column
/// is 32 bytes, two columns a line, and the default tile takes 2 MiB instead of 4. The renderer
/// samples its tiles through these (render/tracer.h); filters read either layout
/// (sampler/filters.h, ColumnTexels).
///
/// Codes are the tile's distances divided by texelsPerCode (the tile's largest |distance| over
/// 32767: 0.5e-3 texel for a 16-texel band) rounded *down*, so a stored distance never exceeds
/// the tile's (up to the rounding of one float product): a conservative tile stays conservative.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "sampler/tile.h"

namespace distile {

class TileColumns {
  public:
    explicit TileColumns(const Tile& tile);
    TileColumns(const TileColumns&) = delete;  // codes() points into storage_
    TileColumns& operator=(const TileColumns&) = delete;

    const Size3& size() const { return size_; }
    /// W x H x D codes, column by column.
    const std::int16_t* codes() const { return codes_; }
    /// Texels per code step (> 0).
    float texelsPerCode() const { return texelsPerCode_; }
    std::size_t bytes() const { return size_.texelCount() * sizeof(std::int16_t); }

  private:
    Size3 size_;
    float texelsPerCode_ = 1.0f;
    std::vector<std::int16_t> storage_;  ///< the codes plus room to align codes_
    const std::int16_t* codes_ = nullptr;
};

}  // namespace distile
