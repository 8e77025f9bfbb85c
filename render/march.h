/// @file
/// The march of distance mapping (GPU Gems 2, ch. 8) in a tile's texel space, from the entry point
/// on the top (z = D) along a direction normalised in texel space, in four methods:
/// - SphereTracing (ch. 8): step by the sampled distance; every step is safe for a distance that
///   does not overestimate.
/// - OverRelaxed (Keinert et al. 2014, "Enhanced sphere tracing"): step by relaxation x distance
///   while the unbounding spheres of consecutive points overlap, so the segment between them is
///   known to be empty; when they do not, step back to the last safe point and continue as plain
///   sphere tracing. Same hits as SphereTracing, in fewer steps along grazing rays.
/// - Budgeted (the default): sphere tracing whose steps are at least the path left to the floor
///   over the samples left, so every ray reaches the surface or the floor within the budget
///   (plain sphere tracing creeps along grazing rays and stops short), and where the distance
///   fell over the last step, at least the secant step toward where the last two samples' line
///   reaches zero (detail::secantStepLanes, at most kSecantReachTexels beyond the distance); a
///   step that lands inside the detail is refined by regula falsi with the samples left. A step
///   of the sampled distance is as safe as sphere tracing; a longer one (the minimum, or the
///   secant step) can cross a feature thinner than the step along the ray.
/// - Relief (relief mapping, Policarpo et al. 2005): fixed linear steps through the slab until the
///   first point inside the detail, then a binary search between it and the previous point. Can
///   step over features thinner than a step.
/// - FixedSteps: fixed linear steps through the slab until the first point inside, then the zero
///   crossing of the distance interpolated linearly between the last two points.
/// Every method counts one iteration per distance sample.
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/vec3.hpp>
#include <limits>
#include <optional>
#include <span>
#include <type_traits>

#include "common/simd.h"
#include "render/march_wide.h"
#include "render/scene.h"
#include "sampler/filters.h"

namespace distile {

enum class MarchMethod { SphereTracing, OverRelaxed, Budgeted, Relief, FixedSteps };
inline constexpr MarchMethod kMarchMethods[] = {MarchMethod::SphereTracing,
                                                MarchMethod::OverRelaxed, MarchMethod::Budgeted,
                                                MarchMethod::Relief, MarchMethod::FixedSteps};

/// "sphere", "relaxed", "budgeted", "relief", "fixed": the names of the command line and the
/// benchmark.
inline const char* marchMethodName(MarchMethod method) {
    switch (method) {
        case MarchMethod::SphereTracing:
            return "sphere";
        case MarchMethod::OverRelaxed:
            return "relaxed";
        case MarchMethod::Budgeted:
            return "budgeted";
        case MarchMethod::Relief:
            return "relief";
        case MarchMethod::FixedSteps:
            return "fixed";
    }
    return "?";
}

struct MarchSettings {
    MarchMethod method = MarchMethod::Budgeted;
    /// Distance samples per ray at most; what grazing rays need. Before the secant step, 32 took
    /// 16% more samples than 16 on the chain-mail sheet and cut its mean hit error from 0.232 to
    /// 0.084 texel, the silhouettes' from 0.59 to 0.20 (the forced steps of 16, 3 texels and more
    /// far away, passed wire edges).
    int maxIterations = 32;
    float epsilonTexels = 0.02f;  ///< a point closer than this to the surface is a hit
    /// OverRelaxed: step factor while the spheres overlap, in [1, 2) (1 is plain sphere tracing).
    float relaxation = 1.6f;
    /// Relief: share of the budget spent on the linear search, the rest on the binary search.
    float reliefLinearShare = 0.75f;
};

namespace detail {

/// One ray as a lane of detail::secantStepLanes, in single (float) or double precision.
template <class Real>
struct OneLaneOf {
    using F = Real;
    using M = bool;
    static F set1(float value) { return value; }
    static F add(F a, F b) { return a + b; }
    static F sub(F a, F b) { return a - b; }
    static F mul(F a, F b) { return a * b; }
    static F div(F a, F b) { return a / b; }
    static M less(F a, F b) { return a < b; }
    static M greater(F a, F b) { return a > b; }
    static M both(M a, M b) { return a && b; }
    static F onlyWhere(M m, F v) { return m ? v : F(0); }
    static F blend(F a, F b, M m) { return m ? b : a; }
};
using OneLane = OneLaneOf<float>;

}  // namespace detail

/// Where a march ended. Positions in texel space, lengths in texels.
struct MarchResult {
    glm::vec3 texelPosition;
    float travelTexels = 0.0f;
    int iterations = 0;
    bool converged = false;  ///< within epsilon of the detail, or on the solid floor
    bool onFloor = false;
    bool exitedFloor = false;  ///< open floor: the ray left the shell through the bottom
};

namespace detail {

/// Ends a march at the floor z = 0, `toFloor` texels along the ray from `position`.
inline void endOnFloor(MarchResult& result, const glm::vec3& position, const glm::vec3& direction,
                       float travelTexels, float toFloor, Floor floor) {
    result.texelPosition = position + direction * toFloor;
    result.texelPosition.z = 0.0f;
    result.travelTexels = travelTexels + toFloor;
    if (floor == Floor::Solid) {
        result.converged = result.onFloor = true;
    } else {
        result.exitedFloor = true;
    }
}

/// Where a ray leaves its shell through an open border of the base mesh `leaveTravelTexels` along
/// it, before the floor `toFloor` texels along it: the march ends there as at an open floor (no
/// hit), so that border takes the floor's place.
template <class Real>
void leaveBeforeFloor(Real& toFloor, Floor& floor, Real leaveTravelTexels) {
    if (!(leaveTravelTexels < toFloor)) return;
    toFloor = std::max(leaveTravelTexels, Real(0));
    floor = Floor::Open;
}

/// One ray's sphere trace (SphereTracing, OverRelaxed, Budgeted; file note), taken a distance
/// sample at a time, so that marchInterleaved() can alternate between rays whose sample chains are
/// independent. The operations per ray are exactly those of one march, in the same order:
/// interleaved and single marches give bit-identical results. The floor z = 0 is hit exactly when
/// a safe sphere reaches it: the sphere is empty of detail, so the floor crossing inside it is the
/// first surface along the ray.
class SphereTraceRay {
  public:
    /// (Re)starts the march of march() for `settings` (method SphereTracing, OverRelaxed or
    /// Budgeted) from `start` along `direction`, in place. Preconditions as march(), and
    /// settings.maxIterations >= 1.
    void start(const glm::vec3& start, const glm::vec3& direction, Floor floor,
               const MarchSettings& settings,
               float leaveTravelTexels = std::numeric_limits<float>::infinity()) {
        for (int axis = 0; axis < 3; ++axis) {
            lane_.start[axis] = start[axis];
            lane_.direction[axis] = direction[axis];
        }
        floor_ = floor;
        lane_.maxIterations = settings.maxIterations;
        epsilonTexels_ = settings.epsilonTexels;
        factor_ = settings.method == MarchMethod::OverRelaxed ? settings.relaxation : 1.0f;
        budgeted_ = settings.method == MarchMethod::Budgeted;
        lane_.refining = false;
        lane_.toFloorAtStart = start.z / -direction.z;
        leaveBeforeFloor(lane_.toFloorAtStart, floor_, leaveTravelTexels);
        lane_.travel = lane_.safeRadius = lane_.previousStep = 0.0f;
        lane_.iterations = 0;
        result_.iterations = 0;
        result_.travelTexels = 0.0f;
        result_.converged = result_.onFloor = result_.exitedFloor = false;
    }

    /// Takes the next distance sample from `filter`, the same filter on every call; false once
    /// the march has ended (then result() is final).
    template <class Filter>
    bool step(const Filter& filter) {
        return advance(filter.distanceTexels(samplePosition()));
    }

    /// step() in two halves, so the samples of several rays can be taken together: where the
    /// next sample is, then the march's move given the distance sampled there.
    glm::vec3 samplePosition() const {
        return origin() + direction() * (lane_.refining ? lane_.estimate : lane_.travel);
    }
    [[gnu::always_inline]] bool advance(float distance) {
        const bool goesOn = lane_.refining ? refineStep(distance) : traceStep(distance);
        if (!goesOn) result_.iterations = lane_.iterations;
        return goesOn;
    }

    /// Final once step() or advance() returned false.
    const MarchResult& result() const { return result_; }

    /// Whether the wide kernel can take this ray's next steps (render/march_wide.h): it shares
    /// `uniforms` (a relaxed march that took a step back goes on unrelaxed).
    bool fitsLanes(const SphereTraceUniforms& uniforms) const {
        return uniforms.epsilonTexels == epsilonTexels_ && uniforms.factor == factor_ &&
               uniforms.budgeted == budgeted_;
    }
    SphereTraceUniforms uniforms() const { return {epsilonTexels_, factor_, budgeted_}; }
    /// The state the wide kernel steps (fitsLanes), in place.
    SphereTraceLane& lane() { return lane_; }

  private:
    [[gnu::always_inline]] bool traceStep(float distance) {
        ++lane_.iterations;
        const glm::vec3 position = origin() + direction() * lane_.travel;
        if (factor_ > 1.0f && lane_.previousStep > lane_.safeRadius &&
            distance + lane_.safeRadius < lane_.previousStep) {
            // The relaxed step left the previous sphere and this one does not reach back to it:
            // the gap between them is unverified. Back to the edge of the previous sphere, as
            // plain sphere tracing from here on.
            lane_.travel -= lane_.previousStep - lane_.safeRadius;
            lane_.previousStep = lane_.safeRadius;
            factor_ = 1.0f;
            return budgetLeft();
        }
        if (distance < epsilonTexels_) {
            if (distance < 0.0f && lane_.previousStep > lane_.safeRadius) {
                // A budgeted step went past the surface: find the crossing in between.
                return beginRefining(lane_.travel - lane_.previousStep, lane_.safeRadius,
                                     lane_.travel, distance);
            }
            result_.converged = true;
            result_.texelPosition = position;
            result_.travelTexels = lane_.travel;
            return false;
        }
        const float toFloor = lane_.toFloorAtStart - lane_.travel;
        if (distance >= toFloor) {
            endOnFloor(result_, position, direction(), lane_.travel, toFloor, floor_);
            return false;
        }
        float step = factor_ * distance;
        if (budgeted_) {
            step = std::max(
                step, secantStepLanes<OneLane>(distance, lane_.safeRadius, lane_.previousStep));
            if (lane_.iterations < lane_.maxIterations)
                step = std::max(step, toFloor / float(lane_.maxIterations - lane_.iterations));
        }
        lane_.safeRadius = distance;
        lane_.previousStep = std::min(step, toFloor);
        lane_.travel += lane_.previousStep;
        return budgetLeft();
    }

    /// After a sample that did not end the march: false, with the last safe point as the result,
    /// when the budget has run out (a longer step beyond that point is unverified).
    bool budgetLeft() {
        if (lane_.iterations < lane_.maxIterations) return true;
        if (lane_.previousStep > lane_.safeRadius)
            lane_.travel -= lane_.previousStep - lane_.safeRadius;
        result_.texelPosition = origin() + direction() * lane_.travel;
        result_.travelTexels = lane_.travel;
        return false;
    }

    /// Regula falsi between a point outside (travel `outside`, distance `outsideDistance` >=
    /// epsilon) and one inside (distance `insideDistance` < 0) with the budget left; ends converged
    /// at the last estimate.
    bool beginRefining(float outside, float outsideDistance, float inside, float insideDistance) {
        lane_.refining = true;
        lane_.outside = outside;
        lane_.outsideDistance = outsideDistance;
        lane_.inside = inside;
        lane_.insideDistance = insideDistance;
        lane_.estimate = falsePosition();
        return lane_.iterations < lane_.maxIterations || endRefining();
    }

    bool refineStep(float distance) {
        ++lane_.iterations;
        if (std::abs(distance) < epsilonTexels_) return endRefining();
        if (distance > 0.0f) {
            lane_.outside = lane_.estimate;
            lane_.outsideDistance = distance;
        } else {
            lane_.inside = lane_.estimate;
            lane_.insideDistance = distance;
        }
        lane_.estimate = falsePosition();
        return lane_.iterations < lane_.maxIterations || endRefining();
    }

    float falsePosition() const {
        return lane_.outside + (lane_.inside - lane_.outside) * lane_.outsideDistance /
                                   (lane_.outsideDistance - lane_.insideDistance);
    }

    bool endRefining() {
        result_.converged = true;
        result_.travelTexels = lane_.estimate;
        result_.texelPosition = origin() + direction() * lane_.estimate;
        return false;
    }

    /// start, direction, toFloorAtStart, travel (of the current point), safeRadius (distance
    /// sampled at the previous point), previousStep (from the previous point to the current one),
    /// iterations, maxIterations and the refinement's state, as the wide kernel takes them.
    SphereTraceLane lane_{};
    Floor floor_ = Floor::Solid;
    float epsilonTexels_ = 0.0f;
    float factor_ = 1.0f;
    bool budgeted_ = false;
    MarchResult result_;  ///< its iterations lane_'s once the march has ended

    glm::vec3 origin() const { return {lane_.start[0], lane_.start[1], lane_.start[2]}; }
    glm::vec3 direction() const {
        return {lane_.direction[0], lane_.direction[1], lane_.direction[2]};
    }
};

/// Fixed linear steps from the top to the floor; at the first point inside (distance below
/// epsilon), Relief refines by binary search with the rest of the budget, FixedSteps by the
/// linear zero crossing of the last two distances.
template <class Filter>
MarchResult stepThroughSlab(const Filter& filter, const glm::vec3& start,
                            const glm::vec3& direction, Floor floor, const MarchSettings& settings,
                            float leaveTravelTexels) {
    MarchResult result;
    const bool relief = settings.method == MarchMethod::Relief;
    // The last linear step lands on the floor itself, which needs no sample.
    const int linearSteps =
        relief ? std::clamp(int(float(settings.maxIterations) * settings.reliefLinearShare), 1,
                            settings.maxIterations)
               : settings.maxIterations;
    float toFloor = start.z / -direction.z;
    leaveBeforeFloor(toFloor, floor, leaveTravelTexels);
    const float step = toFloor / float(linearSteps + 1);
    float outsideTravel = 0.0f;
    float outsideDistance = -1.0f;  // none sampled yet
    for (result.iterations = 1; result.iterations <= linearSteps; ++result.iterations) {
        const float travel = step * float(result.iterations);
        const float distance = filter.distanceTexels(start + direction * travel);
        if (distance >= settings.epsilonTexels) {
            outsideTravel = travel;
            outsideDistance = distance;
            continue;
        }
        float hitTravel = travel;
        if (relief) {
            float insideTravel = travel;
            for (; result.iterations < settings.maxIterations; ++result.iterations) {
                hitTravel = 0.5f * (outsideTravel + insideTravel);
                if (filter.distanceTexels(start + direction * hitTravel) >=
                    settings.epsilonTexels) {
                    outsideTravel = hitTravel;
                } else {
                    insideTravel = hitTravel;
                }
            }
            hitTravel = insideTravel;
        } else if (outsideDistance > 0.0f) {
            hitTravel = outsideTravel +
                        (travel - outsideTravel) * outsideDistance / (outsideDistance - distance);
        }
        result.converged = true;
        result.travelTexels = hitTravel;
        result.texelPosition = start + direction * hitTravel;
        return result;
    }
    result.iterations = linearSteps;
    endOnFloor(result, start, direction, 0.0f, toFloor, floor);
    return result;
}

}  // namespace detail

/// What march() returns at once, without a sample, for a ray outside its preconditions: a NaN/Inf
/// position or direction, or no budget (not converged, no iterations, the position as given);
/// nothing for a ray it marches.
inline std::optional<MarchResult> refusedMarch(const glm::vec3& position,
                                               const glm::vec3& direction,
                                               const MarchSettings& settings) {
    // Without this check a NaN coordinate reads a finite (clamped) texel and can report a converged
    // hit at a NaN position (tests/stress_test.cpp). Once per ray, not per step.
    if (std::isfinite(position.x) && std::isfinite(position.y) && std::isfinite(position.z) &&
        std::isfinite(direction.x) && std::isfinite(direction.y) && std::isfinite(direction.z) &&
        settings.maxIterations >= 1) {
        return std::nullopt;
    }
    MarchResult result;
    result.texelPosition = position;
    return result;
}

/// Marches from `position` along `direction` with `settings` (file note). Preconditions:
/// `direction` unit length with direction.z < 0; `position` inside the tile's slab. A NaN/Inf
/// position or direction (outside the preconditions) returns at once: not converged, no
/// iterations, the position as given. A ray that leaves the shell through an open border of its
/// mesh `leaveTravelTexels` along it, before the floor, ends there without a hit
/// (leaveBeforeFloor).
template <class Filter>
MarchResult march(const Filter& filter, const glm::vec3& position, const glm::vec3& direction,
                  Floor floor, const MarchSettings& settings,
                  float leaveTravelTexels = std::numeric_limits<float>::infinity()) {
    if (const std::optional<MarchResult> refused = refusedMarch(position, direction, settings))
        return *refused;
    switch (settings.method) {
        case MarchMethod::SphereTracing:
        case MarchMethod::OverRelaxed:
        case MarchMethod::Budgeted: {
            detail::SphereTraceRay ray;
            ray.start(position, direction, floor, settings, leaveTravelTexels);
            while (ray.step(filter)) {
            }
            return ray.result();
        }
        case MarchMethod::Relief:
        case MarchMethod::FixedSteps:
            return detail::stepThroughSlab(filter, position, direction, floor, settings,
                                           leaveTravelTexels);
    }
    return {};
}

/// Plain sphere tracing (ch. 8) with `maxIterations` and `epsilonTexels`.
template <class Filter>
MarchResult march(const Filter& filter, const glm::vec3& position, const glm::vec3& direction,
                  Floor floor, int maxIterations, float epsilonTexels) {
    MarchSettings settings;
    settings.method = MarchMethod::SphereTracing;
    settings.maxIterations = maxIterations;
    settings.epsilonTexels = epsilonTexels;
    return march(filter, position, direction, floor, settings);
}

/// Sphere-tracing methods (SphereTracing, OverRelaxed, Budgeted) can be interleaved
/// (marchInterleaved); the slab methods march one ray at a time.
inline bool isSphereTracing(MarchMethod method) {
    return method == MarchMethod::SphereTracing || method == MarchMethod::OverRelaxed ||
           method == MarchMethod::Budgeted;
}

/// Runs the sphere traces `rays` (started by SphereTraceRay::start, as march() starts them) to
/// their ends over `filter`, up to kMarchLanes rays at a time, one sample of each per round (any
/// `Marcher` with samplePosition() and advance(distance) that needs at least one more sample
/// interleaves the same way, e.g. the renderer's self-shadow rays): a sample's address depends on
/// the previous sample of the same ray, so a single ray keeps the processor waiting on each fetch,
/// while several rays' chains overlap, and a round's samples are taken together (distancesTexels8,
/// distancesTexels4). Every ray's result is bit-identical to its march() (the same operations in
/// the same order), whatever the order of the rays.
inline constexpr std::size_t kMarchLanes = 8;

namespace detail {

/// marchInterleaved one sample of each ray per round through the filter's distancesTexels8/4
/// (the rays' own steppers; any Marcher).
template <class Filter, class Marcher>
void marchInterleavedScalar(const Filter& filter, std::span<Marcher* const> rays) {
    static_assert(kMarchLanes == 8);
    Marcher* lanes[kMarchLanes];
    std::size_t laneCount = 0;
    std::size_t next = 0;
    for (; next < rays.size() && laneCount < kMarchLanes; ++next) lanes[laneCount++] = rays[next];
    glm::vec3 positions[kMarchLanes];
    alignas(32) float distances[kMarchLanes];
    while (laneCount > 0) {
        for (std::size_t lane = 0; lane < laneCount; ++lane)
            positions[lane] = lanes[lane]->samplePosition();
        if (laneCount == 1) {  // a lone ray (a single march): no padding lanes
            distances[0] = filter.distanceTexels(positions[0]);
        } else if (laneCount <= 4) {
            for (std::size_t lane = laneCount; lane < 4; ++lane) positions[lane] = positions[0];
            distancesTexels4(filter, positions, distances);
        } else {
            for (std::size_t lane = laneCount; lane < 8; ++lane) positions[lane] = positions[0];
            distancesTexels8(filter, positions, distances);
        }
        std::size_t kept = 0;
        for (std::size_t lane = 0; lane < laneCount; ++lane) {
            if (lanes[lane]->advance(distances[lane])) {
                lanes[kept++] = lanes[lane];
            } else if (next < rays.size()) {
                lanes[kept++] = rays[next++];
            }
        }
        laneCount = kept;
    }
}

/// The wide marches' frame: `rays` in chunks of 64, each split into the rays laneOf(ray) gives a
/// lane (a pointer to its state in a wide kernel's form; null: not for the kernel) and the rest;
/// kernel(lanes, count) takes the lanes' samples; then continues(ray, lane) finishes what the
/// kernel left to a laned ray and says whether it needs more samples, which
/// marchInterleavedScalar takes, with the rest.
template <class Filter, class Marcher, class LaneOf, class Kernel, class Continues>
void marchInLanes(const Filter& filter, std::span<Marcher* const> rays, LaneOf&& laneOf,
                  Kernel&& kernel, Continues&& continues) {
    constexpr std::size_t kChunk = 64;
    using Lane = std::remove_pointer_t<decltype(laneOf(rays[0]))>;
    for (std::size_t begin = 0; begin < rays.size(); begin += kChunk) {
        const std::size_t end = std::min(begin + kChunk, rays.size());
        Lane* lanes[kChunk];
        Marcher* laned[kChunk];
        Marcher* scalar[kChunk];  // rays marchInterleavedScalar takes on
        std::size_t laneCount = 0, scalarCount = 0;
        for (std::size_t index = begin; index < end; ++index) {
            if (Lane* lane = laneOf(rays[index])) {
                lanes[laneCount] = lane;
                laned[laneCount++] = rays[index];
            } else {
                scalar[scalarCount++] = rays[index];
            }
        }
        kernel(lanes, int(laneCount));
        for (std::size_t index = 0; index < laneCount; ++index)
            if (continues(laned[index], lanes[index])) scalar[scalarCount++] = laned[index];
        marchInterleavedScalar(filter, std::span<Marcher* const>(scalar, scalarCount));
    }
}

/// marchInterleaved for sphere traces over TileColumns' trilinear filter with the wide kernel
/// (render/march_wide.h): the rays' steps that go on in SIMD lanes, the step that ends each march
/// by the ray itself; the few rays that go on after it (a relaxed step taken back, a point the
/// wide filter does not take) are marched by marchInterleavedScalar. Precondition:
/// kSimdLevel >= SimdLevel::Avx2.
template <class Filter>
void marchSphereTracesWide(const Filter& filter, std::span<SphereTraceRay* const> rays) {
    const SphereTraceUniforms uniforms = rays[0]->uniforms();
    const WideColumns columns = filter.texels().wide();
    marchInLanes(
        filter, rays,
        [&](SphereTraceRay* ray) { return ray->fitsLanes(uniforms) ? &ray->lane() : nullptr; },
        [&](SphereTraceLane* const* lanes, int count) {
            sphereTraceOngoingSteps(columns, uniforms, lanes, count);
        },
        [&](SphereTraceRay* ray, const SphereTraceLane* lane) {
            return ray->advance(lane->distanceKnown ? lane->pendingDistance
                                                    : filter.distanceTexels(ray->samplePosition()));
        });
}

/// marchInterleaved for rays with a wide visibility kernel (render/march_wide.h): a Marcher
/// whose visibilityLane() is its state as a VisibilityLane, or null where the kernel does not
/// apply. Those rays' samples are taken in SIMD lanes; the samples the wide filter does not take
/// and the other rays, by marchInterleavedScalar. Precondition: kSimdLevel >= SimdLevel::Avx2.
template <class Filter, class Marcher>
void marchVisibilitiesWide(const Filter& filter, std::span<Marcher* const> rays) {
    const WideColumns columns = filter.texels().wide();
    marchInLanes(
        filter, rays, [](Marcher* ray) { return ray->visibilityLane(); },
        [&](VisibilityLane* const* lanes, int count) { visibilitySteps(columns, lanes, count); },
        [](Marcher* ray, const VisibilityLane*) { return ray->needsSample(); });
}

}  // namespace detail

template <class Filter, class Marcher = detail::SphereTraceRay>
void marchInterleaved(const Filter& filter, std::span<Marcher* const> rays) {
    if constexpr (std::is_same_v<Filter, BasicTrilinearFilter<ColumnTexels>>) {
        if (kSimdLevel >= SimdLevel::Avx2 && rays.size() > 1) {
            if constexpr (std::is_same_v<Marcher, detail::SphereTraceRay>) {
                detail::marchSphereTracesWide(filter, rays);
                return;
            } else if constexpr (requires(Marcher & ray) { ray.visibilityLane(); }) {
                detail::marchVisibilitiesWide(filter, rays);
                return;
            }
        }
    }
    detail::marchInterleavedScalar(filter, rays);
}

}  // namespace distile
