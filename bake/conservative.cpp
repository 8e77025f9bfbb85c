#include "bake/conservative.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <string>
#include <vector>

#include "common/error.h"

namespace distile {

namespace {

int wrapped(int index, int count) {
    return index < 0 ? index + count : (index >= count ? index - count : index);
}

/// Estimated path: per texel, sum over the axes of g(positive second difference).
std::vector<float> estimatedOverestimates(const Tile& exact, const ConservativeOptions& options) {
    const Size3 size = exact.size();
    auto estimate = [&](float secondDifference) {
        const float positive = std::max(secondDifference, 0.0f);
        return positive > options.kinkThresholdTexels ? options.kinkFactor * positive
                                                      : options.smoothFactor * positive;
    };
    std::vector<float> overestimates(exact.distancesTexels().size());
    tbb::parallel_for(
        tbb::blocked_range<int>(0, size.depth), [&](const tbb::blocked_range<int>& slices) {
            for (int z = slices.begin(); z != slices.end(); ++z) {
                // The centred z difference of the first and last slice is that of their inner
                // neighbour.
                const int zCentre = size.depth < 3 ? -1 : std::clamp(z, 1, size.depth - 2);
                for (int y = 0; y < size.height; ++y) {
                    const int yBelow = wrapped(y - 1, size.height);
                    const int yAbove = wrapped(y + 1, size.height);
                    for (int x = 0; x < size.width; ++x) {
                        const int xBelow = wrapped(x - 1, size.width);
                        const int xAbove = wrapped(x + 1, size.width);
                        const float centre = exact.at(x, y, z);
                        float overestimate = estimate(exact.at(xAbove, y, z) - 2.0f * centre +
                                                      exact.at(xBelow, y, z)) +
                                             estimate(exact.at(x, yAbove, z) - 2.0f * centre +
                                                      exact.at(x, yBelow, z));
                        if (zCentre >= 0) {
                            overestimate += estimate(exact.at(x, y, zCentre + 1) -
                                                     2.0f * exact.at(x, y, zCentre) +
                                                     exact.at(x, y, zCentre - 1));
                        }
                        overestimates[exact.index(x, y, z)] = overestimate;
                    }
                }
            }
        });
    return overestimates;
}

/// Estimated path: per column, the removal asked at the face z = 0 (index 0) and z = D (index 1),
/// texels, where the filter extends the edge cell linearly (face = 1.5 v_edge - 0.5 v_inner):
/// - at least the edge slice's own lowering `estimatedLowerings` (what the slice overestimates
///   between samples in x and y, the face has too);
/// - extrapolating half a texel errs by -3/8 of the second difference: an overestimate where the
///   field is concave in z (second difference D1 < 0 at the edge slice's inner neighbour);
/// - a concave kink (where the nearest wire changes) between the edge slice and the face is not
///   in the samples at all, and the extension then overestimates by up to half the rise toward
///   the face (Japanese 4-in-1: 0.2 texel at 0.1% of the samples). Where some D1 of the 3 x 3
///   columns around is negative, the face is held at the edge slice's value (removal: half the
///   rise v_edge - v_inner), as the clamp to the slice did.
/// Each term less the allowance. Only the first when D < 3.
std::array<std::vector<float>, 2> estimatedFaceRemovals(const Tile& exact,
                                                        std::span<const float> estimatedLowerings,
                                                        float allowanceTexels) {
    const Size3 size = exact.size();
    const std::size_t columns = std::size_t(size.width) * std::size_t(size.height);
    const std::span<const float> texels = exact.distancesTexels();
    std::array<std::vector<float>, 2> removals;
    for (int face = 0; face < 2; ++face) {
        const int edge = face == 0 ? 0 : size.depth - 1;
        const int inner = face == 0 ? 1 : size.depth - 2;
        removals[face].assign(estimatedLowerings.begin() + std::ptrdiff_t(edge * columns),
                              estimatedLowerings.begin() + std::ptrdiff_t((edge + 1) * columns));
        if (size.depth < 3) continue;
        const float* below = &texels[std::size_t(inner - 1) * columns];
        const float* centre = &texels[std::size_t(inner) * columns];
        const float* above = &texels[std::size_t(inner + 1) * columns];
        const auto secondDifference = [&](std::size_t n) {
            return above[n] - 2.0f * centre[n] + below[n];
        };
        for (int y = 0; y < size.height; ++y) {
            for (int x = 0; x < size.width; ++x) {
                const std::size_t n = std::size_t(y) * size.width + x;
                removals[face][n] =
                    std::max(removals[face][n], -0.375f * secondDifference(n) - allowanceTexels);
                float concavest = 0.0f;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx)
                        concavest = std::min(
                            concavest, secondDifference(std::size_t(wrapped(y + dy, size.height)) *
                                                            size.width +
                                                        wrapped(x + dx, size.width)));
                if (concavest < 0.0f) {
                    const float edgeValue = face == 0 ? below[n] : above[n];
                    const float rise = edgeValue - centre[n];
                    removals[face][n] = std::max(removals[face][n], 0.5f * rise - allowanceTexels);
                }
            }
        }
    }
    return removals;
}

/// What the measured path asks of each texel: the lowering of its own points, and for the first
/// and last slice the removal asked by the face points (kept apart: see raiseEdgeSlicesForFaces).
struct MeasuredLowerings {
    std::vector<float> lowerings;  ///< per texel, texels
    /// Per column (x fastest, then y): the largest removal of the face points z = 0 (index 0)
    /// and z = D (index 1) next to it, texels.
    std::array<std::vector<float>, 2> faceRemovals;
};

/// Measured path, per texel: the lowering that removes the measured overestimates beyond the
/// allowance. The half-texel grid: point (a, b, m) at texel position (0.5 + a/2, 0.5 + b/2, m/2),
/// a in [0, 2W), b in [0, 2H) (periodic), m in [0, 2D]; texel centres are the points with a and b
/// even and m odd. Inside the slab a point's interpolant is the mean of its 1, 2, 4 or 8 nearest
/// texel centres, so a point that overestimates by o > allowance (the tolerance: the points are
/// dense) is corrected by lowering each of its corners by r = o - allowance; each texel takes the
/// largest r of its 3 x 3 x 3 points. The face points (m = 0 and m = 2D) interpolate 1.5 x the
/// edge slice - 0.5 x its inner neighbour (the filter's linear extension): their r is returned
/// per column for raiseEdgeSlicesForFaces. A point is checked when one of its corners is within
/// bandTexels of the surface or, given `estimatedLowerings` (per texel), has an estimated lowering
/// > 0: a kink or a curvature the estimate sees, however far from the surface. Other points are
/// not checked (a texel's lowering then comes from its checked points only). A point's target is
/// max(exact, -insideFloorTexels): more than insideFloorTexels inside the detail it must only read
/// at most -insideFloorTexels (plus the allowance); 0 makes the target the distance to the
/// outside.
MeasuredLowerings measuredLowerings(const Tile& exact, const ExactDistancesOnLine& exactDistances,
                                    float allowanceTexels, float bandTexels,
                                    double insideFloorTexels,
                                    std::span<const float> estimatedLowerings) {
    const Size3 size = exact.size();
    const int pointsX = 2 * size.width, pointsY = 2 * size.height, levels = 2 * size.depth + 1;
    const int lastLevel = levels - 1;
    // The tile holds its level set's band: compare with the truth clamped alike.
    float clampTexels = 0.0f;
    for (float value : exact.distancesTexels())
        clampTexels = std::max(clampTexels, std::abs(value));
    const auto point = [&](int a, int b, int m) {
        return std::size_t(a) +
               std::size_t(pointsX) * (std::size_t(b) + std::size_t(pointsY) * std::size_t(m));
    };
    std::vector<float> pointRemovals(std::size_t(pointsX) * pointsY * levels, 0.0f);
    // The two slices level m interpolates, and their weights: one slice (weights 1/2 each) when
    // the level is a texel plane, two midway; on the faces the edge cell's two slices, weights
    // 1.5 on the edge slice and -0.5 on its inner neighbour.
    struct LevelSlices {
        int z0, z1;
        double weight0, weight1;
    };
    std::vector<LevelSlices> levelSlices(static_cast<std::size_t>(levels));
    for (int m = 0; m < levels; ++m) {
        LevelSlices& slices = levelSlices[std::size_t(m)];
        slices = m % 2 == 1 ? LevelSlices{(m - 1) / 2, (m - 1) / 2, 0.5, 0.5}
                            : LevelSlices{m / 2 - 1, m / 2, 0.5, 0.5};
        if (m == 0) slices = {0, 1, 1.5, -0.5};
        if (m == lastLevel) slices = {size.depth - 2, size.depth - 1, -0.5, 1.5};
    }
    // Raw pointers into the tile and the estimate: the loops below run for every point.
    const float* distances = exact.distancesTexels().data();
    const float* estimates = estimatedLowerings.data();
    const std::size_t sliceStride = std::size_t(size.width) * std::size_t(size.height);
    // A column of points (a, b) at a time: its points that need the truth, one line for
    // exactDistances.
    tbb::parallel_for(
        tbb::blocked_range<int>(0, pointsX * pointsY), [&](const tbb::blocked_range<int>& columns) {
            std::vector<double> z, interpolated, truth;
            std::vector<int> level;
            for (int column = columns.begin(); column != columns.end(); ++column) {
                const int a = column % pointsX, b = column / pointsX;
                // Corner texels along each axis: one when the point is on a texel plane, two
                // midway. Texel (x, y, k) of a corner column is its element k * sliceStride.
                const int x0 = a / 2, x1 = a % 2 == 0 ? x0 : wrapped(x0 + 1, size.width);
                const int y0 = b / 2, y1 = b % 2 == 0 ? y0 : wrapped(y0 + 1, size.height);
                const std::size_t c00 = exact.index(x0, y0, 0), c10 = exact.index(x1, y0, 0),
                                  c01 = exact.index(x0, y1, 0), c11 = exact.index(x1, y1, 0);
                const auto corner = [&](std::size_t columnStart, int zIndex) {
                    return distances[columnStart + std::size_t(zIndex) * sliceStride];
                };
                const auto estimated = [&](std::size_t columnStart, int zIndex) {
                    return estimates[columnStart + std::size_t(zIndex) * sliceStride] > 0.0f;
                };
                const auto sliceMean = [&](int zIndex) {
                    return 0.25 * (double(corner(c00, zIndex)) + corner(c10, zIndex) +
                                   corner(c01, zIndex) + corner(c11, zIndex));
                };
                const bool texelCentreColumn = a % 2 == 0 && b % 2 == 0;
                z.clear();
                interpolated.clear();
                level.clear();
                for (int m = 0; m < levels; ++m) {
                    if (texelCentreColumn && m % 2 == 1) continue;  // a texel centre
                    const auto [z0, z1, weight0, weight1] = levelSlices[std::size_t(m)];
                    const float nearest =
                        std::min(std::min(std::abs(corner(c00, z0)), std::abs(corner(c11, z1))),
                                 std::min(std::abs(corner(c10, z0)), std::abs(corner(c01, z1))));
                    // Beyond the band only next to a texel the estimate lowers (looked up only
                    // there).
                    if (nearest > bandTexels &&
                        (estimatedLowerings.empty() ||
                         !(estimated(c00, z0) || estimated(c10, z0) || estimated(c01, z0) ||
                           estimated(c11, z0) || estimated(c00, z1) || estimated(c10, z1) ||
                           estimated(c01, z1) || estimated(c11, z1)))) {
                        continue;
                    }
                    z.push_back(0.5 * m);
                    interpolated.push_back(weight0 * sliceMean(z0) + weight1 * sliceMean(z1));
                    level.push_back(m);
                }
                if (z.empty()) continue;
                truth.resize(z.size());
                exactDistances({0.5 + 0.5 * a, 0.5 + 0.5 * b}, z, truth);
                for (std::size_t n = 0; n < z.size(); ++n) {
                    const double clamped =
                        std::clamp(truth[n], -double(clampTexels), double(clampTexels));
                    const double target = std::max(clamped, -insideFloorTexels);
                    pointRemovals[point(a, b, level[n])] =
                        float(std::max(0.0, interpolated[n] - target - allowanceTexels));
                }
            }
        });
    // The largest removal of the 3 x 3 points around column (i, j) at level m.
    const float* removals = pointRemovals.data();
    const auto largestAround = [&](int i, int j, int m) {
        float largest = 0.0f;
        for (int b = 2 * j - 1; b <= 2 * j + 1; ++b) {
            for (int a = 2 * i - 1; a <= 2 * i + 1; ++a) {
                largest =
                    std::max(largest, removals[point(wrapped(a, pointsX), wrapped(b, pointsY), m)]);
            }
        }
        return largest;
    };
    MeasuredLowerings result;
    result.lowerings.resize(exact.distancesTexels().size());
    tbb::parallel_for(tbb::blocked_range<int>(0, size.depth),
                      [&](const tbb::blocked_range<int>& slices) {
                          for (int k = slices.begin(); k != slices.end(); ++k) {
                              // The levels where slice k has a positive weight, except the faces.
                              const int mBegin = std::max(2 * k, 1);
                              const int mEnd = std::min(2 * k + 2, lastLevel - 1);
                              for (int j = 0; j < size.height; ++j) {
                                  for (int i = 0; i < size.width; ++i) {
                                      float largest = 0.0f;
                                      for (int m = mBegin; m <= mEnd; ++m)
                                          largest = std::max(largest, largestAround(i, j, m));
                                      result.lowerings[exact.index(i, j, k)] = largest;
                                  }
                              }
                          }
                      });
    const std::size_t columns = std::size_t(size.width) * std::size_t(size.height);
    for (int face = 0; face < 2; ++face) {
        result.faceRemovals[face].resize(columns);
        const int m = face == 0 ? 0 : lastLevel;
        for (int j = 0; j < size.height; ++j) {
            for (int i = 0; i < size.width; ++i)
                result.faceRemovals[face][std::size_t(j) * size.width + i] = largestAround(i, j, m);
        }
    }
    return result;
}

/// The filter extends the edge cells to the faces: at z = 0 it interpolates 1.5 L0 - 0.5 L1 of
/// lowerings L0, L1 of the first two slices (alike at z = D). Raises the edge slices' lowering to
/// L0 >= (R + 0.5 L1) / 1.5 per column, R the removal asked at the face (0 where none), so the
/// face drops by at least R and, lowered or not, never rises; the outer half texel, linear between
/// the edge slice and the face, then never rises either. With D = 2 the two edge slices are each
/// other's inner neighbour: the rule is iterated (each pass shrinks the change by 3).
void raiseEdgeSlicesForFaces(std::span<float> lowerings, const Size3& size,
                             const std::array<std::vector<float>, 2>& faceRemovals) {
    const std::size_t columns = std::size_t(size.width) * std::size_t(size.height);
    const int passes = size.depth == 2 ? 12 : 1;
    for (int pass = 0; pass < passes; ++pass) {
        for (int face = 0; face < 2; ++face) {
            const int edge = face == 0 ? 0 : size.depth - 1;
            const int inner = face == 0 ? 1 : size.depth - 2;
            float* edgeSlice = &lowerings[std::size_t(edge) * columns];
            const float* innerSlice = &lowerings[std::size_t(inner) * columns];
            for (std::size_t n = 0; n < columns; ++n) {
                edgeSlice[n] =
                    std::max(edgeSlice[n], (faceRemovals[face][n] + 0.5f * innerSlice[n]) / 1.5f);
            }
        }
    }
}

}  // namespace

void makeConservative(Tile& tile, const ConservativeOptions& options,
                      const ExactDistancesOnLine& exactDistances) {
    auto requireNonNegative = [](float value, const char* field) {
        if (!(value >= 0.0f && std::isfinite(value))) {
            throw InputError(std::string("conservative resampling: ") + field + " = " +
                             numberText(value) +
                             " is not accepted; it must be a finite number >= 0");
        }
    };
    requireNonNegative(options.toleranceTexels, "tolerance");
    requireNonNegative(options.allowanceShare, "allowance share");
    requireNonNegative(options.smoothFactor, "smooth factor");
    requireNonNegative(options.kinkThresholdTexels, "kink threshold");
    requireNonNegative(options.kinkFactor, "kink factor");
    requireNonNegative(options.measuredBandTexels, "measured band");
    if (!options.enabled) return;

    const float allowance = options.allowanceShare * options.toleranceTexels;
    std::vector<float> lowerings;
    lowerings = estimatedOverestimates(tile, options);
    for (float& lowering : lowerings) lowering = std::max(0.0f, lowering - allowance);
    std::array<std::vector<float>, 2> faceRemovals =
        estimatedFaceRemovals(tile, lowerings, allowance);
    if (exactDistances && options.measuredOnTopOfEstimate) {
        const MeasuredLowerings measured = measuredLowerings(
            tile, exactDistances, options.toleranceTexels, options.measuredBandTexels, 0.0, {});
        for (std::size_t n = 0; n < lowerings.size(); ++n)
            lowerings[n] = std::max(lowerings[n], measured.lowerings[n]);
        for (int face = 0; face < 2; ++face) {
            for (std::size_t n = 0; n < faceRemovals[face].size(); ++n) {
                faceRemovals[face][n] =
                    std::max(faceRemovals[face][n], measured.faceRemovals[face][n]);
            }
        }
    } else if (exactDistances) {
        // Within the band the measured lowering replaces the estimate; beyond it, where the
        // estimate lowers, the points around are measured too and lower further if they ask.
        // Deeper inside the detail than the band a point need only read clearly inside (at most
        // -band): no tracer samples there, and the estimate's lowering of an inner kink (a
        // slab's or a cube's mid-plane, across the whole tile) would cost accuracy for nothing,
        // so the measured lowering alone holds there too.
        const float band = options.measuredBandTexels;
        const MeasuredLowerings measured = measuredLowerings(
            tile, exactDistances, options.toleranceTexels, band, double(band), lowerings);
        const std::span<const float> exact = tile.distancesTexels();
        for (std::size_t n = 0; n < lowerings.size(); ++n) {
            lowerings[n] = exact[n] <= band ? measured.lowerings[n]
                                            : std::max(lowerings[n], measured.lowerings[n]);
        }
        const std::size_t columns = faceRemovals[0].size();
        for (int face = 0; face < 2; ++face) {
            const std::size_t edge = face == 0 ? 0 : exact.size() - columns;
            for (std::size_t n = 0; n < columns; ++n) {
                if (exact[edge + n] <= band) faceRemovals[face][n] = measured.faceRemovals[face][n];
            }
        }
    }
    raiseEdgeSlicesForFaces(lowerings, tile.size(), faceRemovals);
    std::span<float> texels = tile.distancesTexels();
    for (std::size_t n = 0; n < texels.size(); ++n) texels[n] -= lowerings[n];
}

}  // namespace distile
