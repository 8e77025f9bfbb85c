/// @file
/// Conservative rasterization (GPU Gems 2, ch. 42) of the detail shells for camera rays.
///
/// Every entry face of the scene (SceneTracer::entryFaceCount: each base triangle, the top of its
/// shell, and the sides of shells on an open border that face the camera; "shell" below) is
/// projected with the renderer's pinhole camera and binned into screen tiles with
/// *overestimated* coverage: a triangle goes into every tile, and passes the test of every pixel,
/// whose square it touches (thin slivers and sub-pixel triangles included). Its shell also gets
/// conservative depth bounds, so a camera ray can skip a shell that cannot be nearer than the hit
/// it already has (shell culling).
///
/// Pixel coordinates: x to the right in [0, width], y down in [0, height]; pixel (i, j) is the
/// square [i, i+1] x [j, j+1], its centre (i + 0.5, j + 0.5). Depths are distances from the eye
/// along camera rays, world units.
#pragma once

#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

#include "render/bvh.h"
#include "render/scene.h"
#include "render/tracer.h"

namespace distile {

/// The renderer's pinhole camera: pixel positions to rays, world points to pixels.
class PinholeProjection {
  public:
    /// Preconditions: the camera passed validateScene; width and height >= 1 pixels.
    PinholeProjection(const Camera& camera, int widthPixels, int heightPixels);

    /// The camera ray through pixel position (x, y) (pixels, y down); direction unit length.
    Ray ray(float xPixels, float yPixels) const {
        glm::vec3 direction;
        directions(&xPixels, &yPixels, 1, &direction.x, &direction.y, &direction.z);
        return {eye_, direction};
    }
    /// The directions of ray() for `count` pixel positions, x, y and z components apart, four at
    /// a time with SSE2 (ray() is the one-position case: the same floats either way).
    void directions(const float* xPixels, const float* yPixels, std::size_t count, float* x,
                    float* y, float* z) const;

    /// `world` relative to the eye in the camera basis: x right, y up, z forward (world units).
    glm::dvec3 toView(const glm::vec3& world) const;
    /// The view-space direction (x, y, 1) of the camera ray through pixel position (x, y) is an
    /// affine function of it: x = slopePerPixel.x * xPixels + slopeAtOrigin.x, same for y.
    glm::dvec2 slopePerPixel() const { return slopePerPixel_; }
    glm::dvec2 slopeAtOrigin() const { return slopeAtOrigin_; }
    /// Pixel position of a view-space point; precondition: view.z > 0.
    glm::dvec2 toPixels(const glm::dvec3& view) const;
    /// True when all of `worldPoints` lie beyond one side of the view frustum (grown by 1% of
    /// its slopes), so no camera ray meets their convex hull.
    bool seesNoneOf(std::span<const glm::vec3> worldPoints) const;

    glm::vec3 eye() const { return eye_; }
    /// The least angle a pixel spans seen from the eye, radians: a pixel at distance d is at
    /// least d times this wide in every direction across its ray.
    float pixelAngleRadians() const { return pixelAngleRadians_; }
    int width() const { return width_; }
    int height() const { return height_; }
    /// How far (pixels) a camera ray computed in single precision may stray from the pixel
    /// position it was asked for; coverage tests grow pixel squares by this much.
    double marginPixels() const { return marginPixels_; }

  private:
    glm::vec3 eye_, forward_, right_, up_;
    float tanHalfFov_;
    int width_, height_;
    glm::dvec2 slopePerPixel_, slopeAtOrigin_;
    glm::vec2 slopePerPixelFloat_, slopeAtOriginFloat_;  ///< the same, for ray()
    double marginPixels_;
    float pixelAngleRadians_;
};

/// A triangle on the screen, ready for conservative pixel tests: the pixel bounds of its
/// visible part plus three edge functions; together they are the separating-axis test of a
/// triangle against an axis-aligned square (ch. 42: bounding box, and each edge tested at the
/// square's corner that is most inside).
struct ScreenTriangle {
    glm::dvec3 edges[3]{};      ///< a x + b y + c of a pixel position, >= 0 on the triangle's side
    double edgeTolerance[3]{};  ///< rounding allowance of each edge function
    bool hasEdges = false;      ///< false: the bounds only (degenerate, or seen exactly edge-on)
    glm::dvec2 boundsMin{0.0};  ///< pixels; empty when boundsMin.x > boundsMax.x
    glm::dvec2 boundsMax{-1.0};
    double marginPixels = 0.0;  ///< squares are grown by this much before the test

    bool empty() const { return boundsMin.x > boundsMax.x || boundsMin.y > boundsMax.y; }
};

/// A triangle given by its corners in pixel coordinates (finite). A zero-area triangle keeps
/// its bounds only. `marginPixels` >= 0 grows every tested square.
ScreenTriangle screenTriangle(const glm::dvec2 cornersPixels[3], double marginPixels = 0.0);

/// A world-space triangle as the camera sees it: clipped to the view frustum (grown by one pixel),
/// so triangles crossing the eye plane are handled; the edge functions are those of the rays
/// from the eye (homogeneous rasterization), exact for any triangle whose plane misses the eye.
/// Empty when no camera ray can hit it. The margin is projection.marginPixels().
ScreenTriangle projectTriangle(const PinholeProjection& projection,
                               const glm::vec3 cornersWorld[3]);

/// Overestimated coverage: false only when the rectangle [x0, x1] x [y0, y1] (pixels), grown by
/// the triangle's margin, certainly does not touch the triangle.
bool triangleRectOverlapConservative(const ScreenTriangle& triangle, double x0, double y0,
                                     double x1, double y1);

/// True when every pixel square inside [x0, x1] x [y0, y1] certainly passes the per-pixel test
/// (trianglePixelOverlapConservative): the rectangle lies inside the bounds and inside every edge.
bool triangleCoversRect(const ScreenTriangle& triangle, double x0, double y0, double x1, double y1);

/// The per-pixel test: false only when the square of pixel (x, y) certainly misses the triangle.
inline bool trianglePixelOverlapConservative(const ScreenTriangle& triangle, int x, int y) {
    return triangleRectOverlapConservative(triangle, x, y, x + 1.0, y + 1.0);
}

/// What the camera sees of one detail shell.
struct ShellBounds {
    ScreenTriangle top;          ///< coverage of the shell's top (rays enter a shell there)
    float zMinWorld = 0.0f;      ///< no camera ray meets the shell's top nearer than this
    float zMaxWorld = 0.0f;      ///< the farthest corner of the prism (top and bottom corners)
    bool hasDepthPlane = false;  ///< inverseDepthPlane is valid
    glm::dvec3
        inverseDepthPlane{};  ///< 1 / view depth of the top's plane, affine in pixels (ch. 42)
};

/// Per-ray work of the screen-space path, for statistics.
struct ShellCounters {
    std::uint64_t tested = 0;  ///< binned shells whose pixel coverage was tested
    std::uint64_t traced =
        0;  ///< shells whose top was intersected with the ray (then marched if entered)
};

/// Shells binned into screen tiles, nearest z_min first, for the camera rays of one image.
/// Shells that no camera ray can reach are left out. A camera ray enters a shell through its
/// front-facing top; a back-facing top stops it (the inside of a mesh), as SceneTracer's does,
/// except where the ray leaves a curved shell through it (with ShellMapping::Planar, whose march
/// cannot tell where a ray leaves, only where no front-facing surface is hit).
class ScreenShells {
  public:
    /// Side of the screen tiles, pixels: small tiles hold few of a fine curved mesh's shells
    /// (the demo's torus: about 5 per pixel at 8, 11 at 16), so each camera ray tests few.
    static constexpr int kTilePixels = 8;

    /// Preconditions: `tracer` and `projection` outlive this object (both are referenced).
    ScreenShells(const SceneTracer& tracer, const PinholeProjection& projection);

    int tilesX() const { return tilesX_; }
    int tilesY() const { return tilesY_; }
    /// The shells binned to tile (tileX, tileY), by increasing zMinWorld (ties by index).
    std::span<const std::uint32_t> tileShells(int tileX, int tileY) const;
    const ShellBounds& bounds(std::uint32_t shell) const { return bounds_[shell]; }
    /// (shell, tile) pairs in all bins.
    std::size_t binnedCount() const { return shellsByTile_.size(); }
    /// Whether a camera ray through pixel (x, y) takes `shell` as a candidate: the shell is in
    /// the bin of the pixel's tile, and its top passes the pixel's test.
    bool pixelTakes(std::uint32_t shell, int x, int y) const;

    /// A lower bound (world units) of the distance at which any camera ray through the square of
    /// pixel (x, y) meets the top of `shell`: the larger of zMinWorld and the plane's nearest
    /// depth over the square's corners (ch. 42, conservative depth).
    float pixelDepthBound(std::uint32_t shell, int x, int y) const;

    /// The nearest hit of camera ray `ray` (through the square of pixel (x, y)) over the shells
    /// binned to its tile: the shells whose pixel test passes, nearest pixelDepthBound first, are
    /// traced (SceneTracer::enterShell, marchShells, finishShell) and the nearest front-facing hit
    /// is kept. With `shellCulling`, shells whose bound is not nearer than the best hit so far are
    /// skipped; the hit is the same either way. Precondition: 0 <= x < width, 0 <= y < height.
    /// Thread-safe.
    bool traceNearest(int x, int y, const Ray& ray, bool shellCulling, SurfaceHit& hit,
                      TraceCounters& counters, ShellCounters& shellCounters) const;

    /// A camera ray through the square of pixel (x, y), for traceNearestBatch.
    struct PixelRay {
        int x = 0;
        int y = 0;
        Ray ray;
    };
    /// At most this many rays per traceNearestBatch call.
    static constexpr std::size_t kMaxBatchRays = 64;

    /// traceNearest for each of `rays` (at most kMaxBatchRays), their marches taken together
    /// (SceneTracer::marchShells interleaves them): `found[i]`, `hits[i]` and `counters[i]` are
    /// what traceNearest gives for rays[i] alone, bit for bit. Thread-safe.
    void traceNearestBatch(std::span<const PixelRay> rays, bool shellCulling,
                           std::span<SurfaceHit> hits, std::span<bool> found,
                           std::span<TraceCounters> counters, ShellCounters& shellCounters) const;

  private:
    static constexpr std::uint32_t kNoShell = 0xffffffffU;
    /// The shell that is the only one binned to the screen tile of each of `rays` and covers it,
    /// or kNoShell.
    std::uint32_t soleCoveringShell(std::span<const PixelRay> rays) const;

    const SceneTracer& tracer_;
    const PinholeProjection& projection_;
    int tilesX_ = 0, tilesY_ = 0;
    std::vector<ShellBounds> bounds_;
    std::vector<std::uint32_t> tileStart_;     ///< per tile (row-major), then one past the end
    std::vector<std::uint32_t> shellsByTile_;  ///< shell indices, grouped by tile
    /// Per entry of shellsByTile_: its shell's top covers every pixel of the tile (the per-pixel
    /// test would pass everywhere there, so it is skipped).
    std::vector<bool> coversTile_;
    /// Per entry of shellsByTile_: the pixels of the tile whose per-pixel test
    /// (trianglePixelOverlapConservative) passes, bit pixelBit(x, y); all bits where the shell
    /// covers the tile. Taken once per entry over the pixels near the shell's bounds, rather than
    /// by every ray of the tile against every shell binned there.
    std::vector<std::uint64_t> pixelMasks_;
    static_assert(kTilePixels * kTilePixels == 64, "a tile's pixels are the bits of a mask");
    /// Pixel (x, y)'s bit in its tile's masks.
    static int pixelBit(int x, int y) { return (y % kTilePixels) * kTilePixels + x % kTilePixels; }
    /// The mask of pixelMasks_ for `top` over tile (tileX, tileY) of `projection`'s image.
    static std::uint64_t passingPixels(const ScreenTriangle& top, int tileX, int tileY,
                                       const PinholeProjection& projection);
};

}  // namespace distile
