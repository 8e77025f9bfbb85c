/// @file
/// The instruction set distile's wide kernels use, decided once per process and read everywhere
/// (the sampler's filters, the march, the entry of rays into flat shells). Every choice gives the
/// same results bit for bit: the wide kernels do the scalar code's operations in its order,
/// without FMA; a narrower choice is only slower (docs/internals.md).
#pragma once

namespace distile {

/// The widest lanes the kernels may use. Ordered: a level includes the ones below it.
enum class SimdLevel {
    Sse2,    ///< one point at a time (four with SSE2): every x86-64 processor
    Avx2,    ///< eight lanes
    Avx512,  ///< sixteen lanes (AVX-512F and BW)
};

/// The level in use: the widest the processor has (x86-64 only; Sse2 elsewhere), lowered by the
/// environment variable DISTILE_SIMD (sse2, avx2 or avx512; unset: the widest). An unknown value
/// is reported once on stderr and the widest level is used. Decided before main() runs; reads
/// Sse2 during the static initialisation of other translation units, which is safe (the same
/// results, one point at a time). The eight-lane kernels run where it is at least Avx2, the
/// sixteen-lane ones where it is Avx512. A plain variable (no inline function to read it), so
/// the units built with -mavx2 can include this header.
extern const SimdLevel kSimdLevel;

/// "sse2", "avx2", "avx512": the names DISTILE_SIMD accepts.
const char* simdLevelName(SimdLevel level);

}  // namespace distile
