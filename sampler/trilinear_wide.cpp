// The AVX2 kernel of sampler/trilinear_wide.h. This file is compiled with -mavx2 (and without FMA,
// so no product is fused into a sum): it includes nothing with inline functions that the rest of
// distile also instantiates, so no AVX2 code can stand in for theirs.
#include "sampler/trilinear_wide.h"

#include <cstdlib>
#include <cstring>

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)
#include "sampler/trilinear_lanes.h"
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

const bool kSixteenLanes = [] {
    const char* simd = std::getenv("DISTILE_SIMD");
    if (!kWideTrilinear || (simd && std::strcmp(simd, "avx2") == 0)) return false;
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") != 0;
}();

namespace {

/// Axis `axis` of eight points (x, y, z of each) as lanes, from the points' scalars (a vector
/// load over eight separate stores would wait for them).
__m256 lanes(const float* xyz, int axis) {
    return _mm256_setr_ps(xyz[axis], xyz[3 + axis], xyz[6 + axis], xyz[9 + axis], xyz[12 + axis],
                          xyz[15 + axis], xyz[18 + axis], xyz[21 + axis]);
}

/// detail::bsplineWeights and bsplineDerivativeWeights of the fractions `a`, lane by lane, the
/// same operations in the same order.
struct CubicWeights8 {
    __m256 w[4];
};

CubicWeights8 bsplineWeights8(__m256 a) {
    const __m256 one = _mm256_set1_ps(1.0f), three = _mm256_set1_ps(3.0f);
    const __m256 six = _mm256_set1_ps(6.0f);
    const __m256 b = _mm256_sub_ps(one, a);
    const auto times = [](__m256 u, __m256 v) { return _mm256_mul_ps(u, v); };
    const auto plus = [](__m256 u, __m256 v) { return _mm256_add_ps(u, v); };
    return {{_mm256_div_ps(times(times(b, b), b), six),
             _mm256_div_ps(plus(times(times(_mm256_sub_ps(times(three, a), six), a), a),
                                _mm256_set1_ps(4.0f)),
                           six),
             _mm256_div_ps(
                 plus(times(plus(times(plus(times(_mm256_set1_ps(-3.0f), a), three), a), three), a),
                      one),
                 six),
             _mm256_div_ps(times(times(a, a), a), six)}};
}

CubicWeights8 bsplineDerivativeWeights8(__m256 a) {
    const __m256 half = _mm256_set1_ps(0.5f), three = _mm256_set1_ps(3.0f);
    const __m256 b = _mm256_sub_ps(_mm256_set1_ps(1.0f), a);
    const auto times = [](__m256 u, __m256 v) { return _mm256_mul_ps(u, v); };
    return {{times(times(_mm256_set1_ps(-0.5f), b), b),
             times(times(half, a), _mm256_sub_ps(times(three, a), _mm256_set1_ps(4.0f))),
             times(times(half, b), _mm256_add_ps(times(three, a), _mm256_set1_ps(1.0f))),
             times(times(half, a), a)}};
}

}  // namespace

unsigned trilinearColumns8(const WideColumns& columns, const float* xyz, float* out) {
    Lanes8::M outside = _mm256_setzero_ps();
    _mm256_storeu_ps(out, trilinearColumnsLanes<Lanes8>(columns, lanes(xyz, 0), lanes(xyz, 1),
                                                        lanes(xyz, 2), outside));
    const unsigned unknown = Lanes8::bits(outside);
    Lanes8::leave();
    return unknown;
}

unsigned tricubicGradientColumns8(const WideColumns& columns, const float* xyz, float* gradients) {
    // The axes (detail::periodicCubicAxis, extendedCubicAxis): taps x, y at lower - 1 .. upper
    // + 1 wrapped; z taps firstTap .. firstTap + 3, all stored for the lanes taken here.
    Lanes8::M outside = _mm256_setzero_ps();
    __m256i xTap[4], yTap[4];
    const __m256 fx =
        periodicAxisLanes<Lanes8>(lanes(xyz, 0), columns.width, xTap[1], xTap[2], outside);
    const __m256 fy =
        periodicAxisLanes<Lanes8>(lanes(xyz, 1), columns.height, yTap[1], yTap[2], outside);
    const auto outerTaps = [](__m256i tap[4], int extent) {
        const __m256i zero = _mm256_setzero_si256();
        const __m256i extentLanes = _mm256_set1_epi32(extent);
        const __m256i one = _mm256_set1_epi32(1);
        // lower == 0 ? extent - 1 : lower - 1;  upper + 1 == extent ? 0 : upper + 1
        tap[0] = _mm256_add_epi32(_mm256_sub_epi32(tap[1], one),
                                  _mm256_and_si256(_mm256_cmpeq_epi32(tap[1], zero), extentLanes));
        const __m256i next = _mm256_add_epi32(tap[2], one);
        tap[3] = _mm256_andnot_si256(_mm256_cmpeq_epi32(next, extentLanes), next);
    };
    outerTaps(xTap, columns.width);
    outerTaps(yTap, columns.height);
    const __m256 zShifted = clampedSliceCoordinateLanes<Lanes8>(lanes(xyz, 2), columns.depth);
    const __m256 zFloor = floorFiniteLanes<Lanes8>(zShifted);
    const __m256 fz = _mm256_sub_ps(zShifted, zFloor);
    const __m256i firstTap = _mm256_sub_epi32(_mm256_cvttps_epi32(zFloor), _mm256_set1_epi32(1));
    // Ghost taps (firstTap < 0 or firstTap + 3 >= D): left to the scalar filter.
    outside = Lanes8::either(
        outside, Lanes8::either(Lanes8::greater(_mm256_setzero_si256(), firstTap),
                                Lanes8::greater(_mm256_add_epi32(firstTap, _mm256_set1_epi32(3)),
                                                _mm256_set1_epi32(columns.depth - 1))));
    const CubicWeights8 wx = bsplineWeights8(fx), wy = bsplineWeights8(fy),
                        wz = bsplineWeights8(fz);
    const CubicWeights8 dx = bsplineDerivativeWeights8(fx), dy = bsplineDerivativeWeights8(fy),
                        dz = bsplineDerivativeWeights8(fz);
    // detail::gradientOfTaps' sums, per lane in its order: per slice k, rows j of columns i.
    const __m256i columnStride = _mm256_set1_epi32(columns.depth);
    const __m256i rowStride = _mm256_set1_epi32(columns.width * columns.depth);
    __m256i xStart[4], yStart[4];
    for (int i = 0; i < 4; ++i) {
        xStart[i] = _mm256_mullo_epi32(Lanes8::zeroWhere(outside, xTap[i]), columnStride);
        yStart[i] = _mm256_add_epi32(
            _mm256_mullo_epi32(Lanes8::zeroWhere(outside, yTap[i]), rowStride),
            Lanes8::zeroWhere(outside, firstTap));
    }
    const __m256 scale = _mm256_set1_ps(columns.texelsPerCode);
    const int* base = reinterpret_cast<const int*>(columns.codes);
    const __m256 zero = _mm256_setzero_ps();
    __m256 value[4], xDerivative[4], yDerivative[4];
    for (int k = 0; k < 4; ++k) value[k] = xDerivative[k] = yDerivative[k] = zero;
    for (int j = 0; j < 4; ++j) {
        __m256 rowValue[4], rowDerivative[4];
        for (int k = 0; k < 4; ++k) rowValue[k] = rowDerivative[k] = zero;
        for (int i = 0; i < 4; ++i) {
            const __m256i element = _mm256_add_epi32(xStart[i], yStart[j]);
            const __m256i low = _mm256_i32gather_epi32(base, element, 2);  // slices 0, 1
            const __m256i high =
                _mm256_i32gather_epi32(base, _mm256_add_epi32(element, _mm256_set1_epi32(2)), 2);
            const __m256 texel[4] = {
                _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srai_epi32(_mm256_slli_epi32(low, 16), 16)),
                              scale),
                _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srai_epi32(low, 16)), scale),
                _mm256_mul_ps(
                    _mm256_cvtepi32_ps(_mm256_srai_epi32(_mm256_slli_epi32(high, 16), 16)), scale),
                _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srai_epi32(high, 16)), scale)};
            for (int k = 0; k < 4; ++k) {
                rowValue[k] = _mm256_add_ps(rowValue[k], _mm256_mul_ps(wx.w[i], texel[k]));
                rowDerivative[k] =
                    _mm256_add_ps(rowDerivative[k], _mm256_mul_ps(dx.w[i], texel[k]));
            }
        }
        for (int k = 0; k < 4; ++k) {
            value[k] = _mm256_add_ps(value[k], _mm256_mul_ps(wy.w[j], rowValue[k]));
            xDerivative[k] =
                _mm256_add_ps(xDerivative[k], _mm256_mul_ps(wy.w[j], rowDerivative[k]));
            yDerivative[k] = _mm256_add_ps(yDerivative[k], _mm256_mul_ps(dy.w[j], rowValue[k]));
        }
    }
    __m256 sumX = zero, sumY = zero, sumZ = zero;
    for (int k = 0; k < 4; ++k) {
        sumX = _mm256_add_ps(sumX, _mm256_mul_ps(wz.w[k], xDerivative[k]));
        sumY = _mm256_add_ps(sumY, _mm256_mul_ps(wz.w[k], yDerivative[k]));
        sumZ = _mm256_add_ps(sumZ, _mm256_mul_ps(dz.w[k], value[k]));
    }
    alignas(32) float gx[8], gy[8], gz[8];
    _mm256_store_ps(gx, sumX);
    _mm256_store_ps(gy, sumY);
    _mm256_store_ps(gz, sumZ);
    for (int lane = 0; lane < 8; ++lane) {
        gradients[3 * lane] = gx[lane];
        gradients[3 * lane + 1] = gy[lane];
        gradients[3 * lane + 2] = gz[lane];
    }
    const unsigned redo = Lanes8::bits(outside);
    Lanes8::leave();
    return redo;
}

#else

const bool kWideTrilinear = false;
const bool kSixteenLanes = false;

unsigned tricubicGradientColumns8(const WideColumns&, const float*, float*) {
    return 0xffu;
}

unsigned trilinearColumns8(const WideColumns&, const float*, float*) {
    return 0xffu;
}

#endif

}  // namespace distile::detail
