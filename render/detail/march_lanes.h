/// @file
/// The wide march kernel of render/march_wide.h over SIMD lanes (sampler/detail/simd_lanes.h):
/// written once, built with AVX2 (eight lanes, render/march_wide.cpp) and AVX-512 (sixteen,
/// render/march_wide16.cpp). Internal linkage, as simd_lanes.h.
#pragma once

#include "render/march_wide.h"
#include "sampler/detail/trilinear_lanes.h"

namespace distile::detail {
namespace {

/// A ray's line (start and direction, three floats each) into lane `slot` of `group` (any group
/// with startX ... directionZ arrays).
template <class Group>
[[gnu::always_inline]] inline void loadLine(Group& group, int slot, const float start[3],
                                            const float direction[3]) {
    group.startX[slot] = start[0];
    group.startY[slot] = start[1];
    group.startZ[slot] = start[2];
    group.directionX[slot] = direction[0];
    group.directionY[slot] = direction[1];
    group.directionZ[slot] = direction[2];
}

/// V::kWidth rays in flight, one per SIMD lane, in memory between rounds. Zeroed, so idle lanes
/// compute on plain numbers (no NaN or denormal garbage).
template <class V>
struct LaneGroup {
    static constexpr int kWidth = V::kWidth;
    alignas(64) float startX[kWidth]{}, startY[kWidth]{}, startZ[kWidth]{};
    alignas(64) float directionX[kWidth]{}, directionY[kWidth]{}, directionZ[kWidth]{};
    alignas(64) float toFloorAtStart[kWidth]{}, travel[kWidth]{}, safeRadius[kWidth]{},
        previousStep[kWidth]{};
    alignas(64) int iterations[kWidth]{}, maxIterations[kWidth]{};
    alignas(64) int refining[kWidth]{};  ///< -1: refining
    alignas(64) float outside[kWidth]{}, outsideDistance[kWidth]{}, inside[kWidth]{},
        insideDistance[kWidth]{}, estimate[kWidth]{};
    alignas(64) int idle[kWidth]{};        ///< -1: no ray in the lane
    alignas(64) float distance[kWidth]{};  ///< of the parked lanes
    alignas(64) int unknown[kWidth]{};  ///< -1: the distance was not sampled (outside the filter)
    int laneOf[kWidth]{};               ///< which of the call's lanes each SIMD lane holds
    int busy = 0;                       ///< lanes with a ray that goes on
    unsigned parked = 0;  ///< lanes whose ray has left, not yet handed back (bit per lane)
};

/// Lanes whose ray left wait, idle, until an eighth of the group has (or the group has no other
/// ray): then they are handed back and refilled together (two at a time of sixteen measured
/// faster than four or eight: idle lanes cost as much as busy ones).
template <class V>
constexpr int kParkedBeforeRefill = V::kWidth / 8;

/// The next of a call's rays into lane `slot` of `group` (source.load), or the lane idle when
/// none is left: for either lane group and its source (LaneSource, VisibilitySource).
template <class Source, class Group>
void takeNext(Source& source, Group& group, int slot) {
    if (source.next == source.count) {
        group.idle[slot] = -1;
        return;
    }
    source.load(group, slot, source.next++);
}

/// The call's rays, handed to the groups' lanes in order (takeNext).
struct LaneSource {
    SphereTraceLane* const* lanes;
    int count;
    int next = 0;

    /// Ray `index` of the call into lane `slot` of `group`, as the ray holds its state.
    template <class V>
    void load(LaneGroup<V>& group, int slot, int index) const {
        const SphereTraceLane& lane = *lanes[index];
        loadLine(group, slot, lane.start, lane.direction);
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
        group.laneOf[slot] = index;
        ++group.busy;
    }

    /// The state the steps of lane `slot` of `group` changed, back into its ray.
    template <class V>
    void store(const LaneGroup<V>& group, int slot) const {
        SphereTraceLane& lane = *lanes[group.laneOf[slot]];
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
    }
};

/// SphereTraceRay::falsePosition, lane by lane.
template <class V>
[[gnu::always_inline]] inline typename V::F falsePositionLanes(typename V::F outside,
                                                               typename V::F outsideDistance,
                                                               typename V::F inside,
                                                               typename V::F insideDistance) {
    return V::add(outside, V::div(V::mul(V::sub(inside, outside), outsideDistance),
                                  V::sub(outsideDistance, insideDistance)));
}

/// One sample of every busy lane of `group`: the steps that go on taken in the lanes; the lanes
/// whose step does not go on park with the distance sampled (LaneGroup::parked). No branches, so
/// the rounds of two groups overlap in the processor.
template <class V, bool kRelaxed>
[[gnu::always_inline]] inline void round(const WideColumns& columns,
                                         const SphereTraceUniforms& uniforms, LaneGroup<V>& group) {
    using F = typename V::F;
    using I = typename V::I;
    using M = typename V::M;
    const F epsilon = V::set1(uniforms.epsilonTexels);
    const M refining = V::loadMask(group.refining);
    const F t = V::load(group.travel);
    const F estimate = V::load(group.estimate);
    // SphereTraceRay::samplePosition: start + direction * (refining ? estimate : travel).
    const F along = V::blend(t, estimate, refining);
    const F x = V::add(V::load(group.startX), V::mul(V::load(group.directionX), along));
    const F y = V::add(V::load(group.startY), V::mul(V::load(group.directionY), along));
    const F z = V::add(V::load(group.startZ), V::mul(V::load(group.directionZ), along));
    const M idleLanes = V::loadMask(group.idle);
    M unknown = idleLanes;  // idle lanes read texel 0
    const F d = trilinearColumnsLanes<V>(columns, x, y, z, unknown);
    const I samples = V::loadInt(group.iterations);
    const I newIterations = V::add(samples, V::set1(1));
    const I budget = V::loadInt(group.maxIterations);
    const M budgetLeft = V::greater(budget, newIterations);

    // SphereTraceRay::traceStep.
    const F safe = V::load(group.safeRadius);
    const F previous = V::load(group.previousStep);
    const F toFloor = V::sub(V::load(group.toFloorAtStart), t);
    M sphereStep = V::both(V::greaterEqual(d, epsilon), V::less(d, toFloor));
    const F zero = V::set1(0.0f);
    // A step that went inside the detail: refine between the previous point and this one.
    M startsRefining = V::both(V::less(d, zero), V::greater(previous, safe));
    // A relaxed step (factor > 1) whose sphere does not reach back is undone. Unrelaxed (factor
    // 1): none, and the step is the distance (1 x d is d).
    F step = d;
    if constexpr (kRelaxed) {
        const F factor = V::set1(uniforms.factor);
        const M stepBack =
            V::both(V::both(V::greater(factor, V::set1(1.0f)), V::greater(previous, safe)),
                    V::less(V::add(d, safe), previous));
        sphereStep = V::butNot(stepBack, sphereStep);
        startsRefining = V::butNot(stepBack, startsRefining);
        step = V::mul(factor, d);
    }
    // Budgeted: std::max(step, the secant step), then std::max(step, toFloor / samples left).
    const M budgeted = V::uniformMask(uniforms.budgeted);
    const F secant = secantStepLanes<V>(d, safe, previous);
    step = V::blend(step, secant, V::both(budgeted, V::less(step, secant)));
    const F forced = V::div(toFloor, V::toFloat(V::sub(budget, newIterations)));
    step = V::blend(step, forced, V::both(budgeted, V::less(step, forced)));
    // std::min(step, toFloor)
    const F taken = V::blend(step, toFloor, V::less(toFloor, step));
    sphereStep = V::butNot(refining, V::both(sphereStep, budgetLeft));
    startsRefining = V::butNot(refining, V::both(startsRefining, budgetLeft));
    // beginRefining(travel - previousStep, safeRadius, travel, distance).
    const F startOutside = V::sub(t, previous);

    // SphereTraceRay::refineStep: on unless within epsilon (|d| >= epsilon, ordered).
    const M refineStep =
        V::both(refining, V::both(V::greaterEqual(V::abs(d), epsilon), budgetLeft));
    const M positive = V::greater(d, zero);
    const M movesOutside = V::both(refineStep, positive);
    const M movesInside = V::butNot(positive, refineStep);

    const M known = V::butNot(unknown, V::allLanes());
    sphereStep = V::both(sphereStep, known);
    startsRefining = V::both(startsRefining, known);
    const M refines = V::both(refineStep, known);
    const M goesOn = V::either(V::either(sphereStep, startsRefining), refines);

    V::store(group.travel, V::blend(t, V::add(t, taken), sphereStep));
    V::store(group.safeRadius, V::blend(safe, d, sphereStep));
    V::store(group.previousStep, V::blend(previous, taken, sphereStep));
    F outside = V::load(group.outside), outsideDistance = V::load(group.outsideDistance);
    F inside = V::load(group.inside), insideDistance = V::load(group.insideDistance);
    const M toOutside = V::both(movesOutside, known);
    const M toInside = V::both(movesInside, known);
    outside = V::blend(V::blend(outside, estimate, toOutside), startOutside, startsRefining);
    outsideDistance = V::blend(V::blend(outsideDistance, d, toOutside), safe, startsRefining);
    inside = V::blend(V::blend(inside, estimate, toInside), t, startsRefining);
    insideDistance = V::blend(V::blend(insideDistance, d, toInside), d, startsRefining);
    const M changed = V::either(startsRefining, refines);
    V::store(group.outside, outside);
    V::store(group.outsideDistance, outsideDistance);
    V::store(group.inside, inside);
    V::store(group.insideDistance, insideDistance);
    V::store(
        group.estimate,
        V::blend(estimate, falsePositionLanes<V>(outside, outsideDistance, inside, insideDistance),
                 changed));
    V::storeMask(group.refining, V::either(refining, startsRefining));
    V::storeInt(group.iterations, V::blend(samples, newIterations, goesOn));
    // Busy lanes whose step does not go on leave with the distance sampled: they park (idle,
    // their state as before the step) until enough have, then are handed back and refilled.
    const M leaving = V::butNot(V::either(goesOn, idleLanes), V::allLanes());
    V::store(group.distance, V::blend(V::load(group.distance), d, leaving));
    V::storeMask(group.unknown, V::blendMasks(V::loadMask(group.unknown), unknown, leaving));
    V::storeMask(group.idle, V::either(idleLanes, leaving));
    const unsigned left = V::bits(leaving);
    group.parked |= left;
    group.busy -= __builtin_popcount(left);
}

/// The parked lanes of `group` handed back to their rays (state before the step, distance
/// sampled) and refilled, once enough have parked or the group has no other ray (or `now`).
template <class V>
inline void handBack(LaneGroup<V>& group, LaneSource& source, bool now = false) {
    if (!now && __builtin_popcount(group.parked) < kParkedBeforeRefill<V> && group.busy > 0) return;
    for (unsigned parked = group.parked; parked != 0; parked &= parked - 1) {
        const int slot = __builtin_ctz(parked);
        source.store(group, slot);
        SphereTraceLane& lane = *source.lanes[group.laneOf[slot]];
        lane.pendingDistance = group.distance[slot];
        lane.distanceKnown = group.unknown[slot] == 0;
        takeNext(source, group, slot);
    }
    group.parked = 0;
}

/// The busy lanes of `from` moved into idle lanes of `to` (which must have enough), through
/// their rays; `from`'s parked lanes already handed back.
template <class V>
void moveBusyLanes(LaneGroup<V>& from, LaneGroup<V>& to, const LaneSource& source) {
    int slot = 0;
    for (int fromSlot = 0; fromSlot < V::kWidth; ++fromSlot) {
        if (from.idle[fromSlot] != 0) continue;
        while (to.idle[slot] == 0) ++slot;
        source.store(from, fromSlot);
        source.load(to, slot, from.laneOf[fromSlot]);
        from.idle[fromSlot] = -1;
        --from.busy;
    }
}

template <class V, bool kRelaxed>
void sphereTraceOngoingStepsOf(const WideColumns& columns, const SphereTraceUniforms& uniforms,
                               SphereTraceLane* const* lanes, int count) {
    // Two groups of lanes, sampled in turn: while one group's gathers wait on memory, the
    // other's arithmetic runs (a round depends on the one before it in the same group only).
    LaneSource source{lanes, count};
    LaneGroup<V> groups[2];
    for (LaneGroup<V>& group : groups)
        for (int slot = 0; slot < V::kWidth; ++slot) takeNext(source, group, slot);
    while (source.next < source.count || groups[0].busy + groups[1].busy > V::kWidth) {
        round<V, kRelaxed>(columns, uniforms, groups[0]);  // without rays: idle lanes only
        round<V, kRelaxed>(columns, uniforms, groups[1]);
        handBack(groups[0], source);
        handBack(groups[1], source);
    }
    // The last rays, once they fit, in one group: two mostly idle groups would cost two rounds
    // for the samples of one (a call's last rounds hold most of its idle lanes).
    handBack(groups[0], source, true);
    handBack(groups[1], source, true);
    moveBusyLanes(groups[1], groups[0], source);
    while (groups[0].busy > 0) {
        round<V, kRelaxed>(columns, uniforms, groups[0]);
        handBack(groups[0], source);
    }
    handBack(groups[0], source);
    V::leave();
}

/// sphereTraceOngoingSteps (render/march_wide.h) in lanes V.
template <class V>
void sphereTraceOngoingStepsInLanes(const WideColumns& columns, const SphereTraceUniforms& uniforms,
                                    SphereTraceLane* const* lanes, int count) {
    if (uniforms.factor > 1.0f)
        sphereTraceOngoingStepsOf<V, true>(columns, uniforms, lanes, count);
    else
        sphereTraceOngoingStepsOf<V, false>(columns, uniforms, lanes, count);
}

/// V::kWidth visibility rays (VisibilityLane) in flight, one per SIMD lane.
template <class V>
struct VisibilityGroup {
    static constexpr int kWidth = V::kWidth;
    alignas(64) float startX[kWidth]{}, startY[kWidth]{}, startZ[kWidth]{};
    alignas(64) float directionX[kWidth]{}, directionY[kWidth]{}, directionZ[kWidth]{};
    alignas(64) float depthTexels[kWidth]{}, tanHalfAngle[kWidth]{};
    alignas(64) float visibility[kWidth]{}, travel[kWidth]{};
    alignas(64) int samplesLeft[kWidth]{}, samples[kWidth]{};
    alignas(64) int idle[kWidth]{};  ///< -1: no ray in the lane
    int laneOf[kWidth]{};            ///< which of the call's lanes each SIMD lane holds
    int busy = 0;
};

/// The call's visibility rays, handed to the groups' lanes in order (takeNext) and back when
/// they end.
struct VisibilitySource {
    VisibilityLane* const* lanes;
    int count;
    int next = 0;

    /// Ray `index` of the call into lane `slot` of `group`.
    template <class V>
    void load(VisibilityGroup<V>& group, int slot, int index) const {
        const VisibilityLane& lane = *lanes[index];
        loadLine(group, slot, lane.start, lane.direction);
        group.depthTexels[slot] = lane.depthTexels;
        group.tanHalfAngle[slot] = lane.tanHalfAngle;
        group.visibility[slot] = lane.visibility;
        group.travel[slot] = lane.travel;
        group.samplesLeft[slot] = lane.samplesLeft;
        group.samples[slot] = lane.samples;
        group.idle[slot] = 0;
        group.laneOf[slot] = index;
        ++group.busy;
    }

    /// Lane `slot` of `group` back into its ray, which goes on (needsSample) only where its
    /// sample was left to it.
    template <class V>
    void giveBack(VisibilityGroup<V>& group, int slot, bool blocked, bool sampleLeft) const {
        VisibilityLane& lane = *lanes[group.laneOf[slot]];
        lane.visibility = group.visibility[slot];
        lane.travel = group.travel[slot];
        lane.samplesLeft = group.samplesLeft[slot];
        lane.samples = group.samples[slot];
        lane.blocked = blocked;
        lane.needsSample = sampleLeft;
        --group.busy;
    }
};

/// One sample of every busy lane of `group`, as the renderer's LightVisibilityRay::advance takes
/// it; the lanes whose march ends (or whose point the wide filter does not take) are given back
/// and refilled.
template <class V>
[[gnu::always_inline]] inline void visibilityRound(const WideColumns& columns,
                                                   VisibilityGroup<V>& group,
                                                   VisibilitySource& source) {
    using F = typename V::F;
    using I = typename V::I;
    using M = typename V::M;
    // samplePosition: start + direction x travel.
    const F t = V::load(group.travel);
    const F startZ = V::load(group.startZ), directionZ = V::load(group.directionZ);
    const F x = V::add(V::load(group.startX), V::mul(V::load(group.directionX), t));
    const F y = V::add(V::load(group.startY), V::mul(V::load(group.directionY), t));
    const F z = V::add(startZ, V::mul(directionZ, t));
    const M idleLanes = V::loadMask(group.idle);
    M unknown = idleLanes;  // idle lanes read texel 0
    const F d = trilinearColumnsLanes<V>(columns, x, y, z, unknown);
    const M known = V::butNot(unknown, V::allLanes());
    // visibility = min(visibility, d / (travel x tanHalfAngle)), blocked unless above -1;
    // travel += max(|d|, kVisibilityMinStepTexels, the path left to the top over the samples
    // left after this one, where any are left).
    const F visibility = V::load(group.visibility);
    const F ratio = V::div(d, V::mul(t, V::load(group.tanHalfAngle)));
    const F least = V::blend(visibility, ratio, V::less(ratio, visibility));
    const M blocks = V::butNot(V::greater(least, V::set1(-1.0f)), known);
    const M advances = V::butNot(blocks, known);
    const F minStep = V::set1(kVisibilityMinStepTexels);
    const F away = V::abs(d);
    const F step = V::blend(away, minStep, V::less(away, minStep));
    const I samplesLeft = V::loadInt(group.samplesLeft);
    const I left = V::sub(samplesLeft, V::set1(1));
    const F forced =
        V::div(V::div(V::sub(V::load(group.depthTexels), z), directionZ), V::toFloat(left));
    const M forces =
        V::both(V::both(V::greater(left, V::set1(0)), V::greater(directionZ, V::set1(0.0f))),
                V::less(step, forced));
    const F travel = V::add(t, V::blend(step, forced, forces));
    // On while samples are left and the next point is below the top (NaN: on, as the scalar).
    const M below = V::butNot(
        V::greaterEqual(V::add(startZ, V::mul(directionZ, travel)), V::load(group.depthTexels)),
        V::greater(left, V::set1(0)));
    V::store(group.travel, V::blend(t, travel, advances));
    V::store(group.visibility, V::blend(visibility, least, known));
    V::storeInt(group.samplesLeft, V::blend(samplesLeft, left, advances));
    const I samples = V::loadInt(group.samples);
    V::storeInt(group.samples, V::blend(samples, V::add(samples, V::set1(1)), known));
    const M goesOn = V::both(advances, below);
    const unsigned leaving = V::bits(V::butNot(V::either(goesOn, idleLanes), V::allLanes()));
    if (leaving == 0) return;
    const unsigned blocked = V::bits(blocks);
    const unsigned sampleLeftToRay = V::bits(V::butNot(idleLanes, unknown));
    for (unsigned rest = leaving; rest != 0; rest &= rest - 1) {
        const int slot = __builtin_ctz(rest);
        source.giveBack(group, slot, (blocked >> slot) & 1u, (sampleLeftToRay >> slot) & 1u);
        takeNext(source, group, slot);
    }
}

/// visibilitySteps (render/march_wide.h) in lanes V: two groups sampled in turn, so that one's
/// gathers wait on memory while the other's arithmetic runs.
template <class V>
void visibilityStepsInLanes(const WideColumns& columns, VisibilityLane* const* lanes, int count) {
    VisibilitySource source{lanes, count};
    VisibilityGroup<V> groups[2];
    for (VisibilityGroup<V>& group : groups)
        for (int slot = 0; slot < V::kWidth; ++slot) takeNext(source, group, slot);
    while (groups[0].busy + groups[1].busy > 0) {
        if (groups[0].busy > 0) visibilityRound<V>(columns, groups[0], source);
        if (groups[1].busy > 0) visibilityRound<V>(columns, groups[1], source);
    }
    V::leave();
}

}  // namespace
}  // namespace distile::detail
