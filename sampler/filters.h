/// @file
/// Reconstruction filters over a distance tile, in texel space: periodic in x and y; in z the
/// edge cells extend linearly over the outer half texels (z in [0, 0.5] and [D - 0.5, D]) up to
/// the faces z = 0 and z = D, and positions beyond the slab take the value at the face. So a field
/// linear in z is reproduced up to the faces instead of being held at the first/last slice's
/// value (which erred by up to half a texel times the slope). Positions are texel-space points
/// (texel centres at i + 0.5); results are distances in texels and gradients in texels per texel
/// (unit length near the surface of an exact distance field).
///
/// Filters are small value types holding a reference to the tile, meant to be passed as template
/// arguments to the tracer (no virtual call per sample).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/vec3.hpp>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "common/simd.h"
#include "sampler/tile.h"
#include "sampler/tile_columns.h"
#include "sampler/trilinear_wide.h"

namespace distile {

namespace detail {

/// Integer texel index and fraction for a coordinate on an axis of `extent` texels: the sample at
/// `position` lies between texels `lower` and `upper` at fraction `weight` from `lower`. The
/// weight is in [0, 1] except on z in the outer half texels, where it extends the edge cell
/// linearly (down to -0.5 at z = 0, up to 1.5 at z = D; the cubic filters' ghost taps reach -2
/// and 3).
struct AxisLerp {
    int lower;
    int upper;
    float weight;
};

inline int wrapIndex(int index, int extent) {
    const int wrapped = index % extent;
    return wrapped < 0 ? wrapped + extent : wrapped;
}

/// `index` wrapped into [0, extent), cheap when it is at most one period outside (the march's
/// case: positions stay near the tile), exact for any index.
inline int wrapNearIndex(int index, int extent) {
    if (index < 0) index += extent;
    if (index >= extent) index -= extent;
    return unsigned(index) < unsigned(extent) ? index : wrapIndex(index, extent);
}

/// floor(value) for finite |value| < 2^31 without a library call (SSE2 has no rounding
/// instruction): truncate, then step down for negative non-integers.
inline float floorFinite(float value) {
    const float truncated = float(int(value));
    return truncated > value ? truncated - 1.0f : truncated;
}

inline AxisLerp periodicAxis(float position, int extent) {
    const float shifted = position - 0.5f;
    if (!(std::abs(shifted) < 1.0e9f)) {
        // Huge or not finite: wrap in floating point first so far repeats keep their fraction.
        const float floorValue = std::floor(shifted);
        const float wrappedFloor =
            floorValue - float(extent) * std::floor(floorValue / float(extent));
        const int lower = wrapIndex(int(wrappedFloor), extent);
        return {lower, lower + 1 == extent ? 0 : lower + 1, shifted - floorValue};
    }
    const float floorValue = floorFinite(shifted);
    const int lower = wrapNearIndex(int(floorValue), extent);
    return {lower, lower + 1 == extent ? 0 : lower + 1, shifted - floorValue};
}

/// `position` - 0.5 clamped to [-0.5, extent - 0.5] (NaN to -0.5): the z coordinate of the
/// extended axes in units of slices from the first slice's centre.
inline float clampedSliceCoordinate(float position, int extent) {
    const float shifted = position - 0.5f;
    if (!(shifted >= -0.5f)) return -0.5f;
    return shifted < float(extent) - 0.5f ? shifted : float(extent) - 0.5f;
}

/// The z axis: the edge cells (slices 0-1 and D-2 to D-1) extend linearly to the faces z = 0 and
/// z = D; positions beyond the faces are clamped to them (NaN to z = 0). Precondition: extent >= 2.
inline AxisLerp extendedAxis(float position, int extent) {
    const float shifted = clampedSliceCoordinate(position, extent);
    const int lower = std::clamp(int(floorFinite(shifted)), 0, extent - 2);
    return {lower, lower + 1, shifted - float(lower)};
}

}  // namespace detail

/// Where filters read texels. TileTexels reads a Tile in its own layout (x fastest); ColumnTexels
/// reads TileColumns (z fastest), the renderer's faster layout. Texel (x, y, z) is element
/// column(x, y) + z * zStride(). Same values, so a filter gives the same results over either
/// (up to the order of its sums). Both hold a pointer: the tile or columns must outlive them.
class TileTexels {
  public:
    /// Implicit, so the filters over tiles construct from a Tile.
    TileTexels(const Tile& tile) : data_(tile.distancesTexels().data()), size_(tile.size()) {}
    const Size3& size() const { return size_; }
    std::size_t column(int x, int y) const {
        return std::size_t(x) + std::size_t(size_.width) * std::size_t(y);
    }
    std::size_t zStride() const { return std::size_t(size_.width) * std::size_t(size_.height); }
    static constexpr bool kZContiguous = false;
    float operator[](std::size_t element) const { return data_[element]; }

  private:
    const float* data_;
    Size3 size_;
};

class ColumnTexels {
  public:
    /// Implicit, so the filters over columns construct from TileColumns.
    ColumnTexels(const TileColumns& columns)
        : codes_(columns.codes()), texelsPerCode_(columns.texelsPerCode()), size_(columns.size()) {}
    const Size3& size() const { return size_; }
    std::size_t column(int x, int y) const {
        return (std::size_t(x) + std::size_t(size_.width) * std::size_t(y)) *
               std::size_t(size_.depth);
    }
    static constexpr std::size_t zStride() { return 1; }
    /// Slices z and z + 1 of a column are adjacent: the filters load them as pairs (SSE2).
    static constexpr bool kZContiguous = true;
    float operator[](std::size_t element) const { return float(codes_[element]) * texelsPerCode_; }
    const std::int16_t* codes() const { return codes_; }
    float texelsPerCode() const { return texelsPerCode_; }
    /// The same columns as the wide (AVX2, AVX-512) kernels read them (sampler/trilinear_wide.h).
    detail::WideColumns wide() const {
        return {codes_, texelsPerCode_, size_.width, size_.height, size_.depth};
    }

  private:
    const std::int16_t* codes_;
    float texelsPerCode_;
    Size3 size_;
};

#if defined(__SSE2__)
namespace detail {

/// Four 16-bit codes (the low 64 bits of `codes`) as texels: the same float(code) x texelsPerCode
/// as ColumnTexels::operator[], per lane.
inline __m128 texelsOfCodes(__m128i codes, __m128 texelsPerCode) {
    const __m128i widened = _mm_srai_epi32(_mm_unpacklo_epi16(codes, codes), 16);
    return _mm_mul_ps(_mm_cvtepi32_ps(widened), texelsPerCode);
}

}  // namespace detail
#endif

/// Nearest-texel lookup (the reference for "no filtering").
template <class Texels>
class BasicNearestFilter {
  public:
    explicit BasicNearestFilter(const Texels& texels) : texels_(texels) {}

    float distanceTexels(const glm::vec3& texelPosition) const {
        const Size3& size = texels_.size();
        const int x = detail::wrapIndex(int(std::floor(texelPosition.x)), size.width);
        const int y = detail::wrapIndex(int(std::floor(texelPosition.y)), size.height);
        const int z = std::clamp(int(std::floor(texelPosition.z)), 0, size.depth - 1);
        return at(x, y, z);
    }

    /// Central differences of the stored texels around the containing texel (one-sided at the
    /// first and last slice): the gradient of the grid, as a shading normal for this filter.
    glm::vec3 gradient(const glm::vec3& texelPosition) const {
        const Size3& size = texels_.size();
        const int x = detail::wrapIndex(int(std::floor(texelPosition.x)), size.width);
        const int y = detail::wrapIndex(int(std::floor(texelPosition.y)), size.height);
        const int z = std::clamp(int(std::floor(texelPosition.z)), 0, size.depth - 1);
        const int zLow = std::max(z - 1, 0);
        const int zHigh = std::min(z + 1, size.depth - 1);
        return {0.5f * (at(detail::wrapIndex(x + 1, size.width), y, z) -
                        at(detail::wrapIndex(x - 1, size.width), y, z)),
                0.5f * (at(x, detail::wrapIndex(y + 1, size.height), z) -
                        at(x, detail::wrapIndex(y - 1, size.height), z)),
                (at(x, y, zHigh) - at(x, y, zLow)) / float(std::max(zHigh - zLow, 1))};
    }

  private:
    float at(int x, int y, int z) const {
        return texels_[texels_.column(x, y) + std::size_t(z) * texels_.zStride()];
    }

    Texels texels_;
};

/// Trilinear interpolation between the 8 surrounding texel centres, extended linearly in z over
/// the outer half texels. The gradient is the exact derivative of the interpolant (piecewise
/// constant in each axis' own direction); beyond the faces it is the one at the face.
template <class Texels>
class BasicTrilinearFilter {
  public:
    explicit BasicTrilinearFilter(const Texels& texels) : texels_(texels) {}

    const Texels& texels() const { return texels_; }

    float distanceTexels(const glm::vec3& texelPosition) const {
        const Size3& size = texels_.size();
        return fetch(detail::periodicAxis(texelPosition.x, size.width),
                     detail::periodicAxis(texelPosition.y, size.height),
                     detail::extendedAxis(texelPosition.z, size.depth));
    }

    /// distanceTexels() at the four points `positions`, bit for bit; over TileColumns the axis
    /// set-up and the last two lerps are done for the four points at once (SSE2).
    void distancesTexels4(const glm::vec3* positions, float* out) const {
#if defined(__SSE2__)
        if constexpr (Texels::kZContiguous) {
            fetch4(positions, out);
            return;
        }
#endif
        for (int i = 0; i < 4; ++i) out[i] = distanceTexels(positions[i]);
    }

    /// distanceTexels() at the eight points `positions`, bit for bit: over TileColumns on a
    /// processor with AVX2 eight points per instruction (sampler/trilinear_wide.h), else two
    /// distancesTexels4.
    void distancesTexels8(const glm::vec3* positions, float* out) const {
        if constexpr (Texels::kZContiguous) {
            if (kSimdLevel >= SimdLevel::Avx2) {
                const unsigned redo =
                    detail::trilinearColumns8(texels_.wide(), &positions[0].x, out);
                if (redo != 0) {
                    for (int lane = 0; lane < 8; ++lane)
                        if (redo & (1u << lane)) out[lane] = distanceTexels(positions[lane]);
                }
                return;
            }
        }
        distancesTexels4(positions, out);
        distancesTexels4(positions + 4, out + 4);
    }

    /// One linear texture fetch: the trilinear interpolant between the two texels given on each
    /// axis (indices already wrapped or clamped into the tile, weight = fraction toward `upper`;
    /// a z weight outside [0, 1] extrapolates linearly). The building block of the third-order
    /// filters of sampler/tricubic.h. Preconditions: the indices are inside the tile; no checks.
    float fetch(const detail::AxisLerp& x, const detail::AxisLerp& y,
                const detail::AxisLerp& z) const {
        // Along z first (four columns at once where z is contiguous), then x, then y: the same
        // operations in the same order on either layout, so the same result.
        float alongZ[4];
#if defined(__SSE2__)
        if constexpr (Texels::kZContiguous) {
            const std::int16_t* codes = texels_.codes() + z.lower;
            const auto pair = [&](int xIndex, int yIndex) {  // codes of slices z, z + 1
                std::int32_t bits;
                std::memcpy(&bits, codes + texels_.column(xIndex, yIndex), sizeof bits);
                return _mm_cvtsi32_si128(bits);
            };
            const __m128 scale = _mm_set1_ps(texels_.texelsPerCode());
            const __m128 yLower = detail::texelsOfCodes(
                _mm_unpacklo_epi32(pair(x.lower, y.lower), pair(x.upper, y.lower)), scale);
            const __m128 yUpper = detail::texelsOfCodes(
                _mm_unpacklo_epi32(pair(x.lower, y.upper), pair(x.upper, y.upper)), scale);
            const __m128 zLower = _mm_shuffle_ps(yLower, yUpper, _MM_SHUFFLE(2, 0, 2, 0));
            const __m128 zUpper = _mm_shuffle_ps(yLower, yUpper, _MM_SHUFFLE(3, 1, 3, 1));
            _mm_storeu_ps(alongZ, _mm_add_ps(zLower, _mm_mul_ps(_mm_sub_ps(zUpper, zLower),
                                                                _mm_set1_ps(z.weight))));
        } else
#endif
        {
            const Corners c = corners(x, y, z);
            for (int column = 0; column < 4; ++column)
                alongZ[column] = lerp(c.v[column], c.v[column + 4], z.weight);
        }
        return lerp(lerp(alongZ[0], alongZ[1], x.weight), lerp(alongZ[2], alongZ[3], x.weight),
                    y.weight);
    }

    glm::vec3 gradient(const glm::vec3& texelPosition) const {
        const Size3& size = texels_.size();
        const detail::AxisLerp x = detail::periodicAxis(texelPosition.x, size.width);
        const detail::AxisLerp y = detail::periodicAxis(texelPosition.y, size.height);
        const detail::AxisLerp z = detail::extendedAxis(texelPosition.z, size.depth);
        const Corners c = corners(x, y, z);
        const float fx = x.weight;
        const float fy = y.weight;
        const float fz = z.weight;
        // Differences along x at the four (y, z) corners, then interpolate, etc.
        const float dx = lerp(lerp(c.v[1] - c.v[0], c.v[3] - c.v[2], fy),
                              lerp(c.v[5] - c.v[4], c.v[7] - c.v[6], fy), fz);
        const float dy = lerp(lerp(c.v[2] - c.v[0], c.v[3] - c.v[1], fx),
                              lerp(c.v[6] - c.v[4], c.v[7] - c.v[5], fx), fz);
        const float dz = lerp(lerp(c.v[4] - c.v[0], c.v[5] - c.v[1], fx),
                              lerp(c.v[6] - c.v[2], c.v[7] - c.v[3], fx), fy);
        return {dx, dy, dz};
    }

  private:
    /// Corner values, index bit 0: x upper, bit 1: y upper, bit 2: z upper.
    struct Corners {
        float v[8];
    };

#if defined(__SSE2__)
    /// distancesTexels4 over columns: detail::periodicAxis and detail::extendedAxis for four
    /// points per instruction (the same operations lane by lane), the texel pairs fetched point by
    /// point as fetch() does, then the x and y lerps four points at once. Points outside the
    /// near case of periodicAxis (huge, not finite) are redone by distanceTexels().
    void fetch4(const glm::vec3* positions, float* out) const {
        const Size3& size = texels_.size();
        const __m128 half = _mm_set1_ps(0.5f);
        const __m128 one = _mm_set1_ps(1.0f);
        const __m128i zero = _mm_setzero_si128();
        auto floorFinite = [&](__m128 value) {  // detail::floorFinite
            const __m128 truncated = _mm_cvtepi32_ps(_mm_cvttps_epi32(value));
            return _mm_sub_ps(truncated, _mm_and_ps(_mm_cmpgt_ps(truncated, value), one));
        };
        __m128i outside = zero;  // lanes periodicAxis does not take in its near case
        // detail::periodicAxis: lower and upper index and the weight; `outside` collects lanes
        // that are huge, not finite, or more than a period away.
        // Lanes gathered from the points' scalars (a vector load of four separate stores would
        // wait for them).
        const auto lanes = [&](int axis) {
            return _mm_setr_ps(positions[0][axis], positions[1][axis], positions[2][axis],
                               positions[3][axis]);
        };
        auto periodic = [&](__m128 coordinates, int extent, __m128i& lower, __m128i& upper) {
            const __m128 shifted = _mm_sub_ps(coordinates, half);
            const __m128 magnitude =
                _mm_and_ps(shifted, _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff)));
            outside = _mm_or_si128(outside,
                                   _mm_castps_si128(_mm_cmpnlt_ps(magnitude, _mm_set1_ps(1.0e9f))));
            const __m128 floorValue = floorFinite(shifted);
            const __m128i extentLanes = _mm_set1_epi32(extent);
            __m128i index = _mm_cvttps_epi32(floorValue);
            index = _mm_add_epi32(index, _mm_and_si128(_mm_cmplt_epi32(index, zero), extentLanes));
            const __m128i last = _mm_set1_epi32(extent - 1);
            index = _mm_sub_epi32(index, _mm_and_si128(_mm_cmpgt_epi32(index, last), extentLanes));
            outside = _mm_or_si128(
                outside, _mm_or_si128(_mm_cmplt_epi32(index, zero), _mm_cmpgt_epi32(index, last)));
            lower = index;
            const __m128i next = _mm_add_epi32(index, _mm_set1_epi32(1));
            upper = _mm_andnot_si128(_mm_cmpeq_epi32(next, extentLanes), next);
            return _mm_sub_ps(shifted, floorValue);
        };
        __m128i xLower, xUpper, yLower, yUpper;
        const __m128 xWeight = periodic(lanes(0), size.width, xLower, xUpper);
        const __m128 yWeight = periodic(lanes(1), size.height, yLower, yUpper);
        // detail::extendedAxis (clampedSliceCoordinate, then the clamped lower slice).
        __m128 zShifted = _mm_sub_ps(lanes(2), half);
        const __m128 firstFace = _mm_set1_ps(-0.5f);
        const __m128 lastFace = _mm_set1_ps(float(size.depth) - 0.5f);
        const __m128 aboveFirst = _mm_cmpge_ps(zShifted, firstFace);  // false for NaN
        zShifted =
            _mm_or_ps(_mm_and_ps(aboveFirst, zShifted), _mm_andnot_ps(aboveFirst, firstFace));
        const __m128 belowLast = _mm_cmplt_ps(zShifted, lastFace);
        zShifted = _mm_or_ps(_mm_and_ps(belowLast, zShifted), _mm_andnot_ps(belowLast, lastFace));
        __m128i zLower = _mm_cvttps_epi32(floorFinite(zShifted));
        zLower = _mm_andnot_si128(_mm_cmplt_epi32(zLower, zero), zLower);
        const __m128i lastLower = _mm_set1_epi32(size.depth - 2);
        const __m128i aboveLast = _mm_cmpgt_epi32(zLower, lastLower);
        zLower =
            _mm_or_si128(_mm_and_si128(aboveLast, lastLower), _mm_andnot_si128(aboveLast, zLower));
        const __m128 zWeight = _mm_sub_ps(zShifted, _mm_cvtepi32_ps(zLower));
        // The elements of the four columns' slice zLower: column(x, y) + z = x D + y W D + z
        // (ColumnTexels), in 32 bits (a tile's texel count fits: TileColumns). Lanes outside read
        // texel 0; their results are replaced below.
        const auto times = [](__m128i value, std::uint32_t factor) {  // lane-wise, < 2^32
            const __m128i factors = _mm_set1_epi32(std::int32_t(factor));
            const __m128i even = _mm_mul_epu32(value, factors);
            const __m128i odd = _mm_mul_epu32(_mm_srli_epi64(value, 32), factors);
            return _mm_unpacklo_epi32(_mm_shuffle_epi32(even, _MM_SHUFFLE(0, 0, 2, 0)),
                                      _mm_shuffle_epi32(odd, _MM_SHUFFLE(0, 0, 2, 0)));
        };
        const std::uint32_t columnStride = std::uint32_t(size.depth);
        const std::uint32_t rowStride = std::uint32_t(size.width) * columnStride;
        const __m128i xLowerStart = times(_mm_andnot_si128(outside, xLower), columnStride);
        const __m128i xUpperStart = times(_mm_andnot_si128(outside, xUpper), columnStride);
        const __m128i yLowerStart =
            _mm_add_epi32(times(_mm_andnot_si128(outside, yLower), rowStride), zLower);
        const __m128i yUpperStart =
            _mm_add_epi32(times(_mm_andnot_si128(outside, yUpper), rowStride), zLower);
        alignas(16) std::uint32_t elements[4][4];  // x, y lower or upper: 00, 10, 01, 11
        _mm_store_si128(reinterpret_cast<__m128i*>(elements[0]),
                        _mm_add_epi32(xLowerStart, yLowerStart));
        _mm_store_si128(reinterpret_cast<__m128i*>(elements[1]),
                        _mm_add_epi32(xUpperStart, yLowerStart));
        _mm_store_si128(reinterpret_cast<__m128i*>(elements[2]),
                        _mm_add_epi32(xLowerStart, yUpperStart));
        _mm_store_si128(reinterpret_cast<__m128i*>(elements[3]),
                        _mm_add_epi32(xUpperStart, yUpperStart));
        alignas(16) float zWeights[4];
        _mm_store_ps(zWeights, zWeight);
        const __m128 scale = _mm_set1_ps(texels_.texelsPerCode());
        const std::int16_t* codes = texels_.codes();
        __m128 alongZ[4];  // per point: the four columns' values at its z
        for (int lane = 0; lane < 4; ++lane) {
            const auto pair = [&](int column) {  // codes of slices z, z + 1
                std::int32_t bits;
                std::memcpy(&bits, codes + elements[column][lane], sizeof bits);
                return _mm_cvtsi32_si128(bits);
            };
            const __m128 rowLower =
                detail::texelsOfCodes(_mm_unpacklo_epi32(pair(0), pair(1)), scale);
            const __m128 rowUpper =
                detail::texelsOfCodes(_mm_unpacklo_epi32(pair(2), pair(3)), scale);
            const __m128 sliceLower = _mm_shuffle_ps(rowLower, rowUpper, _MM_SHUFFLE(2, 0, 2, 0));
            const __m128 sliceUpper = _mm_shuffle_ps(rowLower, rowUpper, _MM_SHUFFLE(3, 1, 3, 1));
            alongZ[lane] = _mm_add_ps(sliceLower, _mm_mul_ps(_mm_sub_ps(sliceUpper, sliceLower),
                                                             _mm_set1_ps(zWeights[lane])));
        }
        // Column c of every point: alongZ[c] after the transpose.
        _MM_TRANSPOSE4_PS(alongZ[0], alongZ[1], alongZ[2], alongZ[3]);
        const auto lerp4 = [](__m128 a, __m128 b, __m128 t) {
            return _mm_add_ps(a, _mm_mul_ps(_mm_sub_ps(b, a), t));
        };
        _mm_storeu_ps(out, lerp4(lerp4(alongZ[0], alongZ[1], xWeight),
                                 lerp4(alongZ[2], alongZ[3], xWeight), yWeight));
        const int outsideLanes = _mm_movemask_ps(_mm_castsi128_ps(outside));
        if (outsideLanes != 0) {
            for (int lane = 0; lane < 4; ++lane)
                if (outsideLanes & (1 << lane)) out[lane] = distanceTexels(positions[lane]);
        }
    }
#endif

    static float lerp(float a, float b, float t) {
        return a + (b - a) * t;
    }

    Corners corners(const detail::AxisLerp& x, const detail::AxisLerp& y,
                    const detail::AxisLerp& z) const {
        const std::size_t columns[4] = {
            texels_.column(x.lower, y.lower), texels_.column(x.upper, y.lower),
            texels_.column(x.lower, y.upper), texels_.column(x.upper, y.upper)};
        const std::size_t lower = std::size_t(z.lower) * texels_.zStride();
        const std::size_t upper = std::size_t(z.upper) * texels_.zStride();
        return {{texels_[columns[0] + lower], texels_[columns[1] + lower],
                 texels_[columns[2] + lower], texels_[columns[3] + lower],
                 texels_[columns[0] + upper], texels_[columns[1] + upper],
                 texels_[columns[2] + upper], texels_[columns[3] + upper]}};
    }

    Texels texels_;
};

/// `filter`'s distances at the four points `positions` into out[i]: its distancesTexels4 where
/// it has one, else four distanceTexels calls.
template <class Filter>
void distancesTexels4(const Filter& filter, const glm::vec3* positions, float* out) {
    if constexpr (requires { filter.distancesTexels4(positions, out); }) {
        filter.distancesTexels4(positions, out);
    } else {
        for (int i = 0; i < 4; ++i) out[i] = filter.distanceTexels(positions[i]);
    }
}

/// `filter`'s distances at the eight points `positions` into out[i]: its distancesTexels8 where
/// it has one, else two distancesTexels4.
template <class Filter>
void distancesTexels8(const Filter& filter, const glm::vec3* positions, float* out) {
    if constexpr (requires { filter.distancesTexels8(positions, out); }) {
        filter.distancesTexels8(positions, out);
    } else {
        distancesTexels4(filter, positions, out);
        distancesTexels4(filter, positions + 4, out + 4);
    }
}

using NearestFilter = BasicNearestFilter<TileTexels>;
using TrilinearFilter = BasicTrilinearFilter<TileTexels>;

}  // namespace distile
