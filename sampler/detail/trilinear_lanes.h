/// @file
/// The body of the wide trilinear filter (sampler/trilinear_wide.h) over SIMD lanes
/// (sampler/detail/simd_lanes.h: Lanes8 with AVX2, Lanes16 with AVX-512), for translation units
/// built with those instruction sets and without FMA only (sampler/trilinear_wide.cpp,
/// render/march_wide*.cpp). Internal linkage, as simd_lanes.h.
#pragma once

#include "sampler/detail/simd_lanes.h"
#include "sampler/trilinear_wide.h"

namespace distile::detail {
namespace {

/// detail::floorFinite, lane by lane: truncate, then step down where that rounded up.
template <class V>
[[gnu::always_inline]] inline typename V::F floorFiniteLanes(typename V::F value) {
    const typename V::F truncated = V::toFloat(V::truncate(value));
    return V::sub(truncated, V::onlyWhere(V::greater(truncated, value), V::set1(1.0f)));
}

/// detail::periodicAxis in its near case, lane by lane: the lower and upper index and the weight
/// (returned). Lanes outside the near case (huge or not finite, or more than a period away) are
/// added to `outside`; their indices are unspecified.
template <class V>
[[gnu::always_inline]] inline typename V::F periodicAxisLanes(typename V::F coordinates, int extent,
                                                              typename V::I& lower,
                                                              typename V::I& upper,
                                                              typename V::M& outside) {
    using I = typename V::I;
    const I zero = V::set1(0);
    const typename V::F shifted = V::sub(coordinates, V::set1(0.5f));
    outside = V::either(outside, V::notLess(V::abs(shifted), V::set1(1.0e9f)));
    const typename V::F floorValue = floorFiniteLanes<V>(shifted);
    const I extentLanes = V::set1(extent);
    const I last = V::set1(extent - 1);
    I index = V::truncate(floorValue);
    index = V::add(index, V::onlyWhere(V::greater(zero, index), extentLanes));
    index = V::sub(index, V::onlyWhere(V::greater(index, last), extentLanes));
    outside = V::either(outside, V::either(V::greater(zero, index), V::greater(index, last)));
    lower = index;
    const I next = V::add(index, V::set1(1));
    upper = V::zeroWhere(V::equal(next, extentLanes), next);
    return V::sub(shifted, floorValue);
}

/// detail::clampedSliceCoordinate, lane by lane: z - 0.5 clamped to [-0.5, D - 0.5], NaN to -0.5.
template <class V>
[[gnu::always_inline]] inline typename V::F clampedSliceCoordinateLanes(typename V::F z,
                                                                        int depth) {
    const typename V::F firstFace = V::set1(-0.5f);
    const typename V::F lastFace = V::set1(float(depth) - 0.5f);
    typename V::F shifted = V::sub(z, V::set1(0.5f));
    shifted = V::blend(firstFace, shifted, V::greaterEqual(shifted, firstFace));
    return V::blend(lastFace, shifted, V::less(shifted, lastFace));
}

/// The codes of slices z and z + 1 of each lane's column as one 32-bit gather (2-byte elements),
/// as texels (float(code) x texelsPerCode), lerped along z with `zWeight`.
template <class V>
[[gnu::always_inline]] inline typename V::F columnAlongZLanes(const WideColumns& columns,
                                                              typename V::I elements,
                                                              typename V::F zWeight) {
    const typename V::I pairs = V::gatherCodePairs(columns.codes, elements);
    const typename V::F scale = V::set1(columns.texelsPerCode);
    const typename V::F lower = V::mul(V::toFloat(V::lowHalf(pairs)), scale);
    const typename V::F upper = V::mul(V::toFloat(V::highHalf(pairs)), scale);
    return V::add(lower, V::mul(V::sub(upper, lower), zWeight));
}

/// BasicTrilinearFilter<ColumnTexels>::distanceTexels at the points (x, y, z) lane by lane, bit
/// for bit, where `outside` is clear: the lanes periodicAxis does not take in its near case (huge
/// or not finite x or y) are added to `outside`, and lanes already in it read texel 0 and give an
/// unspecified value.
template <class V>
[[gnu::always_inline]] inline typename V::F trilinearColumnsLanes(const WideColumns& columns,
                                                                  typename V::F x, typename V::F y,
                                                                  typename V::F z,
                                                                  typename V::M& outside) {
    using F = typename V::F;
    using I = typename V::I;
    I xLower, xUpper, yLower, yUpper;
    const F xWeight = periodicAxisLanes<V>(x, columns.width, xLower, xUpper, outside);
    const F yWeight = periodicAxisLanes<V>(y, columns.height, yLower, yUpper, outside);
    // detail::extendedAxis: clampedSliceCoordinate (NaN to the first face), then the lower slice
    // clamped to [0, D - 2].
    const F zShifted = clampedSliceCoordinateLanes<V>(z, columns.depth);
    I zLower = V::truncate(floorFiniteLanes<V>(zShifted));
    zLower = V::max(zLower, V::set1(0));
    zLower = V::min(zLower, V::set1(columns.depth - 2));
    const F zWeight = V::sub(zShifted, V::toFloat(zLower));
    // Element of slice zLower in column (x, y): x D + y W D + z (ColumnTexels), in 32 bits (a
    // tile's texel count fits: TileColumns). Outside lanes read texel 0.
    const I columnStride = V::set1(columns.depth);
    const I rowStride = V::set1(columns.width * columns.depth);
    const I xLowerStart = V::mullo(V::zeroWhere(outside, xLower), columnStride);
    const I xUpperStart = V::mullo(V::zeroWhere(outside, xUpper), columnStride);
    const I yLowerStart = V::add(V::mullo(V::zeroWhere(outside, yLower), rowStride), zLower);
    const I yUpperStart = V::add(V::mullo(V::zeroWhere(outside, yUpper), rowStride), zLower);
    const auto lerp = [](F a, F b, F t) { return V::add(a, V::mul(V::sub(b, a), t)); };
    const F rowLower =
        lerp(columnAlongZLanes<V>(columns, V::add(xLowerStart, yLowerStart), zWeight),
             columnAlongZLanes<V>(columns, V::add(xUpperStart, yLowerStart), zWeight), xWeight);
    const F rowUpper =
        lerp(columnAlongZLanes<V>(columns, V::add(xLowerStart, yUpperStart), zWeight),
             columnAlongZLanes<V>(columns, V::add(xUpperStart, yUpperStart), zWeight), xWeight);
    return lerp(rowLower, rowUpper, yWeight);
}

/// detail::bsplineWeights and bsplineDerivativeWeights of the fractions `a`, lane by lane, the
/// same operations in the same order.
template <class V>
struct CubicWeightLanes {
    typename V::F w[4];
};

template <class V>
[[gnu::always_inline]] inline CubicWeightLanes<V> bsplineWeightLanes(typename V::F a) {
    using F = typename V::F;
    const F one = V::set1(1.0f), three = V::set1(3.0f), six = V::set1(6.0f);
    const F b = V::sub(one, a);
    const auto times = [](F u, F v) { return V::mul(u, v); };
    const auto plus = [](F u, F v) { return V::add(u, v); };
    return {
        {V::div(times(times(b, b), b), six),
         V::div(plus(times(times(V::sub(times(three, a), six), a), a), V::set1(4.0f)), six),
         V::div(plus(times(plus(times(plus(times(V::set1(-3.0f), a), three), a), three), a), one),
                six),
         V::div(times(times(a, a), a), six)}};
}

template <class V>
[[gnu::always_inline]] inline CubicWeightLanes<V> bsplineDerivativeWeightLanes(typename V::F a) {
    using F = typename V::F;
    const F half = V::set1(0.5f), three = V::set1(3.0f);
    const F b = V::sub(V::set1(1.0f), a);
    const auto times = [](F u, F v) { return V::mul(u, v); };
    return {{times(times(V::set1(-0.5f), b), b),
             times(times(half, a), V::sub(times(three, a), V::set1(4.0f))),
             times(times(half, b), V::add(times(three, a), V::set1(1.0f))),
             times(times(half, a), a)}};
}

/// BasicTricubicBSplineFilter<ColumnTexels>::gradient at the V::kWidth points `xyz` (x, y, z of
/// each) into `gradients` (the same layout), bit for bit, for the lanes in periodicAxis' near
/// case whose z taps are all stored slices. Returns the other lanes, one bit each (their
/// gradients are unspecified).
template <class V>
inline unsigned tricubicGradientColumnsLanes(const WideColumns& columns, const float* xyz,
                                             float* gradients) {
    using F = typename V::F;
    using I = typename V::I;
    using M = typename V::M;
    // The axes (detail::periodicCubicAxis, extendedCubicAxis): taps x, y at lower - 1 .. upper
    // + 1 wrapped; z taps firstTap .. firstTap + 3, all stored for the lanes taken here.
    M outside = V::uniformMask(false);
    I xTap[4], yTap[4];
    const F fx =
        periodicAxisLanes<V>(V::strided3(xyz, 0), columns.width, xTap[1], xTap[2], outside);
    const F fy =
        periodicAxisLanes<V>(V::strided3(xyz, 1), columns.height, yTap[1], yTap[2], outside);
    const auto outerTaps = [](I tap[4], int extent) {
        const I extentLanes = V::set1(extent);
        const I one = V::set1(1);
        // lower == 0 ? extent - 1 : lower - 1;  upper + 1 == extent ? 0 : upper + 1
        tap[0] =
            V::add(V::sub(tap[1], one), V::onlyWhere(V::equal(tap[1], V::set1(0)), extentLanes));
        const I next = V::add(tap[2], one);
        tap[3] = V::zeroWhere(V::equal(next, extentLanes), next);
    };
    outerTaps(xTap, columns.width);
    outerTaps(yTap, columns.height);
    const F zShifted = clampedSliceCoordinateLanes<V>(V::strided3(xyz, 2), columns.depth);
    const F zFloor = floorFiniteLanes<V>(zShifted);
    const F fz = V::sub(zShifted, zFloor);
    const I firstTap = V::sub(V::truncate(zFloor), V::set1(1));
    // Ghost taps (firstTap < 0 or firstTap + 3 >= D): left to the scalar filter.
    outside = V::either(
        outside, V::either(V::greater(V::set1(0), firstTap),
                           V::greater(V::add(firstTap, V::set1(3)), V::set1(columns.depth - 1))));
    const CubicWeightLanes<V> wx = bsplineWeightLanes<V>(fx), wy = bsplineWeightLanes<V>(fy),
                              wz = bsplineWeightLanes<V>(fz);
    const CubicWeightLanes<V> dx = bsplineDerivativeWeightLanes<V>(fx),
                              dy = bsplineDerivativeWeightLanes<V>(fy),
                              dz = bsplineDerivativeWeightLanes<V>(fz);
    // detail::gradientOfTaps' sums, per lane in its order: per slice k, rows j of columns i.
    const I columnStride = V::set1(columns.depth);
    const I rowStride = V::set1(columns.width * columns.depth);
    I xStart[4], yStart[4];
#pragma GCC unroll 4
    for (int i = 0; i < 4; ++i) {
        xStart[i] = V::mullo(V::zeroWhere(outside, xTap[i]), columnStride);
        yStart[i] = V::add(V::mullo(V::zeroWhere(outside, yTap[i]), rowStride),
                           V::zeroWhere(outside, firstTap));
    }
    const F scale = V::set1(columns.texelsPerCode);
    const F zero = V::set1(0.0f);
    F value[4], xDerivative[4], yDerivative[4];
#pragma GCC unroll 4
    for (int k = 0; k < 4; ++k) value[k] = xDerivative[k] = yDerivative[k] = zero;
#pragma GCC unroll 4
    for (int j = 0; j < 4; ++j) {
        F rowValue[4], rowDerivative[4];
#pragma GCC unroll 4
        for (int k = 0; k < 4; ++k) rowValue[k] = rowDerivative[k] = zero;
#pragma GCC unroll 4
        for (int i = 0; i < 4; ++i) {
            I codes[4];
            V::gatherCodes4(columns.codes, V::add(xStart[i], yStart[j]), codes);
            const F texel[4] = {
                V::mul(V::toFloat(codes[0]), scale), V::mul(V::toFloat(codes[1]), scale),
                V::mul(V::toFloat(codes[2]), scale), V::mul(V::toFloat(codes[3]), scale)};
#pragma GCC unroll 4
            for (int k = 0; k < 4; ++k) {
                rowValue[k] = V::add(rowValue[k], V::mul(wx.w[i], texel[k]));
                rowDerivative[k] = V::add(rowDerivative[k], V::mul(dx.w[i], texel[k]));
            }
        }
#pragma GCC unroll 4
        for (int k = 0; k < 4; ++k) {
            value[k] = V::add(value[k], V::mul(wy.w[j], rowValue[k]));
            xDerivative[k] = V::add(xDerivative[k], V::mul(wy.w[j], rowDerivative[k]));
            yDerivative[k] = V::add(yDerivative[k], V::mul(dy.w[j], rowValue[k]));
        }
    }
    F sumX = zero, sumY = zero, sumZ = zero;
#pragma GCC unroll 4
    for (int k = 0; k < 4; ++k) {
        sumX = V::add(sumX, V::mul(wz.w[k], xDerivative[k]));
        sumY = V::add(sumY, V::mul(wz.w[k], yDerivative[k]));
        sumZ = V::add(sumZ, V::mul(dz.w[k], value[k]));
    }
    alignas(64) float gx[V::kWidth], gy[V::kWidth], gz[V::kWidth];
    V::store(gx, sumX);
    V::store(gy, sumY);
    V::store(gz, sumZ);
    for (int lane = 0; lane < V::kWidth; ++lane) {
        gradients[3 * lane] = gx[lane];
        gradients[3 * lane + 1] = gy[lane];
        gradients[3 * lane + 2] = gz[lane];
    }
    const unsigned redo = V::bits(outside);
    V::leave();
    return redo;
}

}  // namespace
}  // namespace distile::detail
