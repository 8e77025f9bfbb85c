// The AVX2 kernel of render/march_wide.h. Compiled with -mavx2 and without FMA (see
// sampler/trilinear_wide.cpp: nothing here is shared with the SSE2 build of distile).
#include "render/march_wide.h"

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)
#include "sampler/trilinear_avx2.h"
#endif

namespace distile::detail {

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)

namespace {

constexpr int kWidth = 8;

/// Eight rays in flight, one per SIMD lane, in memory between rounds. Zeroed, so idle lanes
/// compute on plain numbers (no NaN or denormal garbage).
struct LaneGroup {
    alignas(32) float startX[kWidth]{}, startY[kWidth]{}, startZ[kWidth]{};
    alignas(32) float directionX[kWidth]{}, directionY[kWidth]{}, directionZ[kWidth]{};
    alignas(32) float toFloorAtStart[kWidth]{}, travel[kWidth]{}, safeRadius[kWidth]{},
        previousStep[kWidth]{};
    alignas(32) int iterations[kWidth]{}, maxIterations[kWidth]{};
    alignas(32) int refining[kWidth]{};  ///< -1: refining
    alignas(32) float outside[kWidth]{}, outsideDistance[kWidth]{}, inside[kWidth]{},
        insideDistance[kWidth]{}, estimate[kWidth]{};
    alignas(32) int idle[kWidth]{};        ///< -1: no ray in the lane
    alignas(32) float distance[kWidth]{};  ///< of the parked lanes
    alignas(32) int unknown[kWidth]{};  ///< -1: the distance was not sampled (outside the filter)
    int laneOf[kWidth]{};               ///< which of the call's lanes each SIMD lane holds
    int busy = 0;                       ///< lanes with a ray that goes on
    unsigned parked = 0;  ///< lanes whose ray has left, not yet handed back (bit per lane)
};

/// Lanes whose ray left wait, idle, until this many have (or the group has no other ray): then
/// they are handed back and refilled together, so the branches of that work are rare.
constexpr int kParkedBeforeRefill = 4;

/// The call's rays, handed to the groups' lanes in order.
struct LaneSource {
    SphereTraceLane* const* lanes;
    int count;
    int next = 0;

    /// The next ray into lane `slot` of `group`, or the lane idle when none is left.
    void take(LaneGroup& group, int slot) {
        if (next == count) {
            group.idle[slot] = -1;
            return;
        }
        const SphereTraceLane& lane = *lanes[next];
        group.startX[slot] = lane.start[0];
        group.startY[slot] = lane.start[1];
        group.startZ[slot] = lane.start[2];
        group.directionX[slot] = lane.direction[0];
        group.directionY[slot] = lane.direction[1];
        group.directionZ[slot] = lane.direction[2];
        group.toFloorAtStart[slot] = lane.toFloorAtStart;
        group.travel[slot] = lane.travel;
        group.safeRadius[slot] = lane.safeRadius;
        group.previousStep[slot] = lane.previousStep;
        group.iterations[slot] = lane.iterations;
        group.maxIterations[slot] = lane.maxIterations;
        group.refining[slot] = lane.refining ? -1 : 0;
        group.outside[slot] = lane.outside;
        group.outsideDistance[slot] = lane.outsideDistance;
        group.inside[slot] = lane.inside;
        group.insideDistance[slot] = lane.insideDistance;
        group.estimate[slot] = lane.estimate;
        group.idle[slot] = 0;
        group.laneOf[slot] = next++;
        ++group.busy;
    }
};

/// SphereTraceRay::falsePosition, lane by lane.
[[gnu::always_inline]] inline __m256 falsePosition(__m256 outside, __m256 outsideDistance,
                                                   __m256 inside, __m256 insideDistance) {
    return _mm256_add_ps(
        outside, _mm256_div_ps(_mm256_mul_ps(_mm256_sub_ps(inside, outside), outsideDistance),
                               _mm256_sub_ps(outsideDistance, insideDistance)));
}

/// One sample of every busy lane of `group`: the steps that go on taken in the lanes; the lanes
/// whose step does not go on park with the distance sampled (LaneGroup::parked). No branches, so
/// the rounds of two groups overlap in the processor.
template <bool kRelaxed>
[[gnu::always_inline]] inline void round(const WideColumns& columns,
                                         const SphereTraceUniforms& uniforms, LaneGroup& group) {
    const __m256 epsilon = _mm256_set1_ps(uniforms.epsilonTexels);
    const __m256i oneStep = _mm256_set1_epi32(1);
    const auto asFloat = [](__m256i mask) { return _mm256_castsi256_ps(mask); };
    const auto load = [](const float* values) { return _mm256_load_ps(values); };
    const __m256 refining =
        asFloat(_mm256_load_si256(reinterpret_cast<const __m256i*>(group.refining)));
    const __m256 t = load(group.travel);
    const __m256 estimate = load(group.estimate);
    // SphereTraceRay::samplePosition: start + direction * (refining ? estimate : travel).
    const __m256 along = _mm256_blendv_ps(t, estimate, refining);
    const __m256 x =
        _mm256_add_ps(load(group.startX), _mm256_mul_ps(load(group.directionX), along));
    const __m256 y =
        _mm256_add_ps(load(group.startY), _mm256_mul_ps(load(group.directionY), along));
    const __m256 z =
        _mm256_add_ps(load(group.startZ), _mm256_mul_ps(load(group.directionZ), along));
    const __m256i idleLanes = _mm256_load_si256(reinterpret_cast<const __m256i*>(group.idle));
    __m256i unknown = idleLanes;  // idle lanes read texel 0
    const __m256 d = trilinearColumnsAvx2(columns, x, y, z, unknown);
    const __m256i samples = _mm256_load_si256(reinterpret_cast<const __m256i*>(group.iterations));
    const __m256i newIterations = _mm256_add_epi32(samples, oneStep);
    const __m256i budget = _mm256_load_si256(reinterpret_cast<const __m256i*>(group.maxIterations));
    const __m256 budgetLeft = asFloat(_mm256_cmpgt_epi32(budget, newIterations));

    // SphereTraceRay::traceStep.
    const __m256 safe = load(group.safeRadius);
    const __m256 previous = load(group.previousStep);
    const __m256 toFloor = _mm256_sub_ps(load(group.toFloorAtStart), t);
    __m256 sphereStep =
        _mm256_and_ps(_mm256_cmp_ps(d, epsilon, _CMP_GE_OQ), _mm256_cmp_ps(d, toFloor, _CMP_LT_OQ));
    const __m256 zero = _mm256_setzero_ps();
    // A step that went inside the detail: refine between the previous point and this one.
    __m256 startsRefining = _mm256_and_ps(_mm256_cmp_ps(d, zero, _CMP_LT_OQ),
                                          _mm256_cmp_ps(previous, safe, _CMP_GT_OQ));
    // A relaxed step (factor > 1) whose sphere does not reach back is undone. Unrelaxed (factor
    // 1): none, and the step is the distance (1 x d is d).
    __m256 step = d;
    if constexpr (kRelaxed) {
        const __m256 factor = _mm256_set1_ps(uniforms.factor);
        const __m256 stepBack =
            _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(factor, _mm256_set1_ps(1.0f), _CMP_GT_OQ),
                                        _mm256_cmp_ps(previous, safe, _CMP_GT_OQ)),
                          _mm256_cmp_ps(_mm256_add_ps(d, safe), previous, _CMP_LT_OQ));
        sphereStep = _mm256_andnot_ps(stepBack, sphereStep);
        startsRefining = _mm256_andnot_ps(stepBack, startsRefining);
        step = _mm256_mul_ps(factor, d);
    }
    // Budgeted: std::max(step, toFloor / samples left).
    const __m256 forced =
        _mm256_div_ps(toFloor, _mm256_cvtepi32_ps(_mm256_sub_epi32(budget, newIterations)));
    const __m256 budgeted = asFloat(_mm256_set1_epi32(uniforms.budgeted ? -1 : 0));
    step = _mm256_blendv_ps(step, forced,
                            _mm256_and_ps(budgeted, _mm256_cmp_ps(step, forced, _CMP_LT_OQ)));
    // std::min(step, toFloor)
    const __m256 taken = _mm256_blendv_ps(step, toFloor, _mm256_cmp_ps(toFloor, step, _CMP_LT_OQ));
    sphereStep = _mm256_andnot_ps(refining, _mm256_and_ps(sphereStep, budgetLeft));
    startsRefining = _mm256_andnot_ps(refining, _mm256_and_ps(startsRefining, budgetLeft));
    // beginRefining(travel - previousStep, safeRadius, travel, distance).
    const __m256 startOutside = _mm256_sub_ps(t, previous);

    // SphereTraceRay::refineStep: on unless within epsilon (|d| >= epsilon, ordered).
    const __m256 magnitude = _mm256_and_ps(d, asFloat(_mm256_set1_epi32(0x7fffffff)));
    const __m256 refineStep = _mm256_and_ps(
        refining, _mm256_and_ps(_mm256_cmp_ps(magnitude, epsilon, _CMP_GE_OQ), budgetLeft));
    const __m256 positive = _mm256_cmp_ps(d, zero, _CMP_GT_OQ);
    const __m256 movesOutside = _mm256_and_ps(refineStep, positive);
    const __m256 movesInside = _mm256_andnot_ps(positive, refineStep);

    const __m256 known =
        _mm256_andnot_ps(asFloat(unknown), asFloat(_mm256_cmpeq_epi32(samples, samples)));
    sphereStep = _mm256_and_ps(sphereStep, known);
    startsRefining = _mm256_and_ps(startsRefining, known);
    const __m256 refines = _mm256_and_ps(refineStep, known);
    const __m256 goesOn = _mm256_or_ps(_mm256_or_ps(sphereStep, startsRefining), refines);

    _mm256_store_ps(group.travel, _mm256_blendv_ps(t, _mm256_add_ps(t, taken), sphereStep));
    _mm256_store_ps(group.safeRadius, _mm256_blendv_ps(safe, d, sphereStep));
    _mm256_store_ps(group.previousStep, _mm256_blendv_ps(previous, taken, sphereStep));
    __m256 outside = load(group.outside), outsideDistance = load(group.outsideDistance);
    __m256 inside = load(group.inside), insideDistance = load(group.insideDistance);
    const __m256 toOutside = _mm256_and_ps(movesOutside, known);
    const __m256 toInside = _mm256_and_ps(movesInside, known);
    outside = _mm256_blendv_ps(_mm256_blendv_ps(outside, estimate, toOutside), startOutside,
                               startsRefining);
    outsideDistance =
        _mm256_blendv_ps(_mm256_blendv_ps(outsideDistance, d, toOutside), safe, startsRefining);
    inside = _mm256_blendv_ps(_mm256_blendv_ps(inside, estimate, toInside), t, startsRefining);
    insideDistance =
        _mm256_blendv_ps(_mm256_blendv_ps(insideDistance, d, toInside), d, startsRefining);
    const __m256 changed = _mm256_or_ps(startsRefining, refines);
    _mm256_store_ps(group.outside, outside);
    _mm256_store_ps(group.outsideDistance, outsideDistance);
    _mm256_store_ps(group.inside, inside);
    _mm256_store_ps(group.insideDistance, insideDistance);
    _mm256_store_ps(
        group.estimate,
        _mm256_blendv_ps(estimate, falsePosition(outside, outsideDistance, inside, insideDistance),
                         changed));
    _mm256_store_si256(reinterpret_cast<__m256i*>(group.refining),
                       _mm256_castps_si256(_mm256_or_ps(refining, startsRefining)));
    _mm256_store_si256(
        reinterpret_cast<__m256i*>(group.iterations),
        _mm256_castps_si256(_mm256_blendv_ps(asFloat(samples), asFloat(newIterations), goesOn)));
    // Busy lanes whose step does not go on leave with the distance sampled: they park (idle,
    // their state as before the step) until enough have, then are handed back and refilled.
    const __m256 leaving = _mm256_andnot_ps(_mm256_or_ps(goesOn, asFloat(idleLanes)),
                                            asFloat(_mm256_cmpeq_epi32(samples, samples)));
    _mm256_store_ps(group.distance, _mm256_blendv_ps(load(group.distance), d, leaving));
    _mm256_store_si256(
        reinterpret_cast<__m256i*>(group.unknown),
        _mm256_castps_si256(_mm256_blendv_ps(
            asFloat(_mm256_load_si256(reinterpret_cast<const __m256i*>(group.unknown))),
            asFloat(unknown), leaving)));
    _mm256_store_si256(reinterpret_cast<__m256i*>(group.idle),
                       _mm256_castps_si256(_mm256_or_ps(asFloat(idleLanes), leaving)));
    const unsigned left = unsigned(_mm256_movemask_ps(leaving));
    group.parked |= left;
    group.busy -= __builtin_popcount(left);
}

/// The parked lanes of `group` handed back to their rays (state before the step, distance
/// sampled) and refilled, once enough have parked or the group has no other ray.
inline void handBack(LaneGroup& group, LaneSource& source) {
    if (__builtin_popcount(group.parked) < kParkedBeforeRefill && group.busy > 0) return;
    for (unsigned parked = group.parked; parked != 0; parked &= parked - 1) {
        const int slot = __builtin_ctz(parked);
        SphereTraceLane& lane = *source.lanes[group.laneOf[slot]];
        lane.travel = group.travel[slot];
        lane.safeRadius = group.safeRadius[slot];
        lane.previousStep = group.previousStep[slot];
        lane.iterations = group.iterations[slot];
        lane.refining = group.refining[slot] != 0;
        lane.outside = group.outside[slot];
        lane.outsideDistance = group.outsideDistance[slot];
        lane.inside = group.inside[slot];
        lane.insideDistance = group.insideDistance[slot];
        lane.estimate = group.estimate[slot];
        lane.pendingDistance = group.distance[slot];
        lane.distanceKnown = group.unknown[slot] == 0;
        source.take(group, slot);
    }
    group.parked = 0;
}

}  // namespace

namespace {

template <bool kRelaxed>
void sphereTraceOngoingStepsOf(const WideColumns& columns, const SphereTraceUniforms& uniforms,
                               SphereTraceLane* const* lanes, int count) {
    // Two groups of eight lanes, sampled in turn: while one group's gathers wait on memory, the
    // other's arithmetic runs (a round depends on the one before it in the same group only).
    LaneSource source{lanes, count};
    LaneGroup groups[2];
    for (LaneGroup& group : groups)
        for (int slot = 0; slot < kWidth; ++slot) source.take(group, slot);
    while (groups[0].busy + groups[1].busy > 0) {
        round<kRelaxed>(columns, uniforms, groups[0]);  // without rays: idle lanes only
        round<kRelaxed>(columns, uniforms, groups[1]);
        handBack(groups[0], source);
        handBack(groups[1], source);
    }
    handBack(groups[0], source);
    handBack(groups[1], source);
    // Back to SSE code: with the upper halves of the ymm registers dirty, every SSE instruction
    // after this would pay for merging them (the compiler does not always clear them itself).
    _mm256_zeroupper();
}

}  // namespace

void sphereTraceOngoingSteps(const WideColumns& columns, const SphereTraceUniforms& uniforms,
                             SphereTraceLane* const* lanes, int count) {
    if (uniforms.factor > 1.0f)
        sphereTraceOngoingStepsOf<true>(columns, uniforms, lanes, count);
    else
        sphereTraceOngoingStepsOf<false>(columns, uniforms, lanes, count);
}

#else

void sphereTraceOngoingSteps(const WideColumns&, const SphereTraceUniforms&,
                             SphereTraceLane* const* lanes, int count) {
    for (int i = 0; i < count; ++i) lanes[i]->distanceKnown = false;  // never called: no AVX2
}

#endif

}  // namespace distile::detail
