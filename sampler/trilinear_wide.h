/// @file
/// The trilinear filter over TileColumns at eight points per call with AVX2 (gathers), for the
/// march (sampler/filters.h, BasicTrilinearFilter::distancesTexels8), and the B-spline gradient
/// at eight (AVX2) or sixteen (AVX-512) points. Built in their own translation units with those
/// instruction sets enabled (sampler/trilinear_wide.cpp, trilinear_wide16.cpp) and run only where
/// the processor has them: the rest of distile stays SSE2. No FMA: every lane does the scalar
/// filter's operations, in its order, bit for bit.
#pragma once

#include <cstdint>

#include "common/simd.h"

namespace distile::detail {

/// A tile's columns as the wide kernel reads them (ColumnTexels' fields).
struct WideColumns {
    const std::int16_t* codes;  ///< W x H x D codes, z fastest
    float texelsPerCode;
    int width, height, depth;
};

/// BasicTrilinearFilter<ColumnTexels>::distanceTexels at the eight points `xyz` (x, y, z of
/// each, 24 floats) into out[0..8), bit for bit, for every lane whose x and y are in
/// periodicAxis' near case. Returns the lanes that are not (huge or not finite coordinates; bit i
/// for point i): their out[] is unspecified and must be computed one at a time.
/// Precondition: kSimdLevel >= SimdLevel::Avx2 (common/simd.h).
unsigned trilinearColumns8(const WideColumns& columns, const float* xyz, float* out);

/// BasicTricubicBSplineFilter<ColumnTexels>::gradient at the first `count` (1 .. 16) of the
/// sixteen points `xyz` into `gradients` (x, y, z of each, 48 floats in and out; the points past
/// `count` finite), bit for bit, for every point whose x and y are in periodicAxis' near case and
/// whose z taps are all stored slices (z - 0.5 in [1, D - 2)): sixteen at a time where
/// kSimdLevel is Avx512, else eight. Returns the other points among the first `count` (bit i for
/// point i): their gradients are unspecified and must be computed one at a time. Precondition:
/// kSimdLevel >= SimdLevel::Avx2.
unsigned tricubicGradientColumns(const WideColumns& columns, const float* xyz, int count,
                                 float* gradients);

/// tricubicGradientColumns for all sixteen points with AVX-512 (sampler/trilinear_wide16.cpp),
/// which it calls where kSimdLevel is Avx512. Precondition: kSimdLevel == SimdLevel::Avx512.
unsigned tricubicGradientColumns16(const WideColumns& columns, const float* xyz, float* gradients);

}  // namespace distile::detail
