/// @file
/// Conservative tiles: lowering texels so that trilinear interpolation (sampler/filters.h) does
/// not overestimate the true distance by more than a tolerance.
///
/// A tile stores the exact distance at texel centres, but the trilinear interpolant between them
/// overestimates wherever the field is convex along an axis: outside curved surfaces (by about
/// c/8 for curvature c of the field at unit spacing) and, much more, across the kink of a
/// distance field on a medial axis inside convex material (a wire's centreline: up to half a
/// texel). Overestimates let the sphere tracer step through surface.
///
/// The correction lowers each texel by an estimate of the interpolation overestimate around it,
/// from the positive parts of its second differences D_a along each axis a (periodic in x and y;
/// the first and last slice use the centred difference of their inner neighbour):
///   lowering = max(0, sum_a g(D_a) - 0.9 * toleranceTexels),
///   g(D) = smoothFactor * D                 for D <= kinkThresholdTexels (smooth curvature),
///   g(D) = kinkFactor * D                   above it (a kink between the samples).
/// A lowered corner lowers the interpolant in its cells by the same amount at that corner, so the
/// tile never rises. This is an estimate, not a bound: nothing that only sees samples can bound
/// what happens between them without assumptions on the detail (a feature smaller than a texel is
/// invisible to the samples). The defaults were tuned on the default chain mail and are checked
/// per procedural tile against the analytic truth (tests/sampler_test.cpp, `distile check`).
#pragma once

#include "sampler/tile.h"

namespace distile {

struct ConservativeOptions {
    bool enabled = true;            ///< false: keep the exact texel-centre distances
    float toleranceTexels = 0.05f;  ///< overestimate the correction aims to stay below, texels
    float smoothFactor =
        0.15f;  ///< lowering per unit of second difference (1/8 = exact for constant curvature)
    float kinkThresholdTexels = 0.8f;  ///< second differences above this are treated as kinks
    float kinkFactor = 0.3f;  ///< lowering per unit of second difference at a kink (at most 1/2)
};

/// Lowers the texels of `tile` as the file note says (nothing when !options.enabled). Multi-
/// threaded; the result does not depend on the thread count. Throws InputError when a factor is
/// negative or not finite, or the tolerance is negative.
void makeConservative(Tile& tile, const ConservativeOptions& options);

}  // namespace distile
