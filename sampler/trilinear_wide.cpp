// The eight-lane (AVX2) kernels of sampler/trilinear_wide.h. This file is compiled with -mavx2 (and
// without FMA, so no product is fused into a sum): it includes nothing with inline functions that
// the rest of distile also instantiates, so no AVX2 code can stand in for theirs.
#include "sampler/trilinear_wide.h"

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)
#include "sampler/detail/trilinear_lanes.h"
#endif

namespace distile::detail {

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)

unsigned trilinearColumns8(const WideColumns& columns, const float* xyz, float* out) {
    Lanes8::M outside = _mm256_setzero_ps();
    _mm256_storeu_ps(out, trilinearColumnsLanes<Lanes8>(columns, Lanes8::strided3(xyz, 0),
                                                        Lanes8::strided3(xyz, 1),
                                                        Lanes8::strided3(xyz, 2), outside));
    const unsigned unknown = Lanes8::bits(outside);
    Lanes8::leave();
    return unknown;
}

unsigned tricubicGradientColumns(const WideColumns& columns, const float* xyz, int count,
                                 float* gradients) {
    const unsigned points = (1u << count) - 1u;
    if (kSimdLevel == SimdLevel::Avx512)
        return points & tricubicGradientColumns16(columns, xyz, gradients);
    unsigned redo = tricubicGradientColumnsLanes<Lanes8>(columns, xyz, gradients);
    if (count > 8)
        redo |= tricubicGradientColumnsLanes<Lanes8>(columns, xyz + 24, gradients + 24) << 8;
    return points & redo;
}

#else

unsigned tricubicGradientColumns(const WideColumns&, const float*, int count, float*) {
    return (1u << count) - 1u;  // never called: no AVX2
}

unsigned trilinearColumns8(const WideColumns&, const float*, float*) {
    return 0xffu;
}

#endif

}  // namespace distile::detail
