/// @file
/// The distance-mapping renderer (GPU Gems 2, ch. 8) on the CPU.
///
/// Per pixel, camera rays find the nearest displaced detail among the shells conservatively
/// rasterized to their screen tile (render/coverage.h, ch. 42), each traced by SceneTracer (entry
/// through the base mesh, then the march in the tile's texel space). Shading: Lambert + Blinn-Phong
/// with the tile gradient as normal, an ambient term darkened low in the shell, soft self-shadows
/// traced through the tile toward each light, and shadows of other surfaces from a shadow map per
/// light (render/shadow_map.h, ch. 17). Pixels are independent, so the image does not depend on the
/// thread count.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/progress.h"
#include "render/image.h"
#include "render/scene.h"
#include "render/shadow_map.h"
#include "render/tracer.h"

namespace distile {

struct RenderOptions {
    int width = 1280;
    int height = 1024;
    int samplesPerPixel = 1;  ///< camera rays per pixel (R2 low-discrepancy offsets), averaged
    MarchSettings march;      ///< method, budget per ray (ch. 8 uses 8 to 16) and hit threshold
    FilterKind filter = FilterKind::Trilinear;  ///< the march's (and self-shadows') distances
    FilterKind normalFilter = FilterKind::TricubicBSpline;  ///< the shading normal's gradient
    bool selfShadows = true;  ///< trace shadow rays through the tile toward each light
    /// Budget of each self-shadow ray: its least, as a ray toward a low light takes a sample per
    /// 2 texels of its path to the tile's top, up to 4 x this.
    int shadowIterations = 24;
    /// Shadows cast between surfaces, from a shadow map per light; None builds no map.
    ShadowFilter shadowFilter = ShadowFilter::Adaptive;
    /// Texels along the longer side of each shadow map's finest level (ShadowMap::kLevels); 0
    /// (default): from the image, 1.5 x its longer side in [256, 4096], so a small image does not
    /// pay for a large map.
    int shadowMapResolution = 0;
    bool outputAovs = false;  ///< also produce the AOV images of RenderResult
    RenderSkips skips;        ///< work left out where the scene does not need it (all on)
    /// Curved bases: follow the shell map prism by prism (default), or ch. 8's planar march.
    ShellMapping shellMapping = ShellMapping::Curved;
    /// Reference render: march and shade every tiled material on its Material::analyticDistance
    /// (double precision, render/analytic_filter.h) instead of its tile, with kReferenceIterations
    /// and kReferenceEpsilonTexels in place of march.maxIterations and march.epsilonTexels (filter
    /// and normalFilter are unused); a material with a Material::exactHit (mesh detail) takes its
    /// hits and normals from it instead of the march. The truth against which ordinary renders
    /// are compared.
    bool reference = false;
    static constexpr int kReferenceIterations = 512;
    static constexpr float kReferenceEpsilonTexels = 1e-3f;
};

struct RenderStats {
    std::uint64_t rays = 0;      ///< camera rays (pixels x samples per pixel)
    std::uint64_t baseHits = 0;  ///< camera rays that hit a base surface
    /// Camera rays whose nearest hit is a tile's (its detail or its floor, marched to): base hits
    /// less those on bare surfaces (no tile) and back faces.
    std::uint64_t detailHits = 0;
    std::uint64_t marchIterations = 0;  ///< sphere-tracing steps over all camera rays
    std::uint64_t converged = 0;        ///< of detailHits, those that converged within the budget
    std::uint64_t shadowSteps = 0;      ///< steps of self-shadow rays
    /// Shadow-map lookups' work, all lights: depth comparisons (PCF samples) of filtered lights,
    /// texels read by the line test of wide ones (render/shadow_map.h).
    std::uint64_t shadowMapSamples = 0;
    std::uint64_t shadowMapTexels = 0;     ///< shadow-map texels traced (tiles lookups reached)
    std::uint64_t shadowMapTexelsAll = 0;  ///< texels of the shadow maps' levels, traced or not
    std::uint64_t shellsTested =
        0;  ///< camera rays x binned shells whose pixel coverage was tested
    std::uint64_t shellsTraced =
        0;  ///< camera rays x shells whose top was intersected (and marched if entered)
    double meanIterations() const {
        return baseHits ? double(marchIterations) / double(baseHits) : 0.0;
    }
    /// The share of the hits on a tile that converged within the budget (1 with none).
    double convergedShare() const {
        return detailHits ? double(converged) / double(detailHits) : 1.0;
    }
};

/// Arbitrary output variables, per pixel (first sample of the pixel), when requested.
struct RenderAovs {
    Image depth;   ///< distance from the eye along the ray, world units (0: miss), in all channels
    Image normal;  ///< shading normal * 0.5 + 0.5 (0: miss)
    Image iterations;     ///< march iterations as a heat map (blue 0 .. red = budget)
    Image shadowSamples;  ///< self-shadow steps as a heat map (blue 0 .. red = budget x lights)
    /// RenderStats::shadowMapSamples per pixel as a heat map (blue 0 .. red = 72 x lights and more)
    Image shadowMapSamples;
    /// Mean curvature of the detail at the hit, 1/texel in texel space, from the tricubic
    /// B-spline's gradient and Hessian, as a heat map: blue -0.5 (concave) .. green 0 (flat) ..
    /// red +0.5 (convex, a wire of radius 2 texels is 0.25); black where no detail was hit.
    Image curvature;
    /// Texels per world unit along the camera ray in the hit's texel space (from the shell entry's
    /// frame), in all channels; 0 where the ray missed or hit no tile. Converts depth differences
    /// to texels (render/compare.h).
    Image texelScale;

    /// Every layer black, `width` x `height` pixels.
    static RenderAovs blank(int width, int height);
};

struct RenderResult {
    Image image;
    std::optional<RenderAovs> aovs;
    RenderStats stats;
    /// What the user should know about the scene as rendered (SceneTracer::warnings), one line
    /// each.
    std::vector<std::string> warnings;
};

/// The most camera samples (width x height x samples per pixel) a render takes: 2^24, about 40 s
/// on two cores for a scene of detail tiles. The time grows linearly with them.
inline constexpr std::int64_t kMaxRenderSamples = std::int64_t(1) << 24;

/// The images a render with AOVs holds in memory at once (the image and seven AOVs).
inline constexpr std::int64_t kAovImages = 8;

/// Renders `scene`. Throws InputError for an invalid scene (validateScene) or options (naming the
/// RenderOptions member, e.g. "march.epsilonTexels"); for a
/// reference render, also for an object whose tile has no analytic distance (naming the object)
/// (width/height in [1, 16384], iterations in [1, 4096], epsilon in (0, 1], samples per pixel
/// in [1, 256], width x height x samples per pixel at most kMaxRenderSamples, with AOVs width x
/// height at most 2^22, shadow-map resolution 0 or in [16, 16384]). `progress` is called on the
/// calling thread; it is not called while the shadow maps are built, before the first row.
RenderResult renderScene(const Scene& scene, const RenderOptions& options,
                         const ProgressCallback& progress = {});

/// A scene made ready to render with `options`: the set-up that does not depend on the camera
/// (the base triangles' bounding-volume hierarchy, each tile in the renderer's layout with its
/// empty space, the curved shells' prisms), built once for any number of renders, each the same
/// as renderScene(scene, options) gives. renderScene prepares the scene on every call; a
/// program that renders one scene several times (or times the frames alone, as `distile bench`
/// does) prepares it once. The scene must outlive it and not change. Throws as renderScene.
class PreparedScene {
  public:
    PreparedScene(const Scene& scene, const RenderOptions& options);
    ~PreparedScene();
    PreparedScene(const PreparedScene&) = delete;
    PreparedScene& operator=(const PreparedScene&) = delete;

    /// One render of the scene with the options it was prepared with.
    RenderResult render(const ProgressCallback& progress = {}) const;

  private:
    struct Parts;
    std::unique_ptr<Parts> parts_;
};

/// A heat-map colour (blue, cyan, green, yellow, red) for a value in [0, 1].
glm::vec3 heatColor(float value);

}  // namespace distile
