// The kernel of render/march_wide.h with AVX2 (eight lanes), or, where the processor has
// AVX-512, render/march_wide16.cpp's sixteen. Compiled with -mavx2 and without FMA (see
// sampler/trilinear_wide.cpp: nothing here is shared with the SSE2 build of distile).
#include "render/march_wide.h"

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)
#include "render/detail/march_lanes.h"
#endif

namespace distile::detail {

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)

void sphereTraceOngoingSteps(const WideColumns& columns, const SphereTraceUniforms& uniforms,
                             SphereTraceLane* const* lanes, int count) {
    if (kSimdLevel == SimdLevel::Avx512)
        sphereTraceOngoingSteps16(columns, uniforms, lanes, count);
    else
        sphereTraceOngoingStepsInLanes<Lanes8>(columns, uniforms, lanes, count);
}

void visibilitySteps(const WideColumns& columns, VisibilityLane* const* lanes, int count) {
    if (kSimdLevel == SimdLevel::Avx512)
        visibilitySteps16(columns, lanes, count);
    else
        visibilityStepsInLanes<Lanes8>(columns, lanes, count);
}

#else

void sphereTraceOngoingSteps(const WideColumns&, const SphereTraceUniforms&,
                             SphereTraceLane* const* lanes, int count) {
    for (int i = 0; i < count; ++i) lanes[i]->distanceKnown = false;  // never called: no AVX2
}

void visibilitySteps(const WideColumns&, VisibilityLane* const*, int) {}  // never called

#endif

}  // namespace distile::detail
