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
#include <glm/vec3.hpp>

#include "sampler/tile.h"

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

/// Nearest-texel lookup (the reference for "no filtering").
class NearestFilter {
  public:
    explicit NearestFilter(const Tile& tile) : tile_(tile) {}

    float distanceTexels(const glm::vec3& texelPosition) const {
        const Size3& size = tile_.size();
        const int x = detail::wrapIndex(int(std::floor(texelPosition.x)), size.width);
        const int y = detail::wrapIndex(int(std::floor(texelPosition.y)), size.height);
        const int z = std::clamp(int(std::floor(texelPosition.z)), 0, size.depth - 1);
        return tile_.at(x, y, z);
    }

    /// Central differences of the stored texels around the containing texel (one-sided at the
    /// first and last slice): the gradient of the grid, as a shading normal for this filter.
    glm::vec3 gradient(const glm::vec3& texelPosition) const {
        const Size3& size = tile_.size();
        const int x = detail::wrapIndex(int(std::floor(texelPosition.x)), size.width);
        const int y = detail::wrapIndex(int(std::floor(texelPosition.y)), size.height);
        const int z = std::clamp(int(std::floor(texelPosition.z)), 0, size.depth - 1);
        const int zLow = std::max(z - 1, 0);
        const int zHigh = std::min(z + 1, size.depth - 1);
        return {0.5f * (tile_.at(detail::wrapIndex(x + 1, size.width), y, z) -
                        tile_.at(detail::wrapIndex(x - 1, size.width), y, z)),
                0.5f * (tile_.at(x, detail::wrapIndex(y + 1, size.height), z) -
                        tile_.at(x, detail::wrapIndex(y - 1, size.height), z)),
                (tile_.at(x, y, zHigh) - tile_.at(x, y, zLow)) / float(std::max(zHigh - zLow, 1))};
    }

  private:
    const Tile& tile_;
};

/// Trilinear interpolation between the 8 surrounding texel centres, extended linearly in z over
/// the outer half texels. The gradient is the exact derivative of the interpolant (piecewise
/// constant in each axis' own direction); beyond the faces it is the one at the face.
class TrilinearFilter {
  public:
    explicit TrilinearFilter(const Tile& tile) : tile_(tile) {}

    float distanceTexels(const glm::vec3& texelPosition) const {
        const Size3& size = tile_.size();
        return fetch(detail::periodicAxis(texelPosition.x, size.width),
                     detail::periodicAxis(texelPosition.y, size.height),
                     detail::extendedAxis(texelPosition.z, size.depth));
    }

    /// One linear texture fetch: the trilinear interpolant between the two texels given on each
    /// axis (indices already wrapped or clamped into the tile, weight = fraction toward `upper`;
    /// a z weight outside [0, 1] extrapolates linearly). The building block of the third-order
    /// filters of sampler/tricubic.h. Preconditions: the indices are inside the tile; no checks.
    float fetch(const detail::AxisLerp& x, const detail::AxisLerp& y,
                const detail::AxisLerp& z) const {
        const Corners c = corners(x, y, z);
        const float fx = c.x.weight;
        const float fy = c.y.weight;
        const float fz = c.z.weight;
        const float v00 = lerp(c.v[0], c.v[1], fx);
        const float v10 = lerp(c.v[2], c.v[3], fx);
        const float v01 = lerp(c.v[4], c.v[5], fx);
        const float v11 = lerp(c.v[6], c.v[7], fx);
        return lerp(lerp(v00, v10, fy), lerp(v01, v11, fy), fz);
    }

    glm::vec3 gradient(const glm::vec3& texelPosition) const {
        const Corners c = corners(texelPosition);
        const float fx = c.x.weight;
        const float fy = c.y.weight;
        const float fz = c.z.weight;
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
    struct Corners {
        detail::AxisLerp x, y, z;
        float v[8];  ///< corner values, index bit 0: x upper, bit 1: y upper, bit 2: z upper
    };

    static float lerp(float a, float b, float t) { return a + (b - a) * t; }

    Corners corners(const glm::vec3& p) const {
        const Size3& size = tile_.size();
        return corners(detail::periodicAxis(p.x, size.width),
                       detail::periodicAxis(p.y, size.height),
                       detail::extendedAxis(p.z, size.depth));
    }

    Corners corners(const detail::AxisLerp& x, const detail::AxisLerp& y,
                    const detail::AxisLerp& z) const {
        const Size3& size = tile_.size();
        Corners c{x, y, z, {}};
        const float* data = tile_.distancesTexels().data();
        const std::size_t strideY = std::size_t(size.width);
        const std::size_t strideZ = strideY * std::size_t(size.height);
        const std::size_t rows[2] = {std::size_t(c.y.lower) * strideY,
                                     std::size_t(c.y.upper) * strideY};
        const std::size_t slabs[2] = {std::size_t(c.z.lower) * strideZ,
                                      std::size_t(c.z.upper) * strideZ};
        const std::size_t columns[2] = {std::size_t(c.x.lower), std::size_t(c.x.upper)};
        for (int corner = 0; corner < 8; ++corner) {
            c.v[corner] = data[columns[corner & 1] + rows[(corner >> 1) & 1] + slabs[corner >> 2]];
        }
        return c;
    }

    const Tile& tile_;
};

}  // namespace distile
