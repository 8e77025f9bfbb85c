/// @file
/// The AVX2 body of the wide trilinear filter (sampler/trilinear_wide.h), for translation units
/// built with AVX2 and without FMA only (sampler/trilinear_wide.cpp, render/march_wide.cpp): its
/// functions are static, so each such unit has its own copy and no other code links to them.
#pragma once

#if !defined(__AVX2__) || defined(__FMA__)
#error "sampler/trilinear_avx2.h is for units built with -mavx2 and without FMA"
#endif

#include <immintrin.h>

#include "sampler/trilinear_wide.h"

namespace distile::detail {

/// detail::floorFinite, lane by lane: truncate, then step down where that rounded up.
[[gnu::always_inline]] static inline __m256 floorFiniteAvx2(__m256 value) {
    const __m256 truncated = _mm256_cvtepi32_ps(_mm256_cvttps_epi32(value));
    return _mm256_sub_ps(truncated, _mm256_and_ps(_mm256_cmp_ps(truncated, value, _CMP_GT_OQ),
                                                  _mm256_set1_ps(1.0f)));
}

/// detail::periodicAxis in its near case, lane by lane: the lower and upper index and the weight
/// (returned). Lanes outside the near case (huge or not finite, or more than a period away) are
/// added to `outside`; their indices are unspecified.
[[gnu::always_inline]] static inline __m256 periodicAxisAvx2(__m256 coordinates, int extent,
                                                             __m256i& lower, __m256i& upper,
                                                             __m256i& outside) {
    const __m256i zero = _mm256_setzero_si256();
    const __m256 shifted = _mm256_sub_ps(coordinates, _mm256_set1_ps(0.5f));
    const __m256 magnitude =
        _mm256_and_ps(shifted, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff)));
    outside = _mm256_or_si256(outside, _mm256_castps_si256(_mm256_cmp_ps(
                                           magnitude, _mm256_set1_ps(1.0e9f), _CMP_NLT_UQ)));
    const __m256 floorValue = floorFiniteAvx2(shifted);
    const __m256i extentLanes = _mm256_set1_epi32(extent);
    const __m256i last = _mm256_set1_epi32(extent - 1);
    __m256i index = _mm256_cvttps_epi32(floorValue);
    index = _mm256_add_epi32(index, _mm256_and_si256(_mm256_cmpgt_epi32(zero, index), extentLanes));
    index = _mm256_sub_epi32(index, _mm256_and_si256(_mm256_cmpgt_epi32(index, last), extentLanes));
    outside = _mm256_or_si256(
        outside, _mm256_or_si256(_mm256_cmpgt_epi32(zero, index), _mm256_cmpgt_epi32(index, last)));
    lower = index;
    const __m256i next = _mm256_add_epi32(index, _mm256_set1_epi32(1));
    upper = _mm256_andnot_si256(_mm256_cmpeq_epi32(next, extentLanes), next);
    return _mm256_sub_ps(shifted, floorValue);
}

/// detail::clampedSliceCoordinate, lane by lane: z - 0.5 clamped to [-0.5, D - 0.5], NaN to -0.5.
[[gnu::always_inline]] static inline __m256 clampedSliceCoordinateAvx2(__m256 z, int depth) {
    const __m256 firstFace = _mm256_set1_ps(-0.5f);
    const __m256 lastFace = _mm256_set1_ps(float(depth) - 0.5f);
    __m256 shifted = _mm256_sub_ps(z, _mm256_set1_ps(0.5f));
    shifted = _mm256_blendv_ps(firstFace, shifted, _mm256_cmp_ps(shifted, firstFace, _CMP_GE_OQ));
    return _mm256_blendv_ps(lastFace, shifted, _mm256_cmp_ps(shifted, lastFace, _CMP_LT_OQ));
}

/// BasicTrilinearFilter<ColumnTexels>::distanceTexels at the points (x, y, z) lane by lane, bit
/// for bit, where `outside` is clear: the lanes periodicAxis does not take in its near case (huge
/// or not finite x or y) are added to `outside`, and lanes already in it read texel 0 and give an
/// unspecified value.
[[gnu::always_inline]] static inline __m256 trilinearColumnsAvx2(const WideColumns& columns,
                                                                 __m256 x, __m256 y, __m256 z,
                                                                 __m256i& outside) {
    const __m256i zero = _mm256_setzero_si256();
    __m256i xLower, xUpper, yLower, yUpper;
    const __m256 xWeight = periodicAxisAvx2(x, columns.width, xLower, xUpper, outside);
    const __m256 yWeight = periodicAxisAvx2(y, columns.height, yLower, yUpper, outside);
    // detail::extendedAxis: clampedSliceCoordinate (NaN to the first face), then the lower slice
    // clamped to [0, D - 2].
    const __m256 zShifted = clampedSliceCoordinateAvx2(z, columns.depth);
    __m256i zLower = _mm256_cvttps_epi32(floorFiniteAvx2(zShifted));
    zLower = _mm256_max_epi32(zLower, zero);
    zLower = _mm256_min_epi32(zLower, _mm256_set1_epi32(columns.depth - 2));
    const __m256 zWeight = _mm256_sub_ps(zShifted, _mm256_cvtepi32_ps(zLower));
    // Element of slice zLower in column (x, y): x D + y W D + z (ColumnTexels), in 32 bits (a
    // tile's texel count fits: TileColumns). Outside lanes read texel 0.
    const __m256i columnStride = _mm256_set1_epi32(columns.depth);
    const __m256i rowStride = _mm256_set1_epi32(columns.width * columns.depth);
    const __m256i xLowerStart =
        _mm256_mullo_epi32(_mm256_andnot_si256(outside, xLower), columnStride);
    const __m256i xUpperStart =
        _mm256_mullo_epi32(_mm256_andnot_si256(outside, xUpper), columnStride);
    const __m256i yLowerStart = _mm256_add_epi32(
        _mm256_mullo_epi32(_mm256_andnot_si256(outside, yLower), rowStride), zLower);
    const __m256i yUpperStart = _mm256_add_epi32(
        _mm256_mullo_epi32(_mm256_andnot_si256(outside, yUpper), rowStride), zLower);
    const __m256 scale = _mm256_set1_ps(columns.texelsPerCode);
    const int* base = reinterpret_cast<const int*>(columns.codes);
    // One column's value at each point's z: codes of slices z and z + 1 as one 32-bit gather
    // (2-byte elements), as texels (float(code) x texelsPerCode), lerped along z.
    const auto alongZ = [&](__m256i elements) {
        const __m256i pairs = _mm256_i32gather_epi32(base, elements, 2);
        const __m256 lower = _mm256_mul_ps(
            _mm256_cvtepi32_ps(_mm256_srai_epi32(_mm256_slli_epi32(pairs, 16), 16)), scale);
        const __m256 upper = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srai_epi32(pairs, 16)), scale);
        return _mm256_add_ps(lower, _mm256_mul_ps(_mm256_sub_ps(upper, lower), zWeight));
    };
    const auto lerp = [](__m256 a, __m256 b, __m256 t) {
        return _mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), t));
    };
    const __m256 rowLower = lerp(alongZ(_mm256_add_epi32(xLowerStart, yLowerStart)),
                                 alongZ(_mm256_add_epi32(xUpperStart, yLowerStart)), xWeight);
    const __m256 rowUpper = lerp(alongZ(_mm256_add_epi32(xLowerStart, yUpperStart)),
                                 alongZ(_mm256_add_epi32(xUpperStart, yUpperStart)), xWeight);
    return lerp(rowLower, rowUpper, yWeight);
}

}  // namespace distile::detail
