// The sixteen-lane (AVX-512) kernels of sampler/trilinear_wide.h. Compiled with -mavx512f
// -mavx512bw and without FMA, and run only where kSimdLevel is Avx512 (common/simd.h).
#include "sampler/trilinear_wide.h"

#if defined(__x86_64__) && defined(__AVX512F__) && defined(__AVX512BW__) && !defined(__FMA__)
#include "sampler/detail/trilinear_lanes.h"
#endif

namespace distile::detail {

#if defined(__x86_64__) && defined(__AVX512F__) && defined(__AVX512BW__) && !defined(__FMA__)

unsigned tricubicGradientColumns16(const WideColumns& columns, const float* xyz, float* gradients) {
    return tricubicGradientColumnsLanes<Lanes16>(columns, xyz, gradients);
}

#else

unsigned tricubicGradientColumns16(const WideColumns&, const float*, float*) {
    return 0xffffu;  // never called
}

#endif

}  // namespace distile::detail
