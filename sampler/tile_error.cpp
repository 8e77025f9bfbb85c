#include "sampler/tile_error.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/error.h"

namespace distile {

TileErrorReport measureTileError(const Tile& tile,
                                 const std::function<double(const glm::dvec3&)>& truth,
                                 const TileErrorOptions& options) {
    if (options.samples < 1) {
        throw InputError::inField(
            "samples", std::to_string(options.samples) + " is not accepted; it must be at least 1");
    }
    auto requireNonNegative = [](double value, const char* field) {
        if (!(value >= 0.0 && std::isfinite(value))) {
            throw InputError::inField(field,
                                      numberText(value) +
                                          " is not accepted; it must be a finite number >= 0 "
                                          "(texels)");
        }
    };
    requireNonNegative(options.nearSurfaceTexels, "nearSurfaceTexels");
    requireNonNegative(options.overestimateToleranceTexels, "overestimateToleranceTexels");
    requireNonNegative(options.signMarginTexels, "signMarginTexels");
    if (!(options.truthClampTexels > 0.0)) {
        throw InputError::inField("truthClampTexels", numberText(options.truthClampTexels) +
                                                          " is not accepted; it must be > 0");
    }

    const Size3& size = tile.size();
    // Points from one sequential generator: the same for a seed whatever the thread count.
    std::mt19937_64 random(options.seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<glm::dvec3> points(std::size_t(options.samples));
    for (glm::dvec3& p : points) {
        const double x = unit(random) * size.width;
        const double y = unit(random) * size.height;
        const double z = unit(random) * size.depth;
        p = {x, y, z};
    }
    std::vector<float> tileValues(points.size());
    withFilter(options.filter, tile, [&](const auto& filter) {
        for (std::size_t i = 0; i < points.size(); ++i)
            tileValues[i] = filter.distanceTexels(glm::vec3(points[i]));
    });

    // The truth at every point in parallel (the costly part: an exact mesh distance is
    // microseconds); the report then takes the points in order.
    std::vector<double> truths(points.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i)
                              truths[i] = truth(points[i]);
                      });

    TileErrorReport report;
    report.samples = options.samples;
    double sumSquares = 0.0;
    double nearSumSquares = 0.0;
    std::vector<double> nearErrors;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const double exactDistance = truths[i];
        if (std::isnan(exactDistance)) {
            throw std::runtime_error("the truth distance at (" + std::to_string(points[i].x) +
                                     ", " + std::to_string(points[i].y) + ", " +
                                     std::to_string(points[i].z) + ") is not a number");
        }
        // The tile stores the band and clamps beyond it; what it says about the surface (sign,
        // nearness) is judged on the exact distance.
        const double trueDistance =
            std::clamp(exactDistance, -options.truthClampTexels, options.truthClampTexels);
        if (std::abs(exactDistance) < options.truthClampTexels) ++report.bandSamples;
        const double error = double(tileValues[i]) - trueDistance;
        const double absError = std::abs(error);
        sumSquares += error * error;
        if (absError > report.maxAbsTexels || i == 0) {
            report.maxAbsTexels = absError;
            report.maxAbsAt = points[i];
            report.maxAbsTruthTexels = trueDistance;
        }
        // Deeper inside than the near-surface margin the tile need only read that deep.
        const double overestimate =
            double(tileValues[i]) - std::max(trueDistance, -options.nearSurfaceTexels);
        report.maxOverestimateTexels = std::max(report.maxOverestimateTexels, overestimate);
        if (overestimate > options.overestimateToleranceTexels) ++report.overestimates;
        const double tracerError = double(tileValues[i]) - std::max(trueDistance, 0.0);
        report.maxTracerOverestimateTexels =
            std::max(report.maxTracerOverestimateTexels, tracerError);
        if (tracerError > options.overestimateToleranceTexels) ++report.tracerOverestimates;
        if (std::abs(exactDistance) > options.signMarginTexels &&
            (tileValues[i] < 0.0f) != (exactDistance < 0.0)) {
            ++report.signErrors;
        }
        if (std::abs(exactDistance) <= options.nearSurfaceTexels) {
            nearErrors.push_back(absError);
            nearSumSquares += error * error;
        }
    }
    report.rmsTexels = std::sqrt(sumSquares / double(points.size()));
    report.overestimateShare = double(report.overestimates) / double(points.size());
    report.bandShare = double(report.bandSamples) / double(points.size());
    report.nearSamples = int(nearErrors.size());
    if (!nearErrors.empty()) {
        std::sort(nearErrors.begin(), nearErrors.end());
        report.nearRmsTexels = std::sqrt(nearSumSquares / double(nearErrors.size()));
        report.nearMaxAbsTexels = nearErrors.back();
        report.nearP999Texels = nearErrors[std::size_t(0.999 * double(nearErrors.size() - 1))];
    }
    return report;
}

}  // namespace distile
