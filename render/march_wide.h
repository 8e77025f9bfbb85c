/// @file
/// The sphere trace's steps for eight rays at a time with AVX2, or sixteen with AVX-512
/// (render/march.h, marchInterleaved, over TileColumns' trilinear filter): the rays' states in
/// SIMD lanes, one sample of each per round, the steps that go on (a sphere step, the start of
/// the regula falsi refinement and its steps) taken in the lanes with the scalar operations in
/// their order (no FMA), so bit for bit as detail::SphereTraceRay takes them. The step that ends
/// a march (or takes back a relaxed step) is left to SphereTraceRay itself. Built in their own
/// translation units with AVX2 and AVX-512 (render/detail/march_lanes.h); plain types only, as
/// sampler/trilinear_wide.h.
#pragma once

#include "sampler/trilinear_wide.h"

namespace distile::detail {

/// The adaptive budget (ch. 8's future work: iterations from the viewing angle): a ray gets one
/// sample per kAdaptiveTexelsPerSample texels of its path to the floor, within [budget / 4,
/// budget]. Steep rays and rays starting low (after empty-space skipping) need few samples; the
/// cut never makes the budgeted march's forced steps (path left over samples left) longer than
/// kAdaptiveTexelsPerSample, so thin detail is not stepped over for it. Half a texel: with one
/// sample per texel, the forced steps of grazing rays passed wire edges the whole budget's did
/// not (budget 32: 1.7% of the chain-mail sheet's pixels changed by more than one 8-bit code,
/// up to 174, at silhouettes); with two, no pixel of the sheet or the low height fields changes.
inline constexpr float kAdaptiveTexelsPerSample = 0.5f;

/// The adaptive budget of rays whose paths to the floor are `pathTexels` (texels; NaN gets the
/// whole budget), written once over lanes L (render/march.h's one ray at a time, the entry
/// kernel's eight): the operations of every lane are the scalar ones, so all agree bit for bit.
template <class L>
typename L::I adaptiveBudgetLanes(int budget, typename L::F pathTexels) {
    const typename L::F samples = L::ceil(L::div(pathTexels, L::set1(kAdaptiveTexelsPerSample)));
    const typename L::M cut = L::less(samples, L::set1(float(budget)));  // false for NaN
    const int quarter = (budget + 3) / 4;
    const int fewest = quarter > 1 ? quarter : 1;
    return L::blend(L::set1(budget),
                    L::max(L::truncate(L::onlyWhere(cut, samples)), L::set1(fewest)), cut);
}

/// A sphere trace between two samples: the state detail::SphereTraceRay keeps (in this form, so
/// the kernel reads and writes it in place), in world-free texel-space floats.
struct SphereTraceLane {
    float start[3];
    float direction[3];  ///< unit
    float toFloorAtStart;
    float travel;        ///< of the point to sample next
    float safeRadius;    ///< distance sampled at the previous point
    float previousStep;  ///< from the previous point to this one
    int iterations;      ///< samples taken
    int maxIterations;
    /// Regula falsi between a point outside (travel, distance) and one inside, sampling at
    /// `estimate` (SphereTraceRay::beginRefining); the fields below are valid when refining.
    bool refining;
    float outside, outsideDistance, inside, insideDistance, estimate;
    /// Out: the distance sampled at `travel`, the step the kernel left to the scalar march
    /// (valid when distanceKnown; false for a point outside the wide filter's near case).
    float pendingDistance;
    bool distanceKnown;
};

/// The march settings every lane of one call shares (detail::SphereTraceRay's).
struct SphereTraceUniforms {
    float epsilonTexels;
    float factor;  ///< step factor: 1, or OverRelaxed's relaxation
    bool budgeted;
};

/// Runs each of `count` lanes' steps that go on (budget left after the step; a sphere step: the
/// distance at least epsilon and short of the floor, no relaxed step to take back; the start of
/// the refinement: a step that went inside; a refinement step: not within epsilon) until the
/// first other step, eight or sixteen lanes at a time: each lane ends in the state before that
/// step, with the distance sampled there. Preconditions: kSimdLevel >= SimdLevel::Avx2; every lane
/// needs a sample.
void sphereTraceOngoingSteps(const WideColumns& columns, const SphereTraceUniforms& uniforms,
                             SphereTraceLane* const* lanes, int count);

/// sphereTraceOngoingSteps sixteen lanes at a time (render/march_wide16.cpp, AVX-512), which it
/// calls where kSimdLevel is Avx512. Precondition: kSimdLevel == SimdLevel::Avx512.
void sphereTraceOngoingSteps16(const WideColumns& columns, const SphereTraceUniforms& uniforms,
                               SphereTraceLane* const* lanes, int count);

/// A self-shadow ray toward a light through a flat shell (the renderer's straight visibility
/// ray): samples from `start` along `direction`, a step of the distance sampled (at least 0.05
/// texel) at a time, until one is nearer to the detail than blockingTexels (blocked), the budget
/// is spent or the next point is at the tile's top, keeping the least distance / (travel x
/// tanHalfAngle) seen. The state the ray keeps, in this form so the kernel reads and writes it in
/// place.
struct VisibilityLane {
    float start[3];
    float direction[3];    ///< unit, texel space, toward the light
    float depthTexels;     ///< z of the tile's top
    float tanHalfAngle;    ///< of the light's angular radius
    float blockingTexels;  ///< a sample nearer to the detail than this blocks the light
    float visibility;      ///< the least distance / (travel x tanHalfAngle) so far
    float travel;          ///< of the point to sample next
    int samplesLeft;
    int samples;  ///< taken
    bool blocked;
    bool needsSample;
};

/// Takes the samples of each of `count` lanes (each needing one) eight or sixteen at a time, with
/// the scalar operations in their order (no FMA), as the ray takes them one by one, until its
/// march ends or its next point is one the wide filter does not take (that sample is left to the
/// ray, whose needsSample stays set). Precondition: kSimdLevel >= SimdLevel::Avx2.
void visibilitySteps(const WideColumns& columns, VisibilityLane* const* lanes, int count);

/// visibilitySteps sixteen lanes at a time (AVX-512), which it calls where kSimdLevel is Avx512.
void visibilitySteps16(const WideColumns& columns, VisibilityLane* const* lanes, int count);

}  // namespace distile::detail
