/// @file
/// Third-order reconstruction filters over a distance tile (GPU Gems 2, ch. 20): the cubic
/// B-spline (approximating, C2: continuous gradient and Hessian, for shading normals and
/// curvature) and Catmull-Rom (interpolating: it returns the stored texels at texel centres).
/// Same texel space and addressing as TrilinearFilter: periodic in x and y; in z the taps beyond
/// the first and last slice are linear ghost texels (tap -1 = 2 v0 - v1, tap -2 = 3 v0 - 2 v1, and
/// alike above the last slice), so both filters reproduce fields linear in z up to the faces
/// z = 0 and z = D, and positions beyond the faces take the value at the face. Distances are in
/// texels, gradients in texels per texel, Hessians in 1/texel, curvatures in 1/texel.
///
/// The B-spline is evaluated in the chapter's "8 trilinear fetches" form: on each axis the four
/// tap weights form two same-sign pairs, and each pair is one linear fetch at the pair's weighted
/// position, so the 64-tap tensor-product sum becomes 8 TrilinearFilter::fetch calls (24 for the
/// gradient8Fetch, 60 for the Hessian). distanceTexels64Tap() is the plain sum, kept as the
/// reference; the gradient is computed from the 64 taps directly (faster on a CPU).
///
/// Note: the B-spline smooths. It reproduces linear functions, and quadratics up to a constant,
/// but on a distance field it may overestimate distances (by about Laplacian / 6 texels), so the
/// march keeps trilinear distances and uses this filter for normals and curvature.
#pragma once

#include <algorithm>
#include <cassert>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "sampler/filters.h"
#include "sampler/tile.h"

namespace distile {

namespace detail {

/// The four taps of a cubic filter on one axis, at offsets -1, 0, +1, +2 from the lower
/// neighbour of the position, and the fraction of the position from tap 1 toward tap 2, in
/// [0, 1). On a periodic axis (x, y) `tap` holds the taps' wrapped texel indices. On the extended
/// axis (z) the taps have slice indices firstTap .. firstTap + 3, from -2 to D + 1: those outside
/// [0, slices) are ghost texels on the line through the edge cell's two slices, and `tap` holds
/// the (up to 4) consecutive stored slices the taps are made of (storedTapWeights() maps tap
/// weights onto them; linearFetch() gives a pair of neighbouring taps as one linear fetch).
struct CubicAxis {
    int tap[4];
    float fraction;
    int firstTap = 0;  ///< extended axis: slice index of tap 0 (-2 .. D - 2)
    int slices = 0;    ///< extended axis: the tile depth D; 0 on a periodic axis
};

/// Periodic axis of `extent` texels (x, y), reusing the trilinear filter's wrap.
inline CubicAxis periodicCubicAxis(float position, int extent) {
    const AxisLerp middle = periodicAxis(position, extent);
    return {{middle.lower == 0 ? extent - 1 : middle.lower - 1, middle.lower, middle.upper,
             middle.upper + 1 == extent ? 0 : middle.upper + 1},
            middle.weight};
}

/// Extended axis of `extent` slices (z), as TrilinearFilter's extendedAxis: positions are clamped
/// to the faces [0, extent] (NaN to 0), taps beyond the slab are linear ghost texels.
/// Precondition: extent >= 2.
inline CubicAxis extendedCubicAxis(float position, int extent) {
    const float shifted = clampedSliceCoordinate(position, extent);
    const float floorValue = floorFinite(shifted);
    const int firstTap = int(floorValue) - 1;
    // Four consecutive stored slices covering the real taps and the edge cell of the ghost taps.
    const int firstStored = std::clamp(firstTap, 0, std::max(extent - 4, 0));
    CubicAxis axis{{}, shifted - floorValue, firstTap, extent};
    for (int k = 0; k < 4; ++k) axis.tap[k] = std::min(firstStored + k, extent - 1);
    return axis;
}

/// Weights of the four taps at fraction `a`, for the filter value or one of its derivatives
/// along the axis (derivative weights sum to zero).
struct CubicWeights {
    float w[4];
};

inline CubicWeights bsplineWeights(float a) {
    const float b = 1.0f - a;
    return {{b * b * b / 6.0f, ((3.0f * a - 6.0f) * a * a + 4.0f) / 6.0f,
             (((-3.0f * a + 3.0f) * a + 3.0f) * a + 1.0f) / 6.0f, a * a * a / 6.0f}};
}

inline CubicWeights bsplineDerivativeWeights(float a) {
    const float b = 1.0f - a;
    return {
        {-0.5f * b * b, 0.5f * a * (3.0f * a - 4.0f), 0.5f * b * (3.0f * a + 1.0f), 0.5f * a * a}};
}

inline CubicWeights catmullRomWeights(float a) {
    return {{0.5f * ((-a + 2.0f) * a - 1.0f) * a, 0.5f * ((3.0f * a - 5.0f) * a * a + 2.0f),
             0.5f * (((-3.0f * a + 4.0f) * a + 1.0f) * a), 0.5f * (a - 1.0f) * a * a}};
}

inline CubicWeights catmullRomDerivativeWeights(float a) {
    return {{0.5f * ((-3.0f * a + 4.0f) * a - 1.0f), 0.5f * (9.0f * a - 10.0f) * a,
             0.5f * ((-9.0f * a + 8.0f) * a + 1.0f), 0.5f * (3.0f * a - 2.0f) * a}};
}

/// Weights on the stored texels `axis.tap` equivalent to `weights` on the axis' four taps: the
/// same on a periodic axis; on the extended axis a ghost tap's weight goes to its edge cell's two
/// slices (tap -1 = 2 v0 - v1 etc.). Sums over the taps then read stored texels only.
inline CubicWeights storedTapWeights(const CubicAxis& axis, const CubicWeights& weights) {
    // A periodic axis, or all four taps stored (away from the faces): the weights as they are.
    if (axis.slices == 0 || (axis.firstTap >= 0 && axis.firstTap + 3 < axis.slices)) return weights;
    CubicWeights stored{};
    const int firstStored = axis.tap[0];
    for (int k = 0; k < 4; ++k) {
        const int slice = axis.firstTap + k;
        if (slice >= 0 && slice < axis.slices) {
            stored.w[slice - firstStored] += weights.w[k];
            continue;
        }
        // A ghost: the edge cell's line at `beyond` slices from its lower slice.
        const int cell = slice < 0 ? 0 : axis.slices - 2;
        const float beyond = float(slice - cell);
        stored.w[cell - firstStored] += weights.w[k] * (1.0f - beyond);
        stored.w[cell + 1 - firstStored] += weights.w[k] * beyond;
    }
    return stored;
}

/// One linear fetch between taps `k` and `k + 1` of `axis` at `weight` in [0, 1] toward tap
/// k + 1. On the extended axis a pair with a ghost tap lies on its edge cell's line: the fetch is
/// on that cell with the weight extended (e.g. between taps -1 and 0 at weight t: the cell of
/// slices 0 and 1 at weight t - 1).
inline AxisLerp linearFetch(const CubicAxis& axis, int k, float weight) {
    if (axis.slices == 0) return {axis.tap[k], axis.tap[k + 1], weight};
    const int slice = axis.firstTap + k;
    const int cell = std::clamp(slice, 0, axis.slices - 2);
    return {cell, cell + 1, float(slice - cell) + weight};
}

/// The linear fetches that replace the four taps on one axis, with their weights.
struct LinearFetches {
    AxisLerp fetch[3];
    float weight[3];
    int count;
};

/// Two fetches for weights that form same-sign pairs (w0, w1) and (w2, w3), as the cubic
/// B-spline's and its first derivative's do: w0 f0 + w1 f1 = (w0 + w1) lerp(f0, f1, w1 / (w0 +
/// w1)). Precondition: neither pair sums to zero (true for those weights on [0, 1]).
inline LinearFetches pairedFetches(const CubicAxis& axis, const CubicWeights& weights) {
    const float low = weights.w[0] + weights.w[1];
    const float high = weights.w[2] + weights.w[3];
    assert(low != 0.0f && high != 0.0f);
    return {
        {linearFetch(axis, 0, weights.w[1] / low), linearFetch(axis, 2, weights.w[3] / high), {}},
        {low, high, 0.0f},
        2};
}

/// Three fetches for the B-spline's second derivative, whose weights (1 - a, 3a - 2, 1 - 3a, a)
/// are the (1, -2, 1) difference of linear fetches one texel apart.
inline LinearFetches secondDerivativeFetches(const CubicAxis& axis) {
    const float a = axis.fraction;
    return {{linearFetch(axis, 0, a), linearFetch(axis, 1, a), linearFetch(axis, 2, a)},
            {1.0f, -2.0f, 1.0f},
            3};
}

/// The weighted sum of the fetches' tensor product: one filter output from linear fetches.
template <class Linear>
float sumOfFetches(const Linear& linear, const LinearFetches& x, const LinearFetches& y,
                   const LinearFetches& z) {
    float sum = 0.0f;
    for (int k = 0; k < z.count; ++k) {
        float plane = 0.0f;
        for (int j = 0; j < y.count; ++j) {
            float row = 0.0f;
            for (int i = 0; i < x.count; ++i)
                row += x.weight[i] * linear.fetch(x.fetch[i], y.fetch[j], z.fetch[k]);
            plane += y.weight[j] * row;
        }
        sum += z.weight[k] * plane;
    }
    return sum;
}

/// The plain 4 x 4 x 4 tensor-product sum of the taps with per-axis weights (64 reads, column by
/// column; the z weights are per tap, ghost taps included, and read through storedTapWeights).
template <class Texels>
float sumOfTaps(const Texels& texels, const CubicAxis& x, const CubicAxis& y, const CubicAxis& z,
                const CubicWeights& wx, const CubicWeights& wy, const CubicWeights& tapWeightsZ) {
    const CubicWeights wz = storedTapWeights(z, tapWeightsZ);
    std::size_t slices[4];
    for (int k = 0; k < 4; ++k) slices[k] = std::size_t(z.tap[k]) * texels.zStride();
    float sum = 0.0f;
    for (int j = 0; j < 4; ++j) {
        for (int i = 0; i < 4; ++i) {
            const std::size_t column = texels.column(x.tap[i], y.tap[j]);
            float columnSum = 0.0f;
            for (int k = 0; k < 4; ++k) columnSum += wz.w[k] * texels[column + slices[k]];
            sum += wx.w[i] * wy.w[j] * columnSum;
        }
    }
    return sum;
}

/// The gradient of a cubic filter in one pass over its 64 taps: value weights `w*` and derivative
/// weights `d*` per axis. Factored by z tap: per stored slice k, each row j of four columns is
/// summed with the x weights (value and derivative), the rows with the y weights, then the z
/// weights are applied once. Where z is contiguous (ColumnTexels) the four slices of a column are
/// one SSE load, with the same operations per lane as the scalar path, so the same result.
template <class Texels>
glm::vec3 gradientOfTaps(const Texels& texels, const CubicAxis& x, const CubicAxis& y,
                         const CubicAxis& z, const CubicWeights& wx, const CubicWeights& wy,
                         const CubicWeights& tapWeightsZ, const CubicWeights& dx,
                         const CubicWeights& dy, const CubicWeights& tapDerivativesZ) {
    const CubicWeights wz = storedTapWeights(z, tapWeightsZ);
    const CubicWeights dz = storedTapWeights(z, tapDerivativesZ);
    alignas(16) float value[4];        // per slice: sum over j of wy_j (sum over i of wx_i texel)
    alignas(16) float xDerivative[4];  // wy_j (dx_i texel)
    alignas(16) float yDerivative[4];  // dy_j (wx_i texel)
    bool summed = false;
#if defined(__SSE2__)
    if constexpr (Texels::kZContiguous) {
        if (z.tap[3] == z.tap[0] + 3) {
            const std::int16_t* codes = texels.codes() + z.tap[0];
            const __m128 scale = _mm_set1_ps(texels.texelsPerCode());
            __m128 valueSum = _mm_setzero_ps(), xSum = _mm_setzero_ps(), ySum = _mm_setzero_ps();
            for (int j = 0; j < 4; ++j) {
                __m128 rowValue = _mm_setzero_ps(), rowDerivative = _mm_setzero_ps();
                for (int i = 0; i < 4; ++i) {
                    const __m128 column =
                        texelsOfCodes(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(
                                          codes + texels.column(x.tap[i], y.tap[j]))),
                                      scale);
                    rowValue = _mm_add_ps(rowValue, _mm_mul_ps(_mm_set1_ps(wx.w[i]), column));
                    rowDerivative =
                        _mm_add_ps(rowDerivative, _mm_mul_ps(_mm_set1_ps(dx.w[i]), column));
                }
                valueSum = _mm_add_ps(valueSum, _mm_mul_ps(_mm_set1_ps(wy.w[j]), rowValue));
                xSum = _mm_add_ps(xSum, _mm_mul_ps(_mm_set1_ps(wy.w[j]), rowDerivative));
                ySum = _mm_add_ps(ySum, _mm_mul_ps(_mm_set1_ps(dy.w[j]), rowValue));
            }
            _mm_store_ps(value, valueSum);
            _mm_store_ps(xDerivative, xSum);
            _mm_store_ps(yDerivative, ySum);
            summed = true;
        }
    }
#endif
    if (!summed) {
        std::size_t slices[4];
        for (int k = 0; k < 4; ++k) slices[k] = std::size_t(z.tap[k]) * texels.zStride();
        for (int k = 0; k < 4; ++k) {
            value[k] = xDerivative[k] = yDerivative[k] = 0.0f;
            for (int j = 0; j < 4; ++j) {
                float rowValue = 0.0f, rowDerivative = 0.0f;
                for (int i = 0; i < 4; ++i) {
                    const float texel = texels[texels.column(x.tap[i], y.tap[j]) + slices[k]];
                    rowValue += wx.w[i] * texel;
                    rowDerivative += dx.w[i] * texel;
                }
                value[k] += wy.w[j] * rowValue;
                xDerivative[k] += wy.w[j] * rowDerivative;
                yDerivative[k] += dy.w[j] * rowValue;
            }
        }
    }
    glm::vec3 sum(0.0f);
    for (int k = 0; k < 4; ++k) {
        sum.x += wz.w[k] * xDerivative[k];
        sum.y += wz.w[k] * yDerivative[k];
        sum.z += dz.w[k] * value[k];
    }
    return sum;
}

}  // namespace detail

/// Cubic B-spline reconstruction (approximating, C2), evaluated from trilinear fetches.
template <class Texels>
class BasicTricubicBSplineFilter {
  public:
    /// Precondition: the texels outlive the filter (validated tiles have every extent >= 2).
    explicit BasicTricubicBSplineFilter(const Texels& texels) : texels_(texels), linear_(texels) {}

    /// Filtered distance, texels, at a texel-space point: 8 trilinear fetches. Any finite point.
    float distanceTexels(const glm::vec3& texelPosition) const {
        const Axes a = axes(texelPosition);
        return detail::sumOfFetches(linear_, value(a.x), value(a.y), value(a.z));
    }

    /// The same value as the plain 64-tap weighted sum: the reference for distanceTexels().
    float distanceTexels64Tap(const glm::vec3& texelPosition) const {
        const Axes a = axes(texelPosition);
        return detail::sumOfTaps(texels_, a.x, a.y, a.z, detail::bsplineWeights(a.x.fraction),
                                 detail::bsplineWeights(a.y.fraction),
                                 detail::bsplineWeights(a.z.fraction));
    }

    /// Exact first derivatives of the filtered field (texels per texel), continuous everywhere,
    /// in one pass over the 64 taps: on a CPU that is about 4x faster than the chapter's 24 linear
    /// fetches (bench/micro_bench.cpp: sampleGradient), which pay off only where the hardware
    /// filters for free. gradient8Fetch() is the chapter's form, kept as the check.
    glm::vec3 gradient(const glm::vec3& texelPosition) const {
        const Axes a = axes(texelPosition);
        return detail::gradientOfTaps(texels_, a.x, a.y, a.z, detail::bsplineWeights(a.x.fraction),
                                      detail::bsplineWeights(a.y.fraction),
                                      detail::bsplineWeights(a.z.fraction),
                                      detail::bsplineDerivativeWeights(a.x.fraction),
                                      detail::bsplineDerivativeWeights(a.y.fraction),
                                      detail::bsplineDerivativeWeights(a.z.fraction));
    }

    /// Points per gradients() call.
    static constexpr int kGroupedGradients = 16;

    /// gradient() at the first `count` (1 .. kGroupedGradients) of the kGroupedGradients points
    /// `positions` into out[0 .. count), bit for bit; the points past `count` must be finite (a
    /// copy of the first, say) and `out` must have room for all. Over TileColumns on a processor
    /// with AVX2 the points' weights and taps are in SIMD lanes, sixteen (AVX-512) or eight at a
    /// time (sampler/trilinear_wide.h; points within 1.5 texels of a face, or far out, one at a
    /// time); else one at a time.
    void gradients(const glm::vec3* positions, int count, glm::vec3* out) const {
        unsigned redo = (1u << count) - 1u;
        if constexpr (Texels::kZContiguous) {
            if (kSimdLevel >= SimdLevel::Avx2) {
                redo = detail::tricubicGradientColumns(texels_.wide(), &positions[0].x, count,
                                                       &out[0].x);
            }
        }
        for (int lane = 0; lane < count; ++lane)
            if (redo & (1u << lane)) out[lane] = gradient(positions[lane]);
    }

    /// The same gradient from 24 trilinear fetches (8 per component, the derivative weights on
    /// its own axis), as ch. 20 evaluates it on a GPU.
    glm::vec3 gradient8Fetch(const glm::vec3& texelPosition) const {
        const Axes a = axes(texelPosition);
        const detail::LinearFetches vx = value(a.x), vy = value(a.y), vz = value(a.z);
        const detail::LinearFetches dx = derivative(a.x), dy = derivative(a.y),
                                    dz = derivative(a.z);
        return {detail::sumOfFetches(linear_, dx, vy, vz),
                detail::sumOfFetches(linear_, vx, dy, vz),
                detail::sumOfFetches(linear_, vx, vy, dz)};
    }

    /// Exact second derivatives of the filtered field (1/texel), symmetric, continuous: mixed
    /// terms from first-derivative fetches on two axes (8 fetches each), diagonal terms from the
    /// (1, -2, 1) form on their axis (12 fetches each).
    glm::mat3 hessian(const glm::vec3& texelPosition) const {
        const Axes a = axes(texelPosition);
        const detail::LinearFetches vx = value(a.x), vy = value(a.y), vz = value(a.z);
        const detail::LinearFetches dx = derivative(a.x), dy = derivative(a.y),
                                    dz = derivative(a.z);
        const float xx =
            detail::sumOfFetches(linear_, detail::secondDerivativeFetches(a.x), vy, vz);
        const float yy =
            detail::sumOfFetches(linear_, vx, detail::secondDerivativeFetches(a.y), vz);
        const float zz =
            detail::sumOfFetches(linear_, vx, vy, detail::secondDerivativeFetches(a.z));
        const float xy = detail::sumOfFetches(linear_, dx, dy, vz);
        const float xz = detail::sumOfFetches(linear_, dx, vy, dz);
        const float yz = detail::sumOfFetches(linear_, vx, dy, dz);
        return glm::mat3(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    }

  private:
    struct Axes {
        detail::CubicAxis x, y, z;
    };

    Axes axes(const glm::vec3& p) const {
        const Size3& size = texels_.size();
        return {detail::periodicCubicAxis(p.x, size.width),
                detail::periodicCubicAxis(p.y, size.height),
                detail::extendedCubicAxis(p.z, size.depth)};
    }
    static detail::LinearFetches value(const detail::CubicAxis& axis) {
        return detail::pairedFetches(axis, detail::bsplineWeights(axis.fraction));
    }
    static detail::LinearFetches derivative(const detail::CubicAxis& axis) {
        return detail::pairedFetches(axis, detail::bsplineDerivativeWeights(axis.fraction));
    }

    Texels texels_;
    BasicTrilinearFilter<Texels> linear_;
};

/// Catmull-Rom reconstruction (interpolating cubic, C1): returns the stored distance at texel
/// centres, reproduces linear functions, may overshoot between texels. Its outer tap weights are
/// negative, so the pairing trick does not apply: it reads the 64 taps directly.
template <class Texels>
class BasicCatmullRomFilter {
  public:
    /// Precondition: the texels outlive the filter.
    explicit BasicCatmullRomFilter(const Texels& texels) : texels_(texels) {}

    /// Interpolated distance, texels, at a texel-space point. Any finite point.
    float distanceTexels(const glm::vec3& texelPosition) const {
        const Axes a = axes(texelPosition);
        return detail::sumOfTaps(texels_, a.x, a.y, a.z, detail::catmullRomWeights(a.x.fraction),
                                 detail::catmullRomWeights(a.y.fraction),
                                 detail::catmullRomWeights(a.z.fraction));
    }

    /// Exact first derivatives of the interpolant (texels per texel), one pass over the 64 taps.
    glm::vec3 gradient(const glm::vec3& texelPosition) const {
        const Axes a = axes(texelPosition);
        return detail::gradientOfTaps(
            texels_, a.x, a.y, a.z, detail::catmullRomWeights(a.x.fraction),
            detail::catmullRomWeights(a.y.fraction), detail::catmullRomWeights(a.z.fraction),
            detail::catmullRomDerivativeWeights(a.x.fraction),
            detail::catmullRomDerivativeWeights(a.y.fraction),
            detail::catmullRomDerivativeWeights(a.z.fraction));
    }

  private:
    struct Axes {
        detail::CubicAxis x, y, z;
    };
    Axes axes(const glm::vec3& p) const {
        const Size3& size = texels_.size();
        return {detail::periodicCubicAxis(p.x, size.width),
                detail::periodicCubicAxis(p.y, size.height),
                detail::extendedCubicAxis(p.z, size.depth)};
    }

    Texels texels_;
};

using TricubicBSplineFilter = BasicTricubicBSplineFilter<TileTexels>;
using CatmullRomFilter = BasicCatmullRomFilter<TileTexels>;

/// Curvatures of the isosurface of a field through a point, 1/texel.
struct Curvature {
    float mean;      ///< (k1 + k2) / 2
    float gaussian;  ///< k1 * k2
};

/// Mean and Gaussian curvature of the isosurface through a point from the field's gradient g and
/// Hessian H there (implicit-surface formulas, Goldman 2005; Kindlmann et al. 2003):
///   mean     = (|g|^2 trace(H) - g^T H g) / (2 |g|^3),
///   gaussian = g^T adj(H) g / |g|^4.
/// Sign convention: the normal is the gradient, pointing out of the material (distances grow
/// outward), and convex material has positive mean curvature: a sphere of radius r gives
/// mean = 1/r, gaussian = 1/r^2; a spherical hole gives mean = -1/r, gaussian = 1/r^2.
/// Precondition: H symmetric. Returns {0, 0} when |g| is zero or not finite (no surface direction).
inline Curvature curvatureFromDerivatives(glm::vec3 gradient, glm::mat3 hessian) {
    const float lengthSquared = glm::dot(gradient, gradient);
    if (!(lengthSquared > 0.0f) || !std::isfinite(lengthSquared)) return {0.0f, 0.0f};
    const float length = std::sqrt(lengthSquared);
    const float trace = hessian[0][0] + hessian[1][1] + hessian[2][2];
    const float normalTerm = glm::dot(gradient, hessian * gradient);
    // Rows of the adjugate of a symmetric matrix: cross products of its columns.
    const glm::vec3 adjugateTimesGradient(glm::dot(glm::cross(hessian[1], hessian[2]), gradient),
                                          glm::dot(glm::cross(hessian[2], hessian[0]), gradient),
                                          glm::dot(glm::cross(hessian[0], hessian[1]), gradient));
    return {(lengthSquared * trace - normalTerm) / (2.0f * lengthSquared * length),
            glm::dot(gradient, adjugateTimesGradient) / (lengthSquared * lengthSquared)};
}

}  // namespace distile
