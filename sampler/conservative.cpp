#include "sampler/conservative.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
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

/// Measured path, per texel: the lowering that removes the measured overestimates beyond the
/// allowance. The half-texel grid: point (a, b, m) at texel position (0.5 + a/2, 0.5 + b/2, m/2),
/// a in [0, 2W), b in [0, 2H) (periodic), m in [0, 2D]; texel centres are the points with a and b
/// even and m odd. A point's interpolant is the mean of its 1, 2, 4 or 8 nearest texel centres
/// (the clamped half slabs z < 0.5 and z > D - 0.5 use their slice only), so a point that
/// overestimates by o > allowance (the tolerance: the points are dense) is corrected by lowering
/// each of its corners by r = o - allowance; each texel takes the largest r of its 3 x 3 x 3
/// points. Except: the first and last slice already carry the clamp's error (up to half a texel
/// where the distance changes along z), so the points midway between them and their inner neighbour
/// (weight 1/2 each) lower the inner slice by 2r instead (when the tile has an inner slice).
/// Points none of whose corners is within bandTexels of the surface are not checked.
std::vector<float> measuredLowerings(const Tile& exact, const ExactDistance& exactDistance,
                                     float allowanceTexels, float bandTexels) {
    const Size3 size = exact.size();
    const int pointsX = 2 * size.width, pointsY = 2 * size.height, levels = 2 * size.depth + 1;
    // The tile holds its level set's band: compare with the truth clamped alike.
    float clampTexels = 0.0f;
    for (float value : exact.distancesTexels())
        clampTexels = std::max(clampTexels, std::abs(value));
    const auto point = [&](int a, int b, int m) {
        return std::size_t(a) +
               std::size_t(pointsX) * (std::size_t(b) + std::size_t(pointsY) * std::size_t(m));
    };
    std::vector<float> pointRemovals(std::size_t(pointsX) * pointsY * levels, 0.0f);
    tbb::parallel_for(
        tbb::blocked_range<int>(0, pointsY * levels), [&](const tbb::blocked_range<int>& rows) {
            for (int row = rows.begin(); row != rows.end(); ++row) {
                const int b = row % pointsY, m = row / pointsY;
                // Corner texels along each axis: one when the point is on a texel plane, two
                // (weight 1/2 each) midway.
                const int y0 = b / 2, y1 = b % 2 == 0 ? y0 : wrapped(y0 + 1, size.height);
                const int z0 = m % 2 == 1 ? (m - 1) / 2 : std::max(m / 2 - 1, 0);
                const int z1 = m % 2 == 1 ? z0 : std::min(m / 2, size.depth - 1);
                for (int a = 0; a < pointsX; ++a) {
                    if (a % 2 == 0 && b % 2 == 0 && m % 2 == 1) continue;  // a texel centre
                    const int x0 = a / 2, x1 = a % 2 == 0 ? x0 : wrapped(x0 + 1, size.width);
                    const double interpolated =
                        0.125 *
                        (double(exact.at(x0, y0, z0)) + exact.at(x1, y0, z0) +
                         exact.at(x0, y1, z0) + exact.at(x1, y1, z0) + exact.at(x0, y0, z1) +
                         exact.at(x1, y0, z1) + exact.at(x0, y1, z1) + exact.at(x1, y1, z1));
                    const float nearest =
                        std::min({std::abs(exact.at(x0, y0, z0)), std::abs(exact.at(x1, y1, z1)),
                                  std::abs(exact.at(x1, y0, z0)), std::abs(exact.at(x0, y1, z1))});
                    if (nearest > bandTexels) continue;  // far from the surface: estimated
                    const glm::dvec3 p(0.5 + 0.5 * a, 0.5 + 0.5 * b, 0.5 * m);
                    const double truth =
                        std::clamp(exactDistance(p), -double(clampTexels), double(clampTexels));
                    pointRemovals[point(a, b, m)] =
                        float(std::max(0.0, interpolated - truth - allowanceTexels));
                }
            }
        });
    const bool shiftToInner = size.depth >= 3;
    const int lastLevel = levels - 1;
    std::vector<float> lowerings(exact.distancesTexels().size());
    tbb::parallel_for(
        tbb::blocked_range<int>(0, size.depth), [&](const tbb::blocked_range<int>& slices) {
            for (int k = slices.begin(); k != slices.end(); ++k) {
                const int mBegin = shiftToInner && k == size.depth - 1 ? lastLevel - 1 : 2 * k;
                const int mEnd = shiftToInner && k == 0 ? 1 : 2 * k + 2;
                for (int j = 0; j < size.height; ++j) {
                    for (int i = 0; i < size.width; ++i) {
                        float largest = 0.0f;
                        for (int m = mBegin; m <= mEnd; ++m) {
                            const float factor =
                                shiftToInner && ((k == 1 && m == 2) ||
                                                 (k == size.depth - 2 && m == lastLevel - 2))
                                    ? 2.0f
                                    : 1.0f;
                            for (int b = 2 * j - 1; b <= 2 * j + 1; ++b) {
                                for (int a = 2 * i - 1; a <= 2 * i + 1; ++a) {
                                    largest = std::max(
                                        largest,
                                        factor * pointRemovals[point(wrapped(a, pointsX),
                                                                     wrapped(b, pointsY), m)]);
                                }
                            }
                        }
                        lowerings[exact.index(i, j, k)] = largest;
                    }
                }
            }
        });
    return lowerings;
}

}  // namespace

void makeConservative(Tile& tile, const ConservativeOptions& options,
                      const ExactDistance& exactDistance) {
    auto requireNonNegative = [](float value, const char* field) {
        if (!(value >= 0.0f && std::isfinite(value))) {
            throw InputError(std::string("conservative resampling: ") + field + " = " +
                             std::to_string(value) +
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
    if (exactDistance) {
        // Within the band the measured lowering replaces the estimate.
        const std::vector<float> measured = measuredLowerings(
            tile, exactDistance, options.toleranceTexels, options.measuredBandTexels);
        const std::span<const float> exact = tile.distancesTexels();
        for (std::size_t n = 0; n < lowerings.size(); ++n) {
            if (std::abs(exact[n]) <= options.measuredBandTexels) lowerings[n] = measured[n];
        }
    }
    std::span<float> texels = tile.distancesTexels();
    for (std::size_t n = 0; n < texels.size(); ++n) texels[n] -= lowerings[n];
}

}  // namespace distile
