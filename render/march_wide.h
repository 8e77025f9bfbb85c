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

/// How far beyond the sampled distance a budgeted step may reach toward the surface the last two
/// samples point at (texels; detail::secantStepLanes). On the chain-mail sheet at 1280 x 1024,
/// with the budget of 32: 0 (plain budgeted steps) takes 9.58 samples per ray at a mean hit error
/// of 0.0840 texel, 0.5 takes 8.52 at 0.0790, 1 takes 7.98 at 0.0831, 1.5 7.69 at 0.0800, 2 7.51
/// at 0.0860, and 3 7.28 at 0.153 (steps across wire edges).
inline constexpr float kSecantReachTexels = 1.0f;

/// The budgeted march's secant step over lanes L (SIMD lanes, or march.h's OneLaneOf: one ray, with
/// the same operations in the same order, so all agree bit for bit): where the distance
/// fell from `previousDistance` to `distance` over the last step of `previousStep` texels, the
/// path to where the line through the two samples reaches zero, but at most kSecantReachTexels
/// beyond `distance`; 0 where it did not fall. Near a surface that is flat along the ray this is
/// the hit in one step where sphere tracing approaches it geometrically (a ray at 30 degrees to
/// a plane halves its distance per sphere step); along a convex surface the distance is convex
/// along the ray and the line's zero lies short of the surface. A step that lands inside the
/// detail starts the march's regula falsi, as a forced budgeted step does.
template <class L>
typename L::F secantStepLanes(typename L::F distance, typename L::F previousDistance,
                              typename L::F previousStep) {
    const typename L::M falls =
        L::both(L::greater(previousStep, L::set1(0.0f)), L::less(distance, previousDistance));
    const typename L::F toZero =
        L::div(L::mul(distance, previousStep), L::sub(previousDistance, distance));
    const typename L::F reach = L::add(distance, L::set1(kSecantReachTexels));
    return L::onlyWhere(falls, L::blend(toZero, reach, L::less(reach, toZero)));
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

/// The least step of a self-shadow ray, texels. Near a surface, where the distance sampled is
/// smaller, steps of the distance would crawl along it: on the chain-mail sheet at 640 x 512,
/// 0.2 takes 7.1 samples per detail hit against 8.3 at 0.05, and agrees better with the world
/// reference's 16 shadow rays (mean sRGB difference 3.2, 4.3 and 10.2 codes at lights of 2, 20
/// and 89 degrees, against 3.5, 4.6 and 10.2). Detail thinner than that can be stepped over; a
/// trilinear tile resolves nothing that thin.
inline constexpr float kVisibilityMinStepTexels = 0.2f;

/// A self-shadow ray toward a light through a flat shell (the renderer's straight visibility
/// ray): samples from `start` along `direction`, a step of the distance sampled (its magnitude,
/// at least kVisibilityMinStepTexels, and at least the path left to the tile's top over the
/// samples left after this one, so the budget takes the ray to the top) at a time, through the
/// detail too, keeping the least distance / (travel x tanHalfAngle) seen, until that is at most -1
/// (blocked), the budget is spent or the next point is at the tile's top. The state the ray keeps,
/// in this form so the kernel reads and writes it in place.
struct VisibilityLane {
    float start[3];
    float direction[3];  ///< unit, texel space, toward the light
    float depthTexels;   ///< z of the tile's top
    float tanHalfAngle;  ///< of the light's angular radius
    float visibility;    ///< the least distance / (travel x tanHalfAngle) so far
    float travel;        ///< of the point to sample next
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
