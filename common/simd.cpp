// The choice of common/simd.h. Built for the baseline instruction set like the rest of distile
// (never with -mavx2): it runs on every processor before anything knows which lanes it has.
#include "common/simd.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>

namespace distile {

namespace {

/// The widest level this processor runs.
SimdLevel processorLevel() {
#if defined(__x86_64__)
    __builtin_cpu_init();  // may run before libgcc's own initialisation
    if (!__builtin_cpu_supports("avx2")) return SimdLevel::Sse2;
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw"))
        return SimdLevel::Avx512;
    return SimdLevel::Avx2;
#else
    return SimdLevel::Sse2;
#endif
}

/// The level DISTILE_SIMD asks for; Avx512 (the widest) when unset or unknown.
SimdLevel requestedLevel() {
    const char* requested = std::getenv("DISTILE_SIMD");
    if (!requested) return SimdLevel::Avx512;
    for (SimdLevel level : {SimdLevel::Sse2, SimdLevel::Avx2, SimdLevel::Avx512}) {
        if (std::strcmp(requested, simdLevelName(level)) == 0) return level;
    }
    std::fprintf(stderr,
                 "distile: warning: DISTILE_SIMD=%s is not one of sse2, avx2, avx512; the widest "
                 "lanes the processor has are used\n",
                 requested);
    return SimdLevel::Avx512;
}

}  // namespace

const char* simdLevelName(SimdLevel level) {
    switch (level) {
        case SimdLevel::Sse2:
            return "sse2";
        case SimdLevel::Avx2:
            return "avx2";
        case SimdLevel::Avx512:
            return "avx512";
    }
    return "?";
}

const SimdLevel kSimdLevel = [] {
    const SimdLevel processor = processorLevel();
    const SimdLevel requested = requestedLevel();
    return requested < processor ? requested : processor;
}();

}  // namespace distile
