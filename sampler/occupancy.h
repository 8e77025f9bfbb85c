/// @file
/// The empty space above a tile's detail, for empty-space skipping in the march: per
/// block of kBlockTexels x kBlockTexels texel columns, the height above which the trilinear (or
/// nearest) reconstruction is at least a threshold everywhere over the block. A ray that descends
/// through the top face crosses the blocks' empty parts in one step each (a 2D walk over the
/// blocks it passes) and starts its march where it first reaches a block's top.
///
/// Why the tops are conservative: between slice centres (z in [k + 0.5, k + 1.5]) the trilinear
/// value is a convex combination of the 8 corner texels of slices k and k + 1, and over a block's
/// columns [x0, x1) those corners lie in the columns x0 - 1 .. x1 (same in y). So above the highest
/// slice kTop holding a value below the threshold in those columns, z >= kTop + 1.5, every value
/// is at least the threshold. The outer half texels extrapolate the edge cells (sampler/filters.h):
/// the top one is checked at the face z = D, where it is lowest if anywhere. The nearest filter
/// reads a subset of the same texels.
///
/// The cubic B-spline's weights are never negative and sum to one, so its value too is a convex
/// combination, of its 4 x 4 x 4 taps: columns x0 - 2 .. x1 + 1 and slices from two below to one
/// above, so everything is at least the threshold above kTop + 2.5; its ghost taps above the top
/// slice (the edge cell's line at slices D and D + 1) are checked like stored ones.
#pragma once

#include <glm/vec3.hpp>
#include <vector>

#include "sampler/tile.h"

namespace distile {

/// The filters whose support an occupancy bounds.
enum class OccupancySupport {
    Linear,        ///< trilinear and nearest
    CubicBSpline,  ///< the tricubic B-spline (not Catmull-Rom: its weights go negative)
};

class TileOccupancy {
  public:
    static constexpr int kBlockTexels = 8;
    /// Blocks whose top is less than this far below the face z = D count as full (top = D).
    static constexpr float kMinimumSkipTexels = 5.0f;

    /// Tops of every block of `tile` for `thresholdTexels` (the march's hit threshold: a point
    /// above a top is not a hit).
    TileOccupancy(const Tile& tile, float thresholdTexels,
                  OccupancySupport support = OccupancySupport::Linear);

    /// Height z (texels, in [0, D]) above which every value of the filter over block (blockX,
    /// blockY) is at least the threshold. Preconditions: indices within blocksX(), blocksY().
    float topTexels(int blockX, int blockY) const {
        return tops_[std::size_t(blockY) * std::size_t(blocksX_) + std::size_t(blockX)];
    }
    /// False when every block is full (top = D): no ray can skip anything.
    bool hasEmptySpace() const { return hasEmptySpace_; }
    /// The highest top of all blocks (texels): emptyTravelTexels without the walk descends to it.
    float highestTopTexels() const { return highestTop_; }
    int blocksX() const { return blocksX_; }
    int blocksY() const { return blocksY_; }

    /// Length (texels) of the empty path from `start` along `direction` (unit, direction.z < 0)
    /// before the ray first reaches the top of the block it is over: the march can start there.
    /// 0 when `start` is already at or below its block's top; not finite inputs give 0. With
    /// `walkBlocks` false only the path down to the highest top of all blocks (one step, no walk;
    /// for marches whose samples cost less than the walk).
    float emptyTravelTexels(const glm::vec3& start, const glm::vec3& direction,
                            bool walkBlocks = true) const;

  private:
    int width_, height_;
    int blocksX_, blocksY_;
    std::vector<float> tops_;
    float highestTop_ = 0.0f;  ///< of all blocks
    bool hasEmptySpace_ = false;
};

}  // namespace distile
