#include "vdb/height_field.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <memory>
#include <sstream>
#include <utility>
#include <vector>

#include "common/error.h"

namespace distile {

namespace {

int wrap(int index, int count) {
    const int r = index % count;
    return r < 0 ? r + count : r;
}

/// Squared distance from p to triangle (a, b, c), double precision (closest point by Voronoi
/// regions of the vertices, edges and face).
double squaredDistanceToTriangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                 const glm::dvec3& c) {
    const auto squared = [](const glm::dvec3& v) { return glm::dot(v, v); };
    const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return squared(ap);
    const glm::dvec3 bp = p - b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return squared(bp);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return squared(ap - ab * (d1 / (d1 - d3)));
    const glm::dvec3 cp = p - c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return squared(cp);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return squared(ap - ac * (d2 / (d2 - d6)));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        return squared(bp - (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    const double denominator = 1.0 / (va + vb + vc);
    return squared(ap - ab * (vb * denominator) - ac * (vc * denominator));
}

/// Height ranges of the cells (cell (ci, cj) spans x in [ci + 0.5, ci + 1.5], y in [cj + 0.5,
/// cj + 1.5], between four nodes) and of square blocks of kBlockCells x kBlockCells cells, over
/// unwrapped cell indices (block (bi, bj) holds cells [bi B, bi B + B) x [bj B, bj B + B), wrapped
/// into the field), so a search skips whole blocks that cannot hold a nearer triangle.
class SurfaceSearch {
  public:
    static constexpr int kBlockCells = 8;

    /// Blocks covering cells [-marginCells, W + marginCells) x [-marginCells, H + marginCells).
    SurfaceSearch(HeightField fieldNodes, int marginCells) : field_(std::move(fieldNodes)) {
        const HeightField& field = field_;
        cellRange_.resize(field.heightsTexels.size());
        for (int j = 0; j < field.height; ++j) {
            for (int i = 0; i < field.width; ++i) {
                const double a = field.node(i, j), b = field.node(i + 1, j);
                const double c = field.node(i, j + 1), d = field.node(i + 1, j + 1);
                cellRange_[std::size_t(i) + std::size_t(j) * std::size_t(field.width)] =
                    glm::dvec2(std::min(std::min(a, b), std::min(c, d)),
                               std::max(std::max(a, b), std::max(c, d)));
            }
        }
        blockXBegin_ = floorDiv(-marginCells, kBlockCells);
        blockYBegin_ = floorDiv(-marginCells, kBlockCells);
        blocksX_ = floorDiv(field.width + marginCells, kBlockCells) - blockXBegin_ + 1;
        blocksY_ = floorDiv(field.height + marginCells, kBlockCells) - blockYBegin_ + 1;
        blockRange_.resize(std::size_t(blocksX_) * std::size_t(blocksY_));
        for (int by = 0; by < blocksY_; ++by) {
            for (int bx = 0; bx < blocksX_; ++bx) {
                glm::dvec2 range(HUGE_VAL, -HUGE_VAL);
                const int ci0 = (blockXBegin_ + bx) * kBlockCells;
                const int cj0 = (blockYBegin_ + by) * kBlockCells;
                for (int cj = cj0; cj < cj0 + kBlockCells; ++cj) {
                    for (int ci = ci0; ci < ci0 + kBlockCells; ++ci) {
                        const glm::dvec2 cell = cellRange(ci, cj);
                        range = glm::dvec2(std::min(range.x, cell.x), std::max(range.y, cell.y));
                    }
                }
                blockRange_[std::size_t(bx) + std::size_t(by) * std::size_t(blocksX_)] = range;
            }
        }
    }

    /// Exact unsigned distance from `p` to the triangulated surface, or `bound` if nothing is
    /// nearer than `bound`: every block, then every cell, whose box (x/y footprint times its
    /// height range) comes nearer than the best distance so far is tested.
    /// @pre bound >= 0, and p within bound of the blocks' cells (marginCells >= bound + 2 beyond
    /// the footprint).
    double distance(const glm::dvec3& p, double bound) const {
        double best = bound;
        const int ciBegin = int(std::floor(p.x - 1.5 - best)),
                  ciEnd = int(std::floor(p.x - 0.5 + best));
        const int cjBegin = int(std::floor(p.y - 1.5 - best)),
                  cjEnd = int(std::floor(p.y - 0.5 + best));
        // Blocks nearest first, so the best distance shrinks early and the rest are skipped.
        struct Candidate {
            double squared;
            int ci0, cj0;
            bool operator<(const Candidate& other) const { return squared < other.squared; }
        };
        std::vector<Candidate> blocks;
        for (int by = floorDiv(cjBegin, kBlockCells); by <= floorDiv(cjEnd, kBlockCells); ++by) {
            for (int bx = floorDiv(ciBegin, kBlockCells); bx <= floorDiv(ciEnd, kBlockCells);
                 ++bx) {
                const glm::dvec2 range =
                    blockRange_[std::size_t(bx - blockXBegin_) +
                                std::size_t(by - blockYBegin_) * std::size_t(blocksX_)];
                const int ci0 = bx * kBlockCells, cj0 = by * kBlockCells;
                const double squared =
                    boxDistanceSquared(p, ci0 + 0.5, ci0 + kBlockCells + 0.5, cj0 + 0.5,
                                       cj0 + kBlockCells + 0.5, range);
                if (squared < best * best) blocks.push_back({squared, ci0, cj0});
            }
        }
        std::sort(blocks.begin(), blocks.end());
        for (const Candidate& block : blocks) {
            if (block.squared >= best * best) break;
            for (int cj = std::max(block.cj0, cjBegin);
                 cj <= std::min(block.cj0 + kBlockCells - 1, cjEnd); ++cj) {
                for (int ci = std::max(block.ci0, ciBegin);
                     ci <= std::min(block.ci0 + kBlockCells - 1, ciEnd); ++ci) {
                    if (boxDistanceSquared(p, ci + 0.5, ci + 1.5, cj + 0.5, cj + 1.5,
                                           cellRange(ci, cj)) >= best * best) {
                        continue;
                    }
                    const glm::dvec3 n00(ci + 0.5, cj + 0.5, field_.node(ci, cj));
                    const glm::dvec3 n10(ci + 1.5, cj + 0.5, field_.node(ci + 1, cj));
                    const glm::dvec3 n01(ci + 0.5, cj + 1.5, field_.node(ci, cj + 1));
                    const glm::dvec3 n11(ci + 1.5, cj + 1.5, field_.node(ci + 1, cj + 1));
                    const double squared = std::min(squaredDistanceToTriangle(p, n00, n10, n11),
                                                    squaredDistanceToTriangle(p, n00, n11, n01));
                    best = std::min(best, std::sqrt(squared));
                }
            }
        }
        return best;
    }

    const HeightField& field() const { return field_; }

  private:
    static int floorDiv(int value, int divisor) {
        return value >= 0 ? value / divisor : -((-value + divisor - 1) / divisor);
    }

    static double boxDistanceSquared(const glm::dvec3& p, double xLow, double xHigh, double yLow,
                                     double yHigh, const glm::dvec2& zRange) {
        const auto gap = [](double value, double low, double high) {
            return value < low ? low - value : (value > high ? value - high : 0.0);
        };
        const double dx = gap(p.x, xLow, xHigh), dy = gap(p.y, yLow, yHigh),
                     dz = gap(p.z, zRange.x, zRange.y);
        return dx * dx + dy * dy + dz * dz;
    }

    glm::dvec2 cellRange(int ci, int cj) const {
        return cellRange_[std::size_t(wrap(ci, field_.width)) +
                          std::size_t(wrap(cj, field_.height)) * std::size_t(field_.width)];
    }

    HeightField field_;
    std::vector<glm::dvec2> cellRange_;
    int blockXBegin_ = 0, blockYBegin_ = 0, blocksX_ = 0, blocksY_ = 0;
    std::vector<glm::dvec2> blockRange_;
};

}  // namespace

double HeightField::node(int i, int j) const {
    return heightsTexels[std::size_t(wrap(i, width)) +
                         std::size_t(wrap(j, height)) * std::size_t(width)];
}

void validateHeightField(const HeightField& field, const Size3& tile, const std::string& what) {
    if (field.width != tile.width || field.height != tile.height ||
        field.heightsTexels.size() != std::size_t(field.width) * std::size_t(field.height)) {
        std::ostringstream message;
        message << what << ": height field of " << field.width << "x" << field.height << " nodes ("
                << field.heightsTexels.size() << " heights) does not match the " << tile.width
                << "x" << tile.height << " tile footprint; one height per texel column is expected";
        throw InputError(message.str());
    }
    for (std::size_t n = 0; n < field.heightsTexels.size(); ++n) {
        const double h = field.heightsTexels[n];
        if (!(std::isfinite(h) && h >= 0.0 && h <= double(tile.depth))) {
            std::ostringstream message;
            message << what << ": height " << h << " at node (" << n % std::size_t(field.width)
                    << ", " << n / std::size_t(field.width)
                    << ") is not accepted; heights must be finite and in [0, " << tile.depth
                    << "] texels";
            throw InputError(message.str());
        }
    }
}

double heightFieldSurfaceTexels(const HeightField& field, double x, double y) {
    const double u = x - 0.5, v = y - 0.5;
    const double iFloor = std::floor(u), jFloor = std::floor(v);
    const double fx = u - iFloor, fy = v - jFloor;
    const int i = int(iFloor), j = int(jFloor);
    const double h00 = field.node(i, j), h10 = field.node(i + 1, j);
    const double h01 = field.node(i, j + 1), h11 = field.node(i + 1, j + 1);
    // Split along the (i, j)-(i+1, j+1) diagonal: triangle (00, 10, 11) below it, (00, 11, 01)
    // above.
    if (fx >= fy) return h00 + fx * (h10 - h00) + fy * (h11 - h10);
    return h00 + fy * (h01 - h00) + fx * (h11 - h01);
}

TriangleSoup heightFieldTriangles(const HeightField& field, int marginNodes) {
    TriangleSoup soup;
    const int first = -marginNodes;
    const int columns = field.width + 2 * marginNodes + 1;  // nodes along x
    const int rows = field.height + 2 * marginNodes + 1;
    soup.positions.reserve(std::size_t(columns) * std::size_t(rows));
    for (int j = 0; j < rows; ++j) {
        for (int i = 0; i < columns; ++i) {
            soup.positions.emplace_back(first + i + 0.5, first + j + 0.5,
                                        field.node(first + i, first + j));
        }
    }
    const auto index = [columns](int i, int j) { return unsigned(i + j * columns); };
    soup.triangles.reserve(2 * std::size_t(columns - 1) * std::size_t(rows - 1));
    for (int j = 0; j + 1 < rows; ++j) {
        for (int i = 0; i + 1 < columns; ++i) {
            // Counter-clockwise seen from above (+z), split as heightFieldSurfaceTexels does.
            soup.triangles.emplace_back(index(i, j), index(i + 1, j), index(i + 1, j + 1));
            soup.triangles.emplace_back(index(i, j), index(i + 1, j + 1), index(i, j + 1));
        }
    }
    return soup;
}

struct HeightFieldDistance::Search {
    SurfaceSearch surface;
    double limitTexels;
};

HeightFieldDistance::HeightFieldDistance(HeightField field, double limitTexels)
    : search_(std::make_unique<const Search>(
          Search{SurfaceSearch(std::move(field), int(std::ceil(limitTexels)) + 2), limitTexels})) {}
HeightFieldDistance::HeightFieldDistance(HeightFieldDistance&&) noexcept = default;
HeightFieldDistance::~HeightFieldDistance() = default;

const HeightField& HeightFieldDistance::field() const {
    return search_->surface.field();
}

double HeightFieldDistance::signedDistanceTexels(const glm::dvec3& texel) const {
    // The vertical distance to the surface bounds the distance (the surface point straight above
    // or below); the exact search over the cells nearer than that finds it.
    const double surfaceHeight = heightFieldSurfaceTexels(field(), texel.x, texel.y);
    const double bound = std::min(std::abs(texel.z - surfaceHeight), search_->limitTexels);
    const double unsignedDistance = search_->surface.distance(texel, bound);
    return texel.z < surfaceHeight ? -unsignedDistance : unsignedDistance;
}

LevelSet levelSetFromHeightField(const HeightField& field, const Size3& tile, float halfBandTexels,
                                 const std::string& source, const std::string& params,
                                 const ProgressCallback& progress) {
    validateTileSize(tile, "height field level set");
    if (!(halfBandTexels >= 1.0f && halfBandTexels <= 1024.0f)) {
        throw InputError("height field level set: half band width " + numberText(halfBandTexels) +
                         " texels is not accepted; it must be in [1, 1024]");
    }
    validateHeightField(field, tile, "height field level set");
    // The level set's band clamps the distance: only cells within the band plus a cell's
    // diagonal are searched.
    const HeightFieldDistance surface(field, double(halfBandTexels) + 2.0);
    return LevelSet::fromDistance(
        [&](const glm::dvec3& texel) { return surface.signedDistanceTexels(texel); }, tile,
        halfBandTexels, source, params, progress);
}

}  // namespace distile
