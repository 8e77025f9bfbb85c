#include "render/coverage.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <glm/geometric.hpp>
#include <limits>
#include <numeric>
#include <utility>
#include <vector>

#include "common/thread_scratch.h"

namespace distile {

namespace {

constexpr float kPi = 3.14159265358979f;
/// Depth bounds are pulled toward the eye by this relative amount: far more than the rounding of
/// the double-precision bound and of the single-precision hit distance it is compared with.
constexpr double kDepthSafety = 1e-6;

/// A convex polygon in view space, clipped by half-spaces through the eye (Sutherland-Hodgman).
struct ViewPolygon {
    glm::dvec3 points[8];
    int count = 0;

    /// Keeps the part where dot(plane, p) >= 0.
    void clip(const glm::dvec3& plane) {
        glm::dvec3 kept[8];
        int keptCount = 0;
        for (int i = 0; i < count; ++i) {
            const glm::dvec3& current = points[i];
            const glm::dvec3& next = points[(i + 1) % count];
            const double currentSide = glm::dot(plane, current);
            const double nextSide = glm::dot(plane, next);
            if (currentSide >= 0.0) kept[keptCount++] = current;
            if ((currentSide >= 0.0) != (nextSide >= 0.0)) {
                kept[keptCount++] =
                    current + (next - current) * (currentSide / (currentSide - nextSide));
            }
        }
        std::copy(kept, kept + keptCount, points);
        count = keptCount;
    }
};

}  // namespace

PinholeProjection::PinholeProjection(const Camera& camera, int widthPixels, int heightPixels)
    : eye_(camera.eye), width_(widthPixels), height_(heightPixels) {
    forward_ = glm::normalize(camera.target - camera.eye);
    right_ = glm::normalize(glm::cross(forward_, camera.up));
    // An up too long or too short for single precision's squares: its direction.
    if (!(glm::dot(right_, right_) > 0.5f))  // not unit: zero (overflow) or NaN (underflow)
        right_ = glm::normalize(glm::cross(forward_, unitDirection(camera.up)));
    up_ = glm::cross(right_, forward_);
    tanHalfFov_ = std::tan(0.5f * camera.fovDeg * kPi / 180.0f);
    const double tanX = double(tanHalfFov_) * (double(width_) / double(height_));
    slopePerPixel_ = {2.0 * tanX / width_, -2.0 * double(tanHalfFov_) / height_};
    slopeAtOrigin_ = {-tanX, double(tanHalfFov_)};
    slopePerPixelFloat_ = glm::vec2(slopePerPixel_);
    slopeAtOriginFloat_ = glm::vec2(slopeAtOrigin_);
    // Single-precision rays stray by a few ulps of direction (relative 1e-6 is a wide allowance,
    // basis vectors included); in pixels that is the slope error over the slope per pixel.
    const double slopeRange = 1.0 + tanX + double(tanHalfFov_);
    marginPixels_ = 1e-4 + 1e-6 * slopeRange / std::min(slopePerPixel_.x, -slopePerPixel_.y);
    // The angle a pixel spans is its slope step divided by 1 + slope^2 (the derivative of atan)
    // across the radius, so at least the step over 1 + the corners' slope^2.
    double cornerSlopeSquared = 0.0;
    for (int corner = 0; corner < 4; ++corner) {
        const glm::dvec2 slope =
            slopePerPixel_ * glm::dvec2(corner & 1 ? width_ : 0, corner & 2 ? height_ : 0) +
            slopeAtOrigin_;
        cornerSlopeSquared = std::max(cornerSlopeSquared, glm::dot(slope, slope));
    }
    const glm::dvec2 step = glm::abs(slopePerPixel_);
    pixelAngleRadians_ = float(std::min(step.x, step.y) / (1.0 + cornerSlopeSquared));
}

void PinholeProjection::directions(const float* xPixels, const float* yPixels, std::size_t count,
                                   float* x, float* y, float* z) const {
    // The view-space slopes are affine in the pixel position (slopePerPixel, slopeAtOrigin);
    // the direction is glm::normalize's: v times 1 / sqrt(v . v).
#if defined(__SSE2__)
    // Four at a time; the last four padded with their first position.
    const auto at = [](float value) { return _mm_set1_ps(value); };
    const auto sum = [](__m128 a, __m128 b) { return _mm_add_ps(a, b); };
    const auto product = [](__m128 a, __m128 b) { return _mm_mul_ps(a, b); };
    for (std::size_t first = 0; first < count; first += 4) {
        const std::size_t lanes = std::min<std::size_t>(4, count - first);
        // Four positions loaded at once (copied lane by lane, the four stores would stall the
        // load that reads them back).
        __m128 xs, ys;
        if (lanes == 4) {
            xs = _mm_loadu_ps(xPixels + first);
            ys = _mm_loadu_ps(yPixels + first);
        } else {
            alignas(16) float xPadded[4], yPadded[4];
            for (std::size_t lane = 0; lane < 4; ++lane) {
                xPadded[lane] = xPixels[first + (lane < lanes ? lane : 0)];
                yPadded[lane] = yPixels[first + (lane < lanes ? lane : 0)];
            }
            xs = _mm_load_ps(xPadded);
            ys = _mm_load_ps(yPadded);
        }
        const __m128 slopeX =
            sum(product(xs, at(slopePerPixelFloat_.x)), at(slopeAtOriginFloat_.x));
        const __m128 slopeY =
            sum(product(ys, at(slopePerPixelFloat_.y)), at(slopeAtOriginFloat_.y));
        __m128 v[3];
        for (int axis = 0; axis < 3; ++axis) {
            v[axis] = sum(sum(at(forward_[axis]), product(slopeX, at(right_[axis]))),
                          product(slopeY, at(up_[axis])));
        }
        const __m128 inverseLength = _mm_div_ps(
            at(1.0f),
            _mm_sqrt_ps(sum(sum(product(v[0], v[0]), product(v[1], v[1])), product(v[2], v[2]))));
        float* const outputs[3] = {x, y, z};
        for (int axis = 0; axis < 3; ++axis) {
            const __m128 direction = product(v[axis], inverseLength);
            if (lanes == 4) {
                _mm_storeu_ps(outputs[axis] + first, direction);
                continue;
            }
            alignas(16) float out[4];
            _mm_store_ps(out, direction);
            for (std::size_t lane = 0; lane < lanes; ++lane)
                outputs[axis][first + lane] = out[lane];
        }
    }
#else
    for (std::size_t i = 0; i < count; ++i) {
        const float slopeX = xPixels[i] * slopePerPixelFloat_.x + slopeAtOriginFloat_.x;
        const float slopeY = yPixels[i] * slopePerPixelFloat_.y + slopeAtOriginFloat_.y;
        const glm::vec3 v = forward_ + slopeX * right_ + slopeY * up_;
        const glm::vec3 unit = v * (1.0f / std::sqrt(glm::dot(v, v)));
        x[i] = unit.x;
        y[i] = unit.y;
        z[i] = unit.z;
    }
#endif
}

glm::dvec3 PinholeProjection::toView(const glm::vec3& world) const {
    const glm::dvec3 relative = glm::dvec3(world) - glm::dvec3(eye_);
    return {glm::dot(relative, glm::dvec3(right_)), glm::dot(relative, glm::dvec3(up_)),
            glm::dot(relative, glm::dvec3(forward_))};
}

glm::dvec2 PinholeProjection::toPixels(const glm::dvec3& view) const {
    return (glm::dvec2(view.x, view.y) / view.z - slopeAtOrigin_) / slopePerPixel_;
}

bool PinholeProjection::seesNoneOf(std::span<const glm::vec3> worldPoints) const {
    // The frustum is the four half-spaces |x| <= tanX z and |y| <= tanY z of view space (z > 0
    // follows from them).
    const glm::dvec2 tanHalf = 1.01 * glm::abs(slopeAtOrigin_);
    bool beyond[4] = {true, true, true, true};
    for (const glm::vec3& world : worldPoints) {
        const glm::dvec3 view = toView(world);
        beyond[0] = beyond[0] && view.x > tanHalf.x * view.z;
        beyond[1] = beyond[1] && -view.x > tanHalf.x * view.z;
        beyond[2] = beyond[2] && view.y > tanHalf.y * view.z;
        beyond[3] = beyond[3] && -view.y > tanHalf.y * view.z;
    }
    return beyond[0] || beyond[1] || beyond[2] || beyond[3];
}

ScreenTriangle screenTriangle(const glm::dvec2 cornersPixels[3], double marginPixels) {
    ScreenTriangle triangle;
    triangle.marginPixels = marginPixels;
    triangle.boundsMin = glm::min(cornersPixels[0], glm::min(cornersPixels[1], cornersPixels[2]));
    triangle.boundsMax = glm::max(cornersPixels[0], glm::max(cornersPixels[1], cornersPixels[2]));
    const glm::dvec2 edge1 = cornersPixels[1] - cornersPixels[0];
    const glm::dvec2 edge2 = cornersPixels[2] - cornersPixels[0];
    const double twiceArea = edge1.x * edge2.y - edge1.y * edge2.x;
    const double extent = std::max(glm::length(edge1), glm::length(edge2));
    if (!(std::abs(twiceArea) > 1e-12 * extent * extent)) return triangle;
    const double orientation = twiceArea > 0.0 ? 1.0 : -1.0;
    for (int i = 0; i < 3; ++i) {
        const glm::dvec2 from = cornersPixels[i];
        const glm::dvec2 to = cornersPixels[(i + 1) % 3];
        // orientation * cross(to - from, p - from): positive on the triangle's side.
        const double a = -orientation * (to.y - from.y);
        const double b = orientation * (to.x - from.x);
        triangle.edges[i] = {a, b, -(a * from.x + b * from.y)};
        triangle.edgeTolerance[i] =
            1e-12 * (std::abs(a) + std::abs(b)) * (1.0 + std::abs(from.x) + std::abs(from.y));
    }
    triangle.hasEdges = true;
    return triangle;
}

ScreenTriangle projectTriangle(const PinholeProjection& projection,
                               const glm::vec3 cornersWorld[3]) {
    ScreenTriangle triangle;
    triangle.marginPixels = projection.marginPixels();
    const glm::dvec3 view[3] = {projection.toView(cornersWorld[0]),
                                projection.toView(cornersWorld[1]),
                                projection.toView(cornersWorld[2])};
    const glm::dvec2 slopePerPixel = projection.slopePerPixel();
    const glm::dvec2 slopeAtOrigin = projection.slopeAtOrigin();
    const double width = projection.width();
    const double height = projection.height();

    // Bounds: the part of the triangle inside the view frustum grown by one pixel. Its side
    // planes pass through the eye and together keep z >= 0, so what is behind the eye goes.
    ViewPolygon polygon;
    polygon.count = 3;
    std::copy(view, view + 3, polygon.points);
    const double slopeLeft = slopeAtOrigin.x - slopePerPixel.x;
    const double slopeRight = slopeAtOrigin.x + slopePerPixel.x * (width + 1.0);
    const double slopeTop = slopeAtOrigin.y - slopePerPixel.y;  // y = -1 pixel
    const double slopeBottom = slopeAtOrigin.y + slopePerPixel.y * (height + 1.0);
    polygon.clip({1.0, 0.0, -slopeLeft});
    polygon.clip({-1.0, 0.0, slopeRight});
    polygon.clip({0.0, -1.0, slopeTop});
    polygon.clip({0.0, 1.0, -slopeBottom});
    if (polygon.count == 0) return triangle;  // empty bounds: no camera ray reaches it
    const double margin = triangle.marginPixels;
    const glm::dvec2 screenMin(-1.0 - margin, -1.0 - margin);
    const glm::dvec2 screenMax(width + 1.0 + margin, height + 1.0 + margin);
    glm::dvec2 boundsMin(std::numeric_limits<double>::max());
    glm::dvec2 boundsMax(-std::numeric_limits<double>::max());
    bool touchesEye = false;
    for (int i = 0; i < polygon.count; ++i) {
        const glm::dvec3& point = polygon.points[i];
        const glm::dvec2 pixels = point.z > 0.0 ? projection.toPixels(point) : glm::dvec2(0.0);
        if (!(point.z > 0.0) || !std::isfinite(pixels.x) || !std::isfinite(pixels.y)) {
            touchesEye = true;  // only the eye itself has z = 0 inside the frustum
            break;
        }
        boundsMin = glm::min(boundsMin, pixels);
        boundsMax = glm::max(boundsMax, pixels);
    }
    if (touchesEye) {
        boundsMin = screenMin;
        boundsMax = screenMax;
    }
    // Clipping rounds; the margin absorbs it (and is added again by the rectangle test).
    triangle.boundsMin = glm::clamp(boundsMin - margin, screenMin, screenMax);
    triangle.boundsMax = glm::clamp(boundsMax + margin, screenMin, screenMax);

    // Edges: a ray with view direction d meets the triangle iff d = a V0 + b V1 + c V2 with a, b,
    // c >= 0, where a = det(d, V1, V2) / det(V0, V1, V2) and so on. With d = (slope(x, y), 1),
    // each weight's numerator is affine in the pixel position.
    const double determinant = glm::dot(view[0], glm::cross(view[1], view[2]));
    const double scale = glm::length(view[0]) * glm::length(view[1]) * glm::length(view[2]);
    if (!(std::abs(determinant) > 1e-10 * scale))
        return triangle;  // its plane (nearly) holds the eye
    const double orientation = determinant > 0.0 ? 1.0 : -1.0;
    const double slopeMagnitude =
        1.0 + std::abs(slopeAtOrigin.x) + std::abs(slopePerPixel.x) * (width + 2.0) +
        std::abs(slopeAtOrigin.y) + std::abs(slopePerPixel.y) * (height + 2.0);
    for (int i = 0; i < 3; ++i) {
        const glm::dvec3& from = view[(i + 1) % 3];
        const glm::dvec3& to = view[(i + 2) % 3];
        const glm::dvec3 normal = glm::cross(from, to) * orientation;
        triangle.edges[i] = {normal.x * slopePerPixel.x, normal.y * slopePerPixel.y,
                             normal.x * slopeAtOrigin.x + normal.y * slopeAtOrigin.y + normal.z};
        triangle.edgeTolerance[i] = 1e-12 * glm::length(from) * glm::length(to) * slopeMagnitude;
    }
    triangle.hasEdges = true;
    return triangle;
}

bool triangleRectOverlapConservative(const ScreenTriangle& triangle, double x0, double y0,
                                     double x1, double y1) {
    x0 -= triangle.marginPixels;
    y0 -= triangle.marginPixels;
    x1 += triangle.marginPixels;
    y1 += triangle.marginPixels;
    // Separating axes x and y: the bounds.
    if (x1 < triangle.boundsMin.x || x0 > triangle.boundsMax.x || y1 < triangle.boundsMin.y ||
        y0 > triangle.boundsMax.y) {
        return false;
    }
    if (!triangle.hasEdges) return true;
    // Separating axes along the edge normals: the corner most inside each edge.
    for (int i = 0; i < 3; ++i) {
        const glm::dvec3& edge = triangle.edges[i];
        const double x = edge.x > 0.0 ? x1 : x0;
        const double y = edge.y > 0.0 ? y1 : y0;
        if (edge.x * x + edge.y * y + edge.z < -triangle.edgeTolerance[i]) return false;
    }
    return true;
}

bool triangleCoversRect(const ScreenTriangle& triangle, double x0, double y0, double x1,
                        double y1) {
    if (!triangle.hasEdges || x0 < triangle.boundsMin.x || x1 > triangle.boundsMax.x ||
        y0 < triangle.boundsMin.y || y1 > triangle.boundsMax.y) {
        return false;
    }
    // Each edge at the rectangle's corner least inside it (the per-pixel test, with its margin
    // and tolerance, allows less: a pixel's most inside corner is at least as far inside).
    for (const glm::dvec3& edge : triangle.edges) {
        const double x = edge.x > 0.0 ? x0 : x1;
        const double y = edge.y > 0.0 ? y0 : y1;
        if (!(edge.x * x + edge.y * y + edge.z >= 0.0)) return false;
    }
    return true;
}

std::uint64_t ScreenShells::passingPixels(const ScreenTriangle& top, int tileX, int tileY,
                                          const PinholeProjection& projection) {
    // Only pixels whose squares, grown by the margin, reach the triangle's bounds can pass (the
    // test's first check): x + 1 + margin >= boundsMin.x and x - margin <= boundsMax.x, and the
    // same in y. The range below holds them all (its low end is the pixel whose grown square
    // ends exactly on boundsMin.x when that is a whole number of pixels).
    const double left = tileX * kTilePixels, upper = tileY * kTilePixels;
    const int x0 = int(std::max(left, std::floor(top.boundsMin.x - top.marginPixels) - 1.0));
    const int y0 = int(std::max(upper, std::floor(top.boundsMin.y - top.marginPixels) - 1.0));
    const int x1 = int(std::min({left + (kTilePixels - 1), double(projection.width() - 1),
                                 std::ceil(top.boundsMax.x + top.marginPixels)}));
    const int y1 = int(std::min({upper + (kTilePixels - 1), double(projection.height() - 1),
                                 std::ceil(top.boundsMax.y + top.marginPixels)}));
    if (x0 > x1 || y0 > y1) return 0;
    // trianglePixelOverlapConservative over the range, its terms taken once per column and per
    // row: each pixel's sums are those of its own test (the same products, added in the same
    // order), so its answer is the same. Column c of a row is bit c of the row's bits.
    const double margin = top.marginPixels;
    bool columnInBounds[kTilePixels] = {};
    double columnTerms[3][kTilePixels] = {};
    for (int column = 0; column <= x1 - x0; ++column) {
        const double low = double(x0 + column) - margin;
        const double high = (double(x0 + column) + 1.0) + margin;
        columnInBounds[column] = !(high < top.boundsMin.x || low > top.boundsMax.x);
        for (int i = 0; i < 3; ++i)
            columnTerms[i][column] = top.edges[i].x * (top.edges[i].x > 0.0 ? high : low);
    }
    std::uint64_t pixels = 0;
    for (int y = y0; y <= y1; ++y) {
        const double low = double(y) - margin;
        const double high = (double(y) + 1.0) + margin;
        if (high < top.boundsMin.y || low > top.boundsMax.y) continue;
        double rowTerms[3];
        for (int i = 0; i < 3; ++i)
            rowTerms[i] = top.edges[i].y * (top.edges[i].y > 0.0 ? high : low);
        unsigned rowBits = 0;
        for (int column = 0; column < kTilePixels; ++column) {
            bool passes = columnInBounds[column];
            if (top.hasEdges) {
                for (int i = 0; i < 3; ++i)
                    passes &= !(columnTerms[i][column] + rowTerms[i] + top.edges[i].z <
                                -top.edgeTolerance[i]);
            }
            rowBits |= unsigned(passes) << column;
        }
        pixels |= std::uint64_t(rowBits) << pixelBit(x0, y);
    }
    return pixels;
}

ScreenShells::ScreenShells(const SceneTracer& tracer, const PinholeProjection& projection)
    : tracer_(tracer), projection_(projection) {
    tilesX_ = (projection.width() + kTilePixels - 1) / kTilePixels;
    tilesY_ = (projection.height() + kTilePixels - 1) / kTilePixels;
    const std::uint32_t shellCount = tracer.entryFaceCount();  // tops and open borders' sides
    bounds_.resize(shellCount);
    const glm::dvec2 slopePerPixel = projection.slopePerPixel();
    const glm::dvec2 slopeAtOrigin = projection.slopeAtOrigin();
    const glm::dvec3 eye(projection.eye());
    // Each shell's projection on its own, in parallel.
    tbb::parallel_for(std::uint32_t(0), shellCount, [&](std::uint32_t shell) {
        glm::vec3 top[3], bottom[3];
        tracer.entryFaceCorners(shell, top, bottom);
        // Front-facing tops are where camera rays enter shells, back-facing ones stop them (the
        // inside of a mesh) unless the ray leaves a curved shell there (traceNearestBatch): both
        // are binned, and the tracer tells them apart.
        ShellBounds& bounds = bounds_[shell];
        if (tracer.entryFaceFacesAway(shell, projection.eye())) return;  // a side seen from inside
        bounds.top = projectTriangle(projection, top);
        if (bounds.top.empty()) return;
        double zMin = std::numeric_limits<double>::max();
        double zMax = 0.0;
        glm::dvec3 view[3];
        for (int corner = 0; corner < 3; ++corner) {
            view[corner] = projection.toView(top[corner]);
            zMin = std::min(zMin,
                            view[corner].z);  // depth along the view axis <= distance from the eye
            zMax = std::max(
                {zMax, glm::length(view[corner]), glm::length(projection.toView(bottom[corner]))});
        }
        bounds.zMinWorld = float(std::max(zMin, 0.0) * (1.0 - kDepthSafety));
        bounds.zMaxWorld = float(zMax * (1.0 + kDepthSafety));
        // The top's plane n.p = h: a ray with view direction (slope, 1) meets it at view depth
        // h / n.(slope, 1), so the inverse depth is affine in the pixel position.
        const glm::dvec3 normal = glm::cross(view[1] - view[0], view[2] - view[0]);
        const double offset = glm::dot(normal, view[0]);
        if (std::abs(offset) > 1e-10 * glm::length(normal) * glm::length(view[0])) {
            bounds.hasDepthPlane = true;
            bounds.inverseDepthPlane =
                glm::dvec3(normal.x * slopePerPixel.x, normal.y * slopePerPixel.y,
                           normal.x * slopeAtOrigin.x + normal.y * slopeAtOrigin.y + normal.z) /
                offset;
        }
    });
    // Nearest first (equal depths in shell order): filling the bins in this order sorts every
    // bin. Sorted as (depth, shell) pairs, an order with no ties, so in parallel.
    std::vector<std::pair<float, std::uint32_t>> byDepth;
    for (std::uint32_t shell = 0; shell < shellCount; ++shell)
        if (!bounds_[shell].top.empty()) byDepth.emplace_back(bounds_[shell].zMinWorld, shell);
    tbb::parallel_sort(byDepth.begin(), byDepth.end());
    std::vector<std::uint32_t> visible(byDepth.size());
    for (std::size_t index = 0; index < byDepth.size(); ++index)
        visible[index] = byDepth[index].second;
    // The (tile, shell) entries of consecutive runs of `visible` in parallel, each run's in
    // order; then the runs in order.
    struct Entry {
        std::uint32_t tile, shell;
        bool covers;
        std::uint64_t pixels;  ///< ScreenShells::pixelMasks_
    };
    constexpr std::size_t kRunShells = 1024;
    std::vector<std::vector<Entry>> runs((visible.size() + kRunShells - 1) / kRunShells);
    tbb::parallel_for(std::size_t(0), runs.size(), [&](std::size_t run) {
        const std::size_t end = std::min(visible.size(), (run + 1) * kRunShells);
        for (std::size_t index = run * kRunShells; index < end; ++index) {
            const std::uint32_t shell = visible[index];
            const ScreenTriangle& top = bounds_[shell].top;
            // Every tile holding a pixel whose square, grown by the margin, meets the bounds.
            const glm::dvec2 low = (top.boundsMin - top.marginPixels) / double(kTilePixels);
            const glm::dvec2 high = (top.boundsMax + top.marginPixels) / double(kTilePixels);
            const int tileX0 = std::clamp(int(std::floor(low.x)), 0, tilesX_ - 1);
            const int tileY0 = std::clamp(int(std::floor(low.y)), 0, tilesY_ - 1);
            const int tileX1 = std::clamp(int(std::floor(high.x)), 0, tilesX_ - 1);
            const int tileY1 = std::clamp(int(std::floor(high.y)), 0, tilesY_ - 1);
            for (int tileY = tileY0; tileY <= tileY1; ++tileY) {
                for (int tileX = tileX0; tileX <= tileX1; ++tileX) {
                    const double x0 = tileX * kTilePixels;
                    const double y0 = tileY * kTilePixels;
                    const double x1 = std::min(x0 + kTilePixels, double(projection.width()));
                    const double y1 = std::min(y0 + kTilePixels, double(projection.height()));
                    if (!triangleRectOverlapConservative(top, x0, y0, x1, y1)) continue;
                    const bool covers = triangleCoversRect(top, x0, y0, x1, y1);
                    runs[run].push_back({std::uint32_t(tileY * tilesX_ + tileX), shell, covers,
                                         covers ? ~std::uint64_t(0)
                                                : passingPixels(top, tileX, tileY, projection)});
                }
            }
        }
    });
    // Counting sort by tile, stable: each bin keeps the nearest-first order.
    tileStart_.assign(std::size_t(tilesX_) * tilesY_ + 1, 0);
    for (const std::vector<Entry>& run : runs)
        for (const Entry& entry : run) ++tileStart_[entry.tile + 1];
    std::partial_sum(tileStart_.begin(), tileStart_.end(), tileStart_.begin());
    shellsByTile_.resize(tileStart_.back());
    coversTile_.resize(tileStart_.back());
    pixelMasks_.resize(tileStart_.back());
    std::vector<std::uint32_t> fill(tileStart_.begin(), tileStart_.end() - 1);
    for (const std::vector<Entry>& run : runs) {
        for (const Entry& entry : run) {
            const std::uint32_t at = fill[entry.tile]++;
            shellsByTile_[at] = entry.shell;
            coversTile_[at] = entry.covers;
            pixelMasks_[at] = entry.pixels;
        }
    }
}

std::span<const std::uint32_t> ScreenShells::tileShells(int tileX, int tileY) const {
    const std::size_t tile = std::size_t(tileY) * tilesX_ + tileX;
    return {shellsByTile_.data() + tileStart_[tile], shellsByTile_.data() + tileStart_[tile + 1]};
}

bool ScreenShells::pixelTakes(std::uint32_t shell, int x, int y) const {
    const std::size_t tile = std::size_t(y / kTilePixels) * tilesX_ + std::size_t(x / kTilePixels);
    for (std::uint32_t entry = tileStart_[tile]; entry < tileStart_[tile + 1]; ++entry)
        if (shellsByTile_[entry] == shell) return (pixelMasks_[entry] >> pixelBit(x, y) & 1) != 0;
    return false;
}

float ScreenShells::pixelDepthBound(std::uint32_t shell, int x, int y) const {
    const ShellBounds& bounds = bounds_[shell];
    if (!bounds.hasDepthPlane) return bounds.zMinWorld;
    // The inverse depth is affine, so its largest value over the (grown) square is at the corner
    // picked by the gradient's signs; a ray's distance is at least its view depth.
    const double margin = bounds.top.marginPixels;
    const glm::dvec3& plane = bounds.inverseDepthPlane;
    const double cornerX = plane.x > 0.0 ? x + 1.0 + margin : x - margin;
    const double cornerY = plane.y > 0.0 ? y + 1.0 + margin : y - margin;
    const double largestInverseDepth = plane.x * cornerX + plane.y * cornerY + plane.z;
    if (!(largestInverseDepth > 0.0)) return bounds.zMinWorld;
    return std::max(bounds.zMinWorld, float((1.0 - kDepthSafety) / largestInverseDepth));
}

namespace {

/// A shell that may cover a pixel, with its depth bound over the pixel.
struct Candidate {
    float depthBound;
    std::uint32_t shell;
};

/// A pixel's candidates, nearest depth bound first: few per pixel, so a small buffer inline, and
/// beyond it a vector of `overflow`, the caller's (so that a Candidates is trivially destructible,
/// as threadScratch needs).
class Candidates {
  public:
    /// `overflow` holds the vectors of a batch's pixels with more than kInline candidates; it
    /// outlives the batch's use of the candidates.
    void push(const Candidate& candidate, std::vector<std::vector<Candidate>>& overflow) {
        if (count_ < kInline) {
            inline_[count_] = candidate;
        } else {
            if (count_ == kInline) {
                // One vector per pixel of the batch at most: reserved, so none moves.
                if (overflow.empty()) overflow.reserve(ScreenShells::kMaxBatchRays);
                heap_ = &overflow.emplace_back(inline_, inline_ + kInline);
            }
            heap_->push_back(candidate);
        }
        ++count_;
    }
    /// Insertion sort by depth bound: stable (ties keep bin order, so the order is the same
    /// whether or not shells are culled), no allocation, fast for a few candidates.
    void sort() {
        Candidate* all = data();
        for (std::size_t i = 1; i < count_; ++i) {
            const Candidate candidate = all[i];
            std::size_t j = i;
            for (; j > 0 && candidate.depthBound < all[j - 1].depthBound; --j) all[j] = all[j - 1];
            all[j] = candidate;
        }
    }
    /// Sets each candidate's depth bound to depthBound(shell).
    template <class DepthBound>
    void bound(DepthBound&& depthBound) {
        Candidate* all = data();
        for (std::size_t i = 0; i < count_; ++i) all[i].depthBound = depthBound(all[i].shell);
    }
    std::size_t size() const { return count_; }
    void clear() { count_ = 0; }
    const Candidate& operator[](std::size_t index) const { return data()[index]; }

  private:
    static constexpr std::size_t kInline = 64;
    Candidate* data() { return count_ <= kInline ? inline_ : heap_->data(); }
    const Candidate* data() const { return count_ <= kInline ? inline_ : heap_->data(); }
    Candidate inline_[kInline];
    std::vector<Candidate>* heap_ = nullptr;  ///< beyond kInline: in the caller's overflow
    std::size_t count_ = 0;
};

}  // namespace

bool ScreenShells::traceNearest(int x, int y, const Ray& ray, bool shellCulling, SurfaceHit& hit,
                                TraceCounters& counters, ShellCounters& shellCounters) const {
    const PixelRay rays[1] = {{x, y, ray}};
    bool found[1] = {false};
    traceNearestBatch(rays, shellCulling, std::span<SurfaceHit>(&hit, 1), found,
                      std::span<TraceCounters>(&counters, 1), shellCounters);
    return found[0];
}

std::uint32_t ScreenShells::soleCoveringShell(std::span<const PixelRay> rays) const {
    std::uint32_t shell = kNoShell;
    std::size_t checkedTile = ~std::size_t(0);
    for (const PixelRay& pixel : rays) {  // runs of pixels: a few tiles, each looked up once
        const std::size_t tile = std::size_t(unsigned(pixel.y) / kTilePixels) * tilesX_ +
                                 unsigned(pixel.x) / kTilePixels;
        if (tile == checkedTile) continue;
        checkedTile = tile;
        const std::uint32_t entry = tileStart_[tile];
        if (tileStart_[tile + 1] != entry + 1 || !coversTile_[entry] ||
            (shell != kNoShell && shellsByTile_[entry] != shell))
            return kNoShell;
        shell = shellsByTile_[entry];
    }
    return shell;
}

void ScreenShells::traceNearestBatch(std::span<const PixelRay> rays, bool shellCulling,
                                     std::span<SurfaceHit> hits, std::span<bool> found,
                                     std::span<TraceCounters> counters,
                                     ShellCounters& shellCounters) const {
    constexpr float kFar = std::numeric_limits<float>::max();
    const std::size_t count = rays.size();
    // Rays whose screen tiles hold one shell, covering them all: each ray's one candidate. For a
    // flat shell whose front they all meet, the tracer takes the batch at once (traceFlatShell:
    // what the rounds below give, without them).
    if (const std::uint32_t shell = soleCoveringShell(rays); shell != kNoShell) {
        const Ray* flatRays[kMaxBatchRays];
        for (std::size_t r = 0; r < count; ++r) flatRays[r] = &rays[r].ray;
        if (tracer_.traceFlatShell(shell, std::span<const Ray* const>(flatRays, count), hits, found,
                                   counters)) {
            shellCounters.tested += count;
            shellCounters.traced += count;
            return;
        }
    }
    // Per ray: its candidates (the tile's shells that pass the pixel test), the next one to trace
    // and the nearest hit so far.
    // Working memory, once per thread: constructing these arrays (tens of kB) for every batch
    // cost several percent of a render. Every element is set before it is read.
    struct Arrays {
        Candidates candidates[kMaxBatchRays];
        SurfaceHit shellHits[kMaxBatchRays];
        SurfaceHit backHits[kMaxBatchRays];
        ShellMarch marches[kMaxBatchRays];
        /// Per ray: where it left curved shells (SceneTracer: it crossed their top between the
        /// two distances), at most kExits of them.
        std::array<std::pair<float, float>, 4> exits[kMaxBatchRays];
    };
    constexpr std::size_t kExits = 4;
    Arrays& arrays = threadScratch<Arrays>();
    std::vector<std::vector<Candidate>> overflow;  // pixels with many candidates (rare)
    Candidates* candidates = arrays.candidates;
    SurfaceHit* shellHits = arrays.shellHits;
    SurfaceHit* backHits = arrays.backHits;
    ShellMarch* marches = arrays.marches;
    auto* exits = arrays.exits;
    std::size_t exitCount[kMaxBatchRays];
    float backNearest[kMaxBatchRays];
    std::size_t next[kMaxBatchRays];
    float nearest[kMaxBatchRays];
    for (std::size_t r = 0; r < count; ++r) {
        const PixelRay& pixel = rays[r];
        candidates[r].clear();
        const std::size_t tile =
            std::size_t(pixel.y / kTilePixels) * tilesX_ + std::size_t(pixel.x / kTilePixels);
        const int bit = pixelBit(pixel.x, pixel.y);
        shellCounters.tested += tileStart_[tile + 1] - tileStart_[tile];
        for (std::uint32_t entry = tileStart_[tile]; entry < tileStart_[tile + 1]; ++entry) {
            if ((pixelMasks_[entry] >> bit & 1) == 0) continue;
            candidates[r].push({-std::numeric_limits<float>::infinity(), shellsByTile_[entry]},
                               overflow);
        }
        // Depth bounds order several candidates and cull the later ones; a lone candidate is
        // traced whatever its bound.
        if (candidates[r].size() > 1) {
            candidates[r].bound(
                [&](std::uint32_t shell) { return pixelDepthBound(shell, pixel.x, pixel.y); });
            candidates[r].sort();
        }
        next[r] = 0;
        nearest[r] = kFar;
        found[r] = false;
        exitCount[r] = 0;
        backNearest[r] = kFar;
    }
    // Rounds: each ray traces its candidates in order up to the next one it enters; the marches
    // of the round are taken together; then each ray takes its march's end. A ray's steps are
    // those of tracing it alone.
    ShellMarch* pending[kMaxBatchRays];
    std::size_t pendingRay[kMaxBatchRays];
    // Where ray r's current shell is traced: straight into its output until it has a hit (most
    // rays have one candidate: no copy), then into working memory, copied when nearer.
    SurfaceHit* into[kMaxBatchRays];
    // Back-facing stops are kept apart, the nearest per ray, and taken at the end unless a front
    // hit is nearer or the ray left a curved shell there (shells are traced in the order of
    // their depth bounds, which need not be the order along the ray).
    auto keepNearest = [&](std::size_t r) {
        const SurfaceHit& shellHit = *into[r];
        if (!shellHit.entry.frontFacing) {
            if (shellHit.distanceWorld < backNearest[r]) {
                backNearest[r] = shellHit.distanceWorld;
                backHits[r] = shellHit;
            }
            return;
        }
        if (!(shellHit.distanceWorld < nearest[r])) return;
        nearest[r] = shellHit.distanceWorld;
        if (into[r] != &hits[r]) hits[r] = shellHit;
        found[r] = true;
    };
    auto leftThere = [&](std::size_t r, float distanceWorld) {
        for (std::size_t e = 0; e < exitCount[r]; ++e)
            if (exits[r][e].first <= distanceWorld && distanceWorld <= exits[r][e].second)
                return true;
        return false;
    };
    // The planar march cannot tell where a ray leaves a shell (it marches on under the base):
    // with it a back face is trusted only where nothing else is hit.
    const bool planar = tracer_.options().shellMapping == ShellMapping::Planar;
    auto takeBackStops = [&] {
        for (std::size_t r = 0; r < count; ++r) {
            if (planar && found[r]) continue;
            if (!(backNearest[r] < nearest[r]) || leftThere(r, backNearest[r])) continue;
            hits[r] = backHits[r];
            found[r] = true;
        }
    };
    for (;;) {
        std::size_t pendingCount = 0;
        for (std::size_t r = 0; r < count; ++r) {
            for (; next[r] < candidates[r].size(); ++next[r]) {
                const Candidate& candidate = candidates[r][next[r]];
                // A shell's hits are never nearer than its depth bound: once the bound is not
                // nearer than the best hit, neither is any later candidate's.
                if (shellCulling && candidate.depthBound >= nearest[r]) {
                    next[r] = candidates[r].size();
                    break;
                }
                ++shellCounters.traced;
                // With culling the top must also be nearer than the best hit; without, every
                // top is traced and its hit compared afterwards, to the same result.
                bool stopped = false;
                into[r] = found[r] ? &shellHits[r] : &hits[r];
                if (tracer_.enterShell(candidate.shell, rays[r].ray, 0.0f,
                                       shellCulling ? nearest[r] : kFar, *into[r], marches[r],
                                       stopped)) {
                    pending[pendingCount] = &marches[r];
                    pendingRay[pendingCount++] = r;
                    ++next[r];
                    break;
                }
                if (stopped) keepNearest(r);
            }
        }
        if (pendingCount == 0) {
            takeBackStops();
            return;
        }
        tracer_.marchShells(std::span<ShellMarch* const>(pending, pendingCount));
        for (std::size_t p = 0; p < pendingCount; ++p) {
            const std::size_t r = pendingRay[p];
            const ShellMarch& march = marches[r];
            if (tracer_.finishShell(rays[r].ray, march, *into[r], counters[r])) {
                keepNearest(r);
            } else if (march.curved) {
                if (exitCount[r] < kExits) {
                    exits[r][exitCount[r]++] = {march.lastInsideWorld, march.firstOutsideWorld};
                } else {  // a ray out of many curved shells: any back face before the last
                    exits[r][kExits - 1].first = 0.0f;
                    exits[r][kExits - 1].second =
                        std::max(exits[r][kExits - 1].second, march.firstOutsideWorld);
                }
            }
        }
    }
}

}  // namespace distile
