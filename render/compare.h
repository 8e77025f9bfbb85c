/// @file
/// How far one render is from another of the same scene (DESIGN.md, Truth and error): hit
/// position error in texels, coverage mismatch, normal angle error and PSNR, from the images and
/// AOVs of RenderResult (or the same layers read back from files by the command line). Works on
/// images in memory only; no file I/O here.
#pragma once

#include <cstdint>

#include "render/image.h"

namespace distile {

/// The layers of one render that a comparison reads, as RenderAovs holds them: the shaded image
/// (linear RGB), the depth AOV (world units along the ray, 0 for a miss), the normal AOV
/// (n * 0.5 + 0.5, 0 for a miss) and the texel-scale AOV (texels per world unit along the ray, 0
/// where no tile was hit). The images must outlive the view.
struct RenderLayersView {
    const Image& image;
    const Image& depth;
    const Image& normal;
    const Image& texelScale;
};

struct RenderComparison {
    int width = 0;
    int height = 0;
    std::uint64_t pixels = 0;
    std::uint64_t bothHit = 0;             ///< pixels where both renders hit a surface
    std::uint64_t coverageMismatches = 0;  ///< pixels where one render hit and the other missed
    /// coverageMismatches / pixels (share of all pixels, not of the hit ones).
    double coverageMismatchShare = 0.0;
    /// Hit position error |depthA - depthB| along the ray, converted to texels with A's texel scale
    /// (B's where A's is 0), over the `hitErrorSamples` pixels where both hit and a scale is known.
    std::uint64_t hitErrorSamples = 0;
    double meanHitErrorTexels = 0.0;
    double p99HitErrorTexels = 0.0;  ///< 99th percentile (nearest rank)
    double maxHitErrorTexels = 0.0;
    /// Mean angle between the decoded normals where both hit, degrees (an 8-bit normal AOV
    /// quantises each component to 1/255, about 0.2 degrees).
    double meanNormalErrorDeg = 0.0;
    /// PSNR of the shaded images over the sRGB-encoded values clamped to [0, 1] (peak 1, all three
    /// channels): for two 8-bit PNGs this is the usual 8-bit PSNR. +infinity for identical images.
    double psnrDb = 0.0;
};

/// Compares render `a` with render `b` (usually the reference). When `difference` is not null it
/// receives a heat map of the shaded difference: heatColor(4 x the largest channel difference of
/// the sRGB-encoded values) per pixel, magenta where the coverage differs. Throws InputError,
/// naming the layer and both sizes, when any layer's size differs from a.image's.
RenderComparison compareRenders(const RenderLayersView& a, const RenderLayersView& b,
                                Image* difference = nullptr);

}  // namespace distile
