// The kernel of render/march_wide.h with AVX-512 (sixteen lanes). Compiled with -mavx512f
// -mavx512bw and without FMA, and run only where kSimdLevel is Avx512 (common/simd.h).
#include "render/march_wide.h"

#if defined(__x86_64__) && defined(__AVX512F__) && defined(__AVX512BW__) && !defined(__FMA__)
#include "render/detail/march_lanes.h"
#endif

namespace distile::detail {

#if defined(__x86_64__) && defined(__AVX512F__) && defined(__AVX512BW__) && !defined(__FMA__)

void sphereTraceOngoingSteps16(const WideColumns& columns, const SphereTraceUniforms& uniforms,
                               SphereTraceLane* const* lanes, int count) {
    sphereTraceOngoingStepsInLanes<Lanes16>(columns, uniforms, lanes, count);
}

void visibilitySteps16(const WideColumns& columns, VisibilityLane* const* lanes, int count) {
    visibilityStepsInLanes<Lanes16>(columns, lanes, count);
}

#else

void visibilitySteps16(const WideColumns&, VisibilityLane* const*, int) {}  // never called

void sphereTraceOngoingSteps16(const WideColumns&, const SphereTraceUniforms&,
                               SphereTraceLane* const* lanes, int count) {
    for (int i = 0; i < count; ++i) lanes[i]->distanceKnown = false;  // never called
}

#endif

}  // namespace distile::detail
