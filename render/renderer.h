/// @file
/// The distance-mapping sphere tracer (GPU Gems 2, ch. 8) on the CPU.
///
/// Per pixel: the camera ray finds the nearest base-mesh triangle (the top of the detail shell).
/// The interpolated tangent frame maps the ray into the tile's texel space, where texels are
/// cubes, and the direction is normalised there; from the entry point at z = D the ray steps by
/// the sampled distance until the distance drops below the epsilon, it reaches a solid floor, or
/// the iteration budget ends. The shading normal is the tile gradient mapped back to world space;
/// Lambert + Blinn-Phong, with soft self-shadows traced through the tile toward each light.
/// Pixels are independent, so the image does not depend on the thread count.
#pragma once

#include <cstdint>

#include "common/progress.h"
#include "render/image.h"
#include "render/scene.h"

namespace distile {

struct RenderOptions {
    int width = 1280;
    int height = 1024;
    int maxIterations = 16;         ///< sphere-tracing budget per ray (ch. 8 uses 8 to 16)
    float epsilonTexels = 0.02f;    ///< a ray closer than this to the surface has hit it
    bool selfShadows = true;        ///< trace shadow rays through the tile toward each light
    int shadowIterations = 24;      ///< budget of each shadow ray
    int samplesPerPixel = 1;        ///< camera rays per pixel (R2 low-discrepancy offsets), averaged
};

struct RenderStats {
    std::uint64_t rays = 0;                ///< camera rays (pixels x samples per pixel)
    std::uint64_t baseHits = 0;            ///< camera rays that hit a base surface
    std::uint64_t marchIterations = 0;     ///< sphere-tracing steps over all primary rays
    std::uint64_t converged = 0;           ///< rays that hit detail or floor within the budget
    double meanIterations() const { return baseHits ? double(marchIterations) / baseHits : 0.0; }
};

/// Renders `scene` (validated with validateScene first). Throws InputError for invalid scenes or
/// options (width/height in [1, 16384], maxIterations in [1, 4096], epsilon in (0, 1],
/// samplesPerPixel in [1, 256]). `progress` is called on the calling thread.
Image renderScene(const Scene& scene, const RenderOptions& options, RenderStats* stats = nullptr,
                  const ProgressCallback& progress = {});

}  // namespace distile
