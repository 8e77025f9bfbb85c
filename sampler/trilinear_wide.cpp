// The AVX2 kernel of sampler/trilinear_wide.h. This file is compiled with -mavx2 (and without FMA,
// so no product is fused into a sum): it includes nothing with inline functions that the rest of
// distile also instantiates, so no AVX2 code can stand in for theirs.
#include "sampler/trilinear_wide.h"

#include <cstdlib>
#include <cstring>

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)
#include "sampler/trilinear_avx2.h"
#endif

namespace distile::detail {

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)

const bool kWideTrilinear = [] {
    // DISTILE_SIMD=sse2 keeps to the SSE2 paths (the same results; to compare or reproduce).
    const char* simd = std::getenv("DISTILE_SIMD");
    if (simd && std::strcmp(simd, "sse2") == 0) return false;
    __builtin_cpu_init();  // may run before libgcc's own initialisation
    return __builtin_cpu_supports("avx2") != 0;
}();

unsigned trilinearColumns8(const WideColumns& columns, const float* xyz, float* out) {
    // Lanes from the points' scalars (a vector load over eight separate stores would wait).
    const auto lanes = [&](int axis) {
        return _mm256_setr_ps(xyz[axis], xyz[3 + axis], xyz[6 + axis], xyz[9 + axis],
                              xyz[12 + axis], xyz[15 + axis], xyz[18 + axis], xyz[21 + axis]);
    };
    __m256i outside = _mm256_setzero_si256();
    _mm256_storeu_ps(out, trilinearColumnsAvx2(columns, lanes(0), lanes(1), lanes(2), outside));
    const unsigned unknown = unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(outside)));
    _mm256_zeroupper();  // back to SSE code (see render/march_wide.cpp)
    return unknown;
}

#else

const bool kWideTrilinear = false;

unsigned trilinearColumns8(const WideColumns&, const float*, float*) {
    return 0xffu;
}

#endif

}  // namespace distile::detail
