/// @file
/// SIMD lanes for the wide kernels (sampler/detail/trilinear_lanes.h, render/detail/march_lanes.h):
/// the float and int operations they need, for eight lanes with AVX2 (Lanes8) and sixteen with
/// AVX-512F and BW (Lanes16), so each kernel is written once for both widths. For translation units
/// built with those instruction sets and without FMA only: every lane rounds as scalar code does.
/// Everything here has internal linkage, so each such unit has its own copy and no code built for
/// another instruction set links to it.
#pragma once

#if !defined(__AVX2__) || defined(__FMA__)
#error \
    "sampler/detail/simd_lanes.h is for units built with -mavx2 (or -mavx512f -mavx512bw), no FMA"
#endif

#include <immintrin.h>

#include <cstdint>

namespace distile::detail {
namespace {

#define DISTILE_LANES_INLINE [[gnu::always_inline]] static inline

/// Eight lanes (AVX2). A mask is a float vector with all bits of its set lanes set.
struct Lanes8 {
    static constexpr int kWidth = 8;
    using F = __m256;
    using I = __m256i;
    using M = __m256;

    DISTILE_LANES_INLINE F load(const float* values) { return _mm256_load_ps(values); }
    DISTILE_LANES_INLINE void store(float* values, F v) { _mm256_store_ps(values, v); }
    DISTILE_LANES_INLINE F loadUnaligned(const float* values) { return _mm256_loadu_ps(values); }
    DISTILE_LANES_INLINE void storeUnaligned(float* values, F v) { _mm256_storeu_ps(values, v); }
    DISTILE_LANES_INLINE void storeIntUnaligned(int* values, I v) {
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(values), v);
    }
    DISTILE_LANES_INLINE I loadInt(const int* values) {
        return _mm256_load_si256(reinterpret_cast<const __m256i*>(values));
    }
    DISTILE_LANES_INLINE void storeInt(int* values, I v) {
        _mm256_store_si256(reinterpret_cast<__m256i*>(values), v);
    }
    /// Masks kept in memory as ints: -1 set, 0 clear.
    DISTILE_LANES_INLINE M loadMask(const int* values) {
        return _mm256_castsi256_ps(loadInt(values));
    }
    DISTILE_LANES_INLINE void storeMask(int* values, M m) {
        storeInt(values, _mm256_castps_si256(m));
    }

    /// Axis `axis` of kWidth points stored x, y, z, from the points' scalars (a vector load over
    /// separate stores would wait for them).
    DISTILE_LANES_INLINE F strided3(const float* xyz, int axis) {
        return _mm256_setr_ps(xyz[axis], xyz[3 + axis], xyz[6 + axis], xyz[9 + axis],
                              xyz[12 + axis], xyz[15 + axis], xyz[18 + axis], xyz[21 + axis]);
    }
    DISTILE_LANES_INLINE F set1(float value) { return _mm256_set1_ps(value); }
    DISTILE_LANES_INLINE I set1(int value) { return _mm256_set1_epi32(value); }
    DISTILE_LANES_INLINE F add(F a, F b) { return _mm256_add_ps(a, b); }
    DISTILE_LANES_INLINE F sub(F a, F b) { return _mm256_sub_ps(a, b); }
    DISTILE_LANES_INLINE F mul(F a, F b) { return _mm256_mul_ps(a, b); }
    DISTILE_LANES_INLINE F div(F a, F b) { return _mm256_div_ps(a, b); }
    DISTILE_LANES_INLINE F abs(F a) {
        return _mm256_and_ps(a, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff)));
    }
    /// -a: the sign bit flipped (-0 for 0, as scalar negation).
    DISTILE_LANES_INLINE F negate(F a) {
        return _mm256_xor_ps(a, _mm256_castsi256_ps(_mm256_set1_epi32(int(0x80000000u))));
    }
    DISTILE_LANES_INLINE F sqrt(F a) { return _mm256_sqrt_ps(a); }
    DISTILE_LANES_INLINE F ceil(F a) { return _mm256_ceil_ps(a); }
    /// Ordered comparisons (false where either is NaN), and a >= b unordered (true there).
    DISTILE_LANES_INLINE M less(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
    DISTILE_LANES_INLINE M greater(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); }
    DISTILE_LANES_INLINE M greaterEqual(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_GE_OQ); }
    DISTILE_LANES_INLINE M notLess(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_NLT_UQ); }
    /// Lanes of b where m is set, of a elsewhere.
    DISTILE_LANES_INLINE F blend(F a, F b, M m) { return _mm256_blendv_ps(a, b, m); }
    DISTILE_LANES_INLINE I blend(I a, I b, M m) {
        return _mm256_castps_si256(
            _mm256_blendv_ps(_mm256_castsi256_ps(a), _mm256_castsi256_ps(b), m));
    }
    /// Lanes of v where m is set, 0 elsewhere; and the other way round.
    DISTILE_LANES_INLINE F onlyWhere(M m, F v) { return _mm256_and_ps(m, v); }
    DISTILE_LANES_INLINE I onlyWhere(M m, I v) {
        return _mm256_and_si256(_mm256_castps_si256(m), v);
    }
    DISTILE_LANES_INLINE I zeroWhere(M m, I v) {
        return _mm256_andnot_si256(_mm256_castps_si256(m), v);
    }

    DISTILE_LANES_INLINE M both(M a, M b) { return _mm256_and_ps(a, b); }
    DISTILE_LANES_INLINE M either(M a, M b) { return _mm256_or_ps(a, b); }
    /// b and not a.
    DISTILE_LANES_INLINE M butNot(M a, M b) { return _mm256_andnot_ps(a, b); }
    /// Lanes of mask b where m is set, of mask a elsewhere.
    DISTILE_LANES_INLINE M blendMasks(M a, M b, M m) { return _mm256_blendv_ps(a, b, m); }
    DISTILE_LANES_INLINE M allLanes() { return _mm256_castsi256_ps(_mm256_set1_epi32(-1)); }
    DISTILE_LANES_INLINE M uniformMask(bool on) {
        return _mm256_castsi256_ps(_mm256_set1_epi32(on ? -1 : 0));
    }
    DISTILE_LANES_INLINE unsigned bits(M m) { return unsigned(_mm256_movemask_ps(m)); }

    DISTILE_LANES_INLINE I add(I a, I b) { return _mm256_add_epi32(a, b); }
    DISTILE_LANES_INLINE I sub(I a, I b) { return _mm256_sub_epi32(a, b); }
    DISTILE_LANES_INLINE I mullo(I a, I b) { return _mm256_mullo_epi32(a, b); }
    DISTILE_LANES_INLINE I max(I a, I b) { return _mm256_max_epi32(a, b); }
    DISTILE_LANES_INLINE I min(I a, I b) { return _mm256_min_epi32(a, b); }
    DISTILE_LANES_INLINE M greater(I a, I b) {
        return _mm256_castsi256_ps(_mm256_cmpgt_epi32(a, b));
    }
    DISTILE_LANES_INLINE M equal(I a, I b) { return _mm256_castsi256_ps(_mm256_cmpeq_epi32(a, b)); }
    DISTILE_LANES_INLINE I truncate(F v) { return _mm256_cvttps_epi32(v); }
    DISTILE_LANES_INLINE F toFloat(I v) { return _mm256_cvtepi32_ps(v); }
    /// The signed 16-bit halves of each 32-bit lane.
    DISTILE_LANES_INLINE I lowHalf(I v) { return _mm256_srai_epi32(_mm256_slli_epi32(v, 16), 16); }
    DISTILE_LANES_INLINE I highHalf(I v) { return _mm256_srai_epi32(v, 16); }
    /// 32 bits at base + 2 x element bytes (two 16-bit codes), lane by lane.
    DISTILE_LANES_INLINE I gatherCodePairs(const std::int16_t* base, I elements) {
        return _mm256_i32gather_epi32(reinterpret_cast<const int*>(base), elements, 2);
    }
    /// The codes of four consecutive slices from base + element onwards, lane by lane, as
    /// sign-extended 32-bit lanes in slices[0 .. 4): two code-pair gathers.
    DISTILE_LANES_INLINE void gatherCodes4(const std::int16_t* base, I elements, I slices[4]) {
        const I low = gatherCodePairs(base, elements);
        const I high = gatherCodePairs(base, add(elements, set1(2)));
        slices[0] = lowHalf(low);
        slices[1] = highHalf(low);
        slices[2] = lowHalf(high);
        slices[3] = highHalf(high);
    }
    /// Back to code without these lanes: with dirty upper halves of the vector registers, every
    /// SSE instruction after this would pay for merging them (the compiler does not always clear
    /// them itself).
    DISTILE_LANES_INLINE void leave() { _mm256_zeroupper(); }
};

#if defined(__AVX512F__) && defined(__AVX512BW__)

/// Sixteen lanes (AVX-512F and BW). A mask is a bit per lane.
struct Lanes16 {
    static constexpr int kWidth = 16;
    using F = __m512;
    using I = __m512i;
    using M = __mmask16;

    DISTILE_LANES_INLINE F load(const float* values) { return _mm512_load_ps(values); }
    DISTILE_LANES_INLINE void store(float* values, F v) { _mm512_store_ps(values, v); }
    DISTILE_LANES_INLINE F loadUnaligned(const float* values) { return _mm512_loadu_ps(values); }
    DISTILE_LANES_INLINE void storeUnaligned(float* values, F v) { _mm512_storeu_ps(values, v); }
    DISTILE_LANES_INLINE void storeIntUnaligned(int* values, I v) {
        _mm512_storeu_si512(values, v);
    }
    DISTILE_LANES_INLINE I loadInt(const int* values) { return _mm512_load_si512(values); }
    DISTILE_LANES_INLINE void storeInt(int* values, I v) { _mm512_store_si512(values, v); }
    DISTILE_LANES_INLINE M loadMask(const int* values) {
        const I v = loadInt(values);
        return _mm512_test_epi32_mask(v, v);
    }
    DISTILE_LANES_INLINE void storeMask(int* values, M m) {
        storeInt(values, _mm512_maskz_mov_epi32(m, _mm512_set1_epi32(-1)));
    }

    DISTILE_LANES_INLINE F strided3(const float* xyz, int axis) {
        return _mm512_setr_ps(xyz[axis], xyz[3 + axis], xyz[6 + axis], xyz[9 + axis],
                              xyz[12 + axis], xyz[15 + axis], xyz[18 + axis], xyz[21 + axis],
                              xyz[24 + axis], xyz[27 + axis], xyz[30 + axis], xyz[33 + axis],
                              xyz[36 + axis], xyz[39 + axis], xyz[42 + axis], xyz[45 + axis]);
    }
    DISTILE_LANES_INLINE F set1(float value) { return _mm512_set1_ps(value); }
    DISTILE_LANES_INLINE I set1(int value) { return _mm512_set1_epi32(value); }
    DISTILE_LANES_INLINE F add(F a, F b) { return _mm512_add_ps(a, b); }
    DISTILE_LANES_INLINE F sub(F a, F b) { return _mm512_sub_ps(a, b); }
    DISTILE_LANES_INLINE F mul(F a, F b) { return _mm512_mul_ps(a, b); }
    DISTILE_LANES_INLINE F div(F a, F b) { return _mm512_div_ps(a, b); }
    DISTILE_LANES_INLINE F abs(F a) {
        return _mm512_castsi512_ps(
            _mm512_and_si512(_mm512_castps_si512(a), _mm512_set1_epi32(0x7fffffff)));
    }
    DISTILE_LANES_INLINE F negate(F a) {
        return _mm512_castsi512_ps(
            _mm512_xor_si512(_mm512_castps_si512(a), _mm512_set1_epi32(int(0x80000000u))));
    }
    DISTILE_LANES_INLINE F sqrt(F a) { return _mm512_sqrt_ps(a); }
    DISTILE_LANES_INLINE F ceil(F a) {
        return _mm512_roundscale_ps(a, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC);
    }
    DISTILE_LANES_INLINE M less(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ); }
    DISTILE_LANES_INLINE M greater(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_GT_OQ); }
    DISTILE_LANES_INLINE M greaterEqual(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_GE_OQ); }
    DISTILE_LANES_INLINE M notLess(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_NLT_UQ); }
    DISTILE_LANES_INLINE F blend(F a, F b, M m) { return _mm512_mask_blend_ps(m, a, b); }
    DISTILE_LANES_INLINE I blend(I a, I b, M m) { return _mm512_mask_blend_epi32(m, a, b); }
    DISTILE_LANES_INLINE F onlyWhere(M m, F v) { return _mm512_maskz_mov_ps(m, v); }
    DISTILE_LANES_INLINE I onlyWhere(M m, I v) { return _mm512_maskz_mov_epi32(m, v); }
    DISTILE_LANES_INLINE I zeroWhere(M m, I v) {
        return _mm512_maskz_mov_epi32(_knot_mask16(m), v);
    }

    // In the mask registers (plain integer operations would move masks to and from them).
    DISTILE_LANES_INLINE M both(M a, M b) { return _kand_mask16(a, b); }
    DISTILE_LANES_INLINE M either(M a, M b) { return _kor_mask16(a, b); }
    DISTILE_LANES_INLINE M butNot(M a, M b) { return _kandn_mask16(a, b); }
    DISTILE_LANES_INLINE M blendMasks(M a, M b, M m) {
        return _kor_mask16(_kandn_mask16(m, a), _kand_mask16(b, m));
    }
    DISTILE_LANES_INLINE M allLanes() { return M(0xffff); }
    DISTILE_LANES_INLINE M uniformMask(bool on) { return on ? M(0xffff) : M(0); }
    DISTILE_LANES_INLINE unsigned bits(M m) { return unsigned(m); }

    DISTILE_LANES_INLINE I add(I a, I b) { return _mm512_add_epi32(a, b); }
    DISTILE_LANES_INLINE I sub(I a, I b) { return _mm512_sub_epi32(a, b); }
    DISTILE_LANES_INLINE I mullo(I a, I b) { return _mm512_mullo_epi32(a, b); }
    DISTILE_LANES_INLINE I max(I a, I b) { return _mm512_max_epi32(a, b); }
    DISTILE_LANES_INLINE I min(I a, I b) { return _mm512_min_epi32(a, b); }
    DISTILE_LANES_INLINE M greater(I a, I b) { return _mm512_cmpgt_epi32_mask(a, b); }
    DISTILE_LANES_INLINE M equal(I a, I b) { return _mm512_cmpeq_epi32_mask(a, b); }
    DISTILE_LANES_INLINE I truncate(F v) { return _mm512_cvttps_epi32(v); }
    DISTILE_LANES_INLINE F toFloat(I v) { return _mm512_cvtepi32_ps(v); }
    DISTILE_LANES_INLINE I lowHalf(I v) { return _mm512_srai_epi32(_mm512_slli_epi32(v, 16), 16); }
    DISTILE_LANES_INLINE I highHalf(I v) { return _mm512_srai_epi32(v, 16); }
    DISTILE_LANES_INLINE I gatherCodePairs(const std::int16_t* base, I elements) {
        return _mm512_i32gather_epi32(elements, base, 2);
    }
    /// Lanes8::gatherCodes4 as two 64-bit gathers of eight lanes each (half the loads of four
    /// code-pair gathers), the codes sorted into slices with two word permutes (AVX-512BW).
    DISTILE_LANES_INLINE void gatherCodes4(const std::int16_t* base, I elements, I slices[4]) {
        const __m512i first = _mm512_i32gather_epi64(_mm512_castsi512_si256(elements), base, 2);
        const __m512i second =
            _mm512_i32gather_epi64(_mm512_extracti64x4_epi64(elements, 1), base, 2);
        // Word 4 l + s of `first` is slice s of lane l (lanes 0-7), of `second` lane l + 8.
        alignas(64) static constexpr short kSlices01[32] = {
            0, 4, 8, 12, 16, 20, 24, 28, 32, 36, 40, 44, 48, 52, 56, 60,
            1, 5, 9, 13, 17, 21, 25, 29, 33, 37, 41, 45, 49, 53, 57, 61};
        alignas(64) static constexpr short kSlices23[32] = {
            2, 6, 10, 14, 18, 22, 26, 30, 34, 38, 42, 46, 50, 54, 58, 62,
            3, 7, 11, 15, 19, 23, 27, 31, 35, 39, 43, 47, 51, 55, 59, 63};
        const __m512i slices01 =
            _mm512_permutex2var_epi16(first, _mm512_load_si512(kSlices01), second);
        const __m512i slices23 =
            _mm512_permutex2var_epi16(first, _mm512_load_si512(kSlices23), second);
        slices[0] = _mm512_cvtepi16_epi32(_mm512_castsi512_si256(slices01));
        slices[1] = _mm512_cvtepi16_epi32(_mm512_extracti64x4_epi64(slices01, 1));
        slices[2] = _mm512_cvtepi16_epi32(_mm512_castsi512_si256(slices23));
        slices[3] = _mm512_cvtepi16_epi32(_mm512_extracti64x4_epi64(slices23, 1));
    }
    DISTILE_LANES_INLINE void leave() { _mm256_zeroupper(); }
};

#endif

#undef DISTILE_LANES_INLINE

}  // namespace
}  // namespace distile::detail
