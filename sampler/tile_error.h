/// @file
/// How far a tile is from the truth: the tile, reconstructed with a filter (trilinear by default),
/// against a truth distance at uniform random points of the tile's volume [0,W) x [0,H) x [0,D)
/// in texel space. All figures in texels. This is what `distile check` prints and the tests
/// assert; the truth (analytic, mesh, level set) is chosen by the caller.
#pragma once

#include <cstdint>
#include <functional>
#include <glm/vec3.hpp>
#include <limits>

#include "sampler/filter_choice.h"
#include "sampler/tile.h"

namespace distile {

struct TileErrorOptions {
    int samples = 100000;    ///< uniform random points, >= 1
    std::uint64_t seed = 1;  ///< the points depend only on the seed and the tile size
    FilterKind filter = FilterKind::Trilinear;
    double nearSurfaceTexels = 2.0;  ///< "near the surface": |true distance| <= this
    double overestimateToleranceTexels =
        0.05;                       ///< tile - truth above this counts as an overestimate
    double signMarginTexels = 1.0;  ///< sign errors are counted where |truth| > this
    /// The truth is clamped to [-this, this] before comparing: a tile stores its level set's
    /// narrow band, distances beyond it clamped to +-band (pass the band the tile declares,
    /// TileProvenance::halfBandTexels; never one read off the tile's own values, which would let
    /// a flat tile compare with a flat truth). Signs and "near the surface" are judged on the
    /// unclamped truth. Infinity: no clamp.
    double truthClampTexels = std::numeric_limits<double>::infinity();
};

struct TileErrorReport {
    int samples = 0;
    int nearSamples = 0;             ///< samples with |truth| <= nearSurfaceTexels
    double rmsTexels = 0.0;          ///< RMS of tile - truth over all samples
    double maxAbsTexels = 0.0;       ///< largest |tile - truth|
    glm::dvec3 maxAbsAt{0.0};        ///< where it occurs (texel space)
    double maxAbsTruthTexels = 0.0;  ///< the true distance there
    double nearRmsTexels = 0.0;      ///< RMS over the near samples (0 if none)
    double nearMaxAbsTexels = 0.0;   ///< largest |error| over the near samples
    double nearP999Texels = 0.0;     ///< 99.9th percentile of |error| over the near samples
    /// Overestimates: tile - max(truth, -nearSurfaceTexels) above overestimateToleranceTexels.
    /// Near the surface and outside, the tile must not read above the truth (a tracer steps by
    /// it, and refines hits between a sample outside and one just inside); deeper inside it need
    /// only read at least that deep: a tile reading -3 where the truth is -4 misleads nothing,
    /// and lowering an inner kink (a slab's mid-plane) to avoid it costs accuracy everywhere on
    /// that plane.
    double maxOverestimateTexels = 0.0;  ///< largest such excess (0 if never above)
    int overestimates = 0;               ///< samples beyond the tolerance
    double overestimateShare = 0.0;      ///< overestimates / samples
    /// The overestimates a sphere tracer can step over the surface by: tile - max(truth, 0) >
    /// overestimateToleranceTexels. Inside the detail a tile above the truth but still below 0
    /// (or within the tolerance of 0) stops no tracer short of the surface or past it.
    int tracerOverestimates = 0;
    double maxTracerOverestimateTexels = 0.0;  ///< largest tile - max(truth, 0), at least 0
    int signErrors = 0;  ///< samples with |truth| > signMarginTexels and the other sign in the tile
    int bandSamples = 0;     ///< samples with |truth| < truthClampTexels (inside the band)
    double bandShare = 0.0;  ///< bandSamples / samples: how much of the tile the band covers
};

/// Samples `tile` with options.filter and `truth` (signed distance in texels at a texel-space
/// point; called from several threads at once, so it must be safe to call concurrently) at
/// options.samples uniform random points. Deterministic for a seed, on any thread count. Throws
/// InputError (naming the TileErrorOptions member) when samples < 1 or a tolerance or margin is
/// negative or not finite; std::runtime_error when the truth returns NaN.
TileErrorReport measureTileError(const Tile& tile,
                                 const std::function<double(const glm::dvec3&)>& truth,
                                 const TileErrorOptions& options = {});

}  // namespace distile
