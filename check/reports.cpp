#include "check/reports.h"

#include <cmath>

namespace distile {

using nlohmann::json;

nlohmann::json tileCheckJson(const TileCheck& check, const TileCheckOptions& options,
                             const std::string& tileName) {
    const TileErrorReport& report = check.report;
    return {{"tile", tileName},
            {"against", check.against},
            {"samples", report.samples},
            {"seed", options.seed},
            {"units", "texels"},
            {"rms", report.rmsTexels},
            {"max_abs", report.maxAbsTexels},
            {"max_abs_at", {report.maxAbsAt.x, report.maxAbsAt.y, report.maxAbsAt.z}},
            {"max_abs_true_distance", report.maxAbsTruthTexels},
            {"near_surface_texels", 2.0},
            {"near_samples", report.nearSamples},
            {"near_rms", report.nearRmsTexels},
            {"near_max_abs", report.nearMaxAbsTexels},
            {"near_p999_abs", report.nearP999Texels},
            {"overestimate_tolerance", options.maxOverestimateTexels},
            {"overestimates", report.overestimates},
            {"overestimate_share", report.overestimateShare},
            {"max_overestimate", report.maxOverestimateTexels},
            {"tracer_overestimates", report.tracerOverestimates},
            {"max_tracer_overestimate", report.maxTracerOverestimateTexels},
            {"sign_errors", report.signErrors},
            {"band", check.bandTexels},
            {"band_declared", check.bandDeclared},
            {"band_share", report.bandShare},
            {"passed", check.passed()},
            {"failures", check.failures}};
}

const char* const kSilhouetteRule =
    "silhouette: a pixel where both hit and, in either render, one of its 8 neighbours misses or "
    "lies across a depth jump (a step over 1 texel and over twice the steps beside it on the same "
    "line that go the same way); interior: the other both-hit pixels";

namespace {

json classJson(const HitErrorSummary& summary) {
    // No pixel measured in texels: null, not an error of 0.
    const auto hitError = [&](double texels) {
        return summary.hitErrorSamples > 0 ? json(texels) : json(nullptr);
    };
    return {{"pixels", summary.pixels},
            {"hit_error_samples", summary.hitErrorSamples},
            {"hit_error_mean", hitError(summary.meanHitErrorTexels)},
            {"hit_error_p99", hitError(summary.p99HitErrorTexels)},
            {"hit_error_max", hitError(summary.maxHitErrorTexels)},
            {"normal_error_mean_deg", summary.meanNormalErrorDeg}};
}

}  // namespace

nlohmann::json renderComparisonJson(const RenderComparison& c) {
    const HitErrorSummary all{c.bothHit,           c.hitErrorSamples,   c.meanHitErrorTexels,
                              c.p99HitErrorTexels, c.maxHitErrorTexels, c.meanNormalErrorDeg};
    // JSON has no infinity: identical images give "psnr_db": null.
    const json psnr = std::isfinite(c.psnrDb) ? json(c.psnrDb) : json(nullptr);
    return {{"width", c.width},
            {"height", c.height},
            {"pixels", c.pixels},
            {"both_hit", c.bothHit},
            {"coverage_mismatches", c.coverageMismatches},
            {"coverage_mismatch_share", c.coverageMismatchShare},
            {"hit_error_units", "texels"},
            {"interior", classJson(c.interior)},
            {"silhouette", classJson(c.silhouette)},
            {"all_both_hit", classJson(all)},
            {"silhouette_rule", kSilhouetteRule},
            {"psnr_db", psnr},
            {"psnr_of", "sRGB-encoded values in [0, 1], peak 1 (8-bit PSNR for PNGs)"},
            {"heatmap_scale", "hit error, log scale from 0.01 texel (blue) to 100 texels (red)"}};
}

}  // namespace distile
