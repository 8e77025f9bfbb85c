#include "sampler/occupancy.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "sampler/filters.h"

namespace distile {

TileOccupancy::TileOccupancy(const Tile& tile, float thresholdTexels, OccupancySupport support)
    : width_(tile.size().width),
      height_(tile.size().height),
      blocksX_((tile.size().width + kBlockTexels - 1) / kBlockTexels),
      blocksY_((tile.size().height + kBlockTexels - 1) / kBlockTexels),
      tops_(std::size_t(blocksX_) * std::size_t(blocksY_), float(tile.size().depth)) {
    const Size3& size = tile.size();
    const int depth = size.depth;
    const bool cubic = support == OccupancySupport::CubicBSpline;
    // The support's columns around a block (file note): x0 - around .. x1 - 1 + around.
    const int around = cubic ? 2 : 1;
    // Rows of blocks in parallel: each block's top depends on its own texels only.
    tbb::parallel_for(
        tbb::blocked_range<int>(0, blocksY_), [&](const tbb::blocked_range<int>& rows) {
            for (int by = rows.begin(); by != rows.end(); ++by) {
                for (int bx = 0; bx < blocksX_; ++bx) {
                    const int x0 = bx * kBlockTexels, x1 = std::min(x0 + kBlockTexels, size.width);
                    const int y0 = by * kBlockTexels, y1 = std::min(y0 + kBlockTexels, size.height);
                    // The lowest value over the block's support in slice z.
                    const auto lowestOfSlice = [&](int z) {
                        float low = tile.at(x0, y0, z);
                        for (int y = y0 - around; y < y1 + around; ++y) {
                            const int wrappedY = detail::wrapIndex(y, size.height);
                            for (int x = x0 - around; x < x1 + around; ++x)
                                low = std::min(
                                    low, tile.at(detail::wrapIndex(x, size.width), wrappedY, z));
                        }
                        return low;
                    };
                    const float topSliceLowest = lowestOfSlice(depth - 1);
                    // Above the top slice: the trilinear filter's edge cell extrapolated to the
                    // face z = D, 1.5 v[D-1] - 0.5 v[D-2] per column (its lowest over the support
                    // bounds the whole outer half texel); the cubic filter's ghost taps at slices
                    // D and D + 1, 2 v[D-1] - v[D-2] and 3 v[D-1] - 2 v[D-2].
                    float faceLowest = topSliceLowest;
                    for (int y = y0 - around; y < y1 + around; ++y) {
                        const int wrappedY = detail::wrapIndex(y, size.height);
                        for (int x = x0 - around; x < x1 + around; ++x) {
                            const int wrappedX = detail::wrapIndex(x, size.width);
                            const float last = tile.at(wrappedX, wrappedY, depth - 1);
                            const float belowLast = tile.at(wrappedX, wrappedY, depth - 2);
                            if (cubic) {
                                faceLowest = std::min({faceLowest, 2.0f * last - belowLast,
                                                       3.0f * last - 2.0f * belowLast});
                            } else {
                                faceLowest = std::min(faceLowest, 1.5f * last - 0.5f * belowLast);
                            }
                        }
                    }
                    float top = 0.0f;
                    if (!(faceLowest >= thresholdTexels)) {
                        top = float(depth);  // the slices below do not matter
                    } else {
                        // The highest slice with a value below the threshold, from the top
                        // down (the slices below it do not matter).
                        int highestLow = -1;
                        for (int z = depth - 1; z >= 0; --z) {
                            const float low = z == depth - 1 ? topSliceLowest : lowestOfSlice(z);
                            if (!(low >= thresholdTexels)) {
                                highestLow = z;
                                break;
                            }
                        }
                        // Above slice centre highestLow + 1 (+ 2 for the cubic filter) every tap
                        // is at least the threshold; a column with no low slice is empty down to
                        // where the taps reach below the bottom slice (there the filters
                        // extrapolate, and the floor ends the ray).
                        const float reach = cubic ? 2.5f : 1.5f;
                        top = highestLow < 0 ? reach - 1.0f
                                             : std::min(float(highestLow) + reach, float(depth));
                        // A sliver of empty space is not worth the walk (and moving the march's
                        // start changes where its budgeted steps land): such a block counts as
                        // full.
                        if (top > float(depth) - kMinimumSkipTexels) top = float(depth);
                    }
                    tops_[std::size_t(by) * std::size_t(blocksX_) + std::size_t(bx)] = top;
                }
            }
        });
    for (const float top : tops_) {
        if (top < float(depth)) hasEmptySpace_ = true;
        highestTop_ = std::max(highestTop_, top);
    }
}

float TileOccupancy::emptyTravelTexels(const glm::vec3& start, const glm::vec3& direction,
                                       bool walkBlocks) const {
    if (!(std::isfinite(start.x) && std::isfinite(start.y) && std::isfinite(start.z) &&
          direction.z < 0.0f && std::isfinite(direction.x) && std::isfinite(direction.y))) {
        return 0.0f;
    }
    // Divisions once per ray, not per block: the walk runs for every ray before its march.
    const float perDescent = 1.0f / -direction.z;
    const float perAlongX = 1.0f / direction.x;  // infinite when the ray does not move in x
    const float perAlongY = 1.0f / direction.y;
    const float perWidth = 1.0f / float(width_);
    const float perHeight = 1.0f / float(height_);
    // `coordinate` wrapped into [0, extent) (up to rounding; the block index is clamped).
    auto wrap = [](float coordinate, float extent, float perExtent) {
        const float periods = coordinate * perExtent;
        return coordinate - extent * (std::abs(periods) < 1.0e9f ? detail::floorFinite(periods)
                                                                 : std::floor(periods));
    };
    // Travel from `coordinate` to the block's wall ahead, [lower, upper) along an axis.
    auto toWall = [](float coordinate, float lower, float upper, float along, float perAlong) {
        if (along > 0.0f) return (upper - coordinate) * perAlong;
        if (along < 0.0f) return (lower - coordinate) * perAlong;
        return std::numeric_limits<float>::infinity();
    };
    // No block reaches above the highest top: the path down to it is empty over every block.
    float travel = start.z > highestTop_ ? (start.z - highestTop_) * perDescent : 0.0f;
    if (!walkBlocks) return travel;
    float lookAhead = 0.0f;  // after a wall: which block the ray goes on over, just past the wall
    // Bounded walk: a ray descending through a slab crosses few blocks unless it is grazing; after
    // the bound the march simply starts where the walk stopped (still a safe point).
    constexpr int kMaxBlocks = 64;
    constexpr float kPastWallTexels = 1e-3f;
    for (int step = 0; step < kMaxBlocks; ++step) {
        const glm::vec3 position = start + direction * travel;
        const glm::vec3 probe = start + direction * (travel + lookAhead);
        const float x = wrap(probe.x, float(width_), perWidth);
        const float y = wrap(probe.y, float(height_), perHeight);
        const int blockX = std::clamp(int(x) / kBlockTexels, 0, blocksX_ - 1);
        const int blockY = std::clamp(int(y) / kBlockTexels, 0, blocksY_ - 1);
        const float top = topTexels(blockX, blockY);
        if (position.z <= top) return travel;
        const float toTop = (position.z - top) * perDescent;
        // Travel to the block's side walls (the last block may be narrower than kBlockTexels),
        // measured from the probe, which is in the block.
        const float lowerX = float(blockX * kBlockTexels);
        const float lowerY = float(blockY * kBlockTexels);
        const float toSide =
            lookAhead +
            std::max(0.0f,
                     std::min(toWall(x, lowerX, std::min(lowerX + kBlockTexels, float(width_)),
                                     direction.x, perAlongX),
                              toWall(y, lowerY, std::min(lowerY + kBlockTexels, float(height_)),
                                     direction.y, perAlongY)));
        if (toTop <= toSide) return travel + toTop;
        // On to the wall; the next block is the one just past it. A step that does not advance
        // (rounding at a huge coordinate) ends the walk safely here.
        const float next = travel + toSide;
        if (!(next > travel)) return travel;
        travel = next;
        lookAhead = kPastWallTexels;
    }
    return travel;
}

}  // namespace distile
