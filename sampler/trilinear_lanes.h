/// @file
/// The body of the wide trilinear filter (sampler/trilinear_wide.h) over SIMD lanes
/// (sampler/simd_lanes.h: Lanes8 with AVX2, Lanes16 with AVX-512), for translation units built
/// with those instruction sets and without FMA only (sampler/trilinear_wide.cpp,
/// render/march_wide*.cpp). Internal linkage, as simd_lanes.h.
#pragma once

#include "sampler/simd_lanes.h"
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
[[gnu::always_inline]] inline typename V::F periodicAxisLanes(typename V::F coordinates,
                                                              int extent, typename V::I& lower,
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
                                                                  typename V::F x,
                                                                  typename V::F y,
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

}  // namespace
}  // namespace distile::detail
