/// @file
/// How far one render is from another of the same scene (docs/reports.md): hit
/// position error in texels, coverage mismatch, normal angle error and PSNR, from the images and
/// AOVs of RenderResult (or the same layers read back from files by the command line); and a
/// heat map of the hit error with its colour bar. Works on images in memory only; no file I/O.
///
/// Interior and silhouette pixels. One pixel where one render hits a near surface and the other
/// a surface far behind it (or where the two silhouettes are a pixel apart) can carry an error of
/// thousands of texels and make the mean larger than the 99th percentile. The figures are
/// therefore also given apart for two classes of the pixels where both renders hit:
///   - silhouette: in either render, one of the pixel's eight neighbours (inside the image)
///     misses, or lies across a depth jump from it;
///   - interior: every other both-hit pixel.
/// A depth jump between neighbours p and q = p + o (o one of the eight offsets) in one render is
/// a step depth(q) - depth(p), converted to texels with p's texel scale, that is larger than
/// kDepthJumpFloorTexels and that neither step beside it on the same line of pixels, from p - o
/// to p and from q to q + o (taken where those pixels are inside the image and hit; a step with
/// neither is not judged: no line to judge it by), explains as a slope: going the same way and at
/// least 1 / kDepthJumpRatio of it. On a continuous surface consecutive steps along a line change
/// slowly whatever its slope and the image resolution (on a plane only through perspective), so
/// a step more than twice its neighbours' marks an occlusion or a fold, where moving the edge by
/// one pixel moves the hit by the whole step; and a step back the other way right after it marks
/// a spike: one pixel seeing through a gap in the detail, or hitting a wire thinner than a pixel,
/// whose own error may be thousands of texels. Steps of at most one texel are never jumps:
/// misplacing such an edge by a pixel costs at most a texel. On detail the image does not resolve
/// (several texels per pixel) most pixels are silhouette pixels; the counts say how many.
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

/// A depth step between neighbouring pixels is a jump (see the file note) when it is larger than
/// this many texels and than kDepthJumpRatio times the steps beside it that go the same way.
inline constexpr double kDepthJumpFloorTexels = 1.0;
inline constexpr double kDepthJumpRatio = 2.0;

/// The hit and normal errors over one class of the pixels where both renders hit.
struct HitErrorSummary {
    std::uint64_t pixels = 0;  ///< both-hit pixels in the class
    /// Of those, the pixels with a texel scale (A's or B's), over which the hit error is taken.
    std::uint64_t hitErrorSamples = 0;
    double meanHitErrorTexels = 0.0;
    double p99HitErrorTexels = 0.0;  ///< 99th percentile (nearest rank)
    double maxHitErrorTexels = 0.0;
    double meanNormalErrorDeg = 0.0;  ///< over the class's pixels
};

struct RenderComparison {
    int width = 0;
    int height = 0;
    std::uint64_t pixels = 0;
    std::uint64_t bothHit = 0;             ///< pixels where both renders hit a surface
    std::uint64_t coverageMismatches = 0;  ///< pixels where one render hit and the other missed
    /// coverageMismatches / pixels (share of all pixels, not of the hit ones).
    double coverageMismatchShare = 0.0;
    /// Over all both-hit pixels: hit position error |depthA - depthB| along the ray, converted to
    /// texels with A's texel scale (B's where A's is 0), over the `hitErrorSamples` pixels where
    /// both hit and a scale is known. `interior` and `silhouette` split these figures (see the
    /// file note): bothHit = interior.pixels + silhouette.pixels, and likewise the samples.
    std::uint64_t hitErrorSamples = 0;
    double meanHitErrorTexels = 0.0;
    double p99HitErrorTexels = 0.0;  ///< 99th percentile (nearest rank)
    double maxHitErrorTexels = 0.0;
    /// Mean angle between the decoded normals where both hit, degrees (an 8-bit normal AOV
    /// quantises each component to 1/255, about 0.2 degrees).
    double meanNormalErrorDeg = 0.0;
    HitErrorSummary interior;    ///< both-hit pixels away from every edge: the figures to quote
    HitErrorSummary silhouette;  ///< both-hit pixels next to a miss or a depth jump
    /// PSNR of the shaded images over the sRGB-encoded values clamped to [0, 1] (peak 1, all three
    /// channels): for two 8-bit PNGs this is the usual 8-bit PSNR. +infinity for identical images.
    double psnrDb = 0.0;
};

/// The hit-error heat map's scale: log10 of the error in texels from -2 to 2, i.e. 0.01 texel
/// (blue, and any smaller error) to 100 texels (red, and any larger), through heatColor.
inline constexpr double kHeatMapMinTexels = 0.01;
inline constexpr double kHeatMapMaxTexels = 100.0;
/// Height in pixels of the colour bar strip under the heat map.
inline constexpr int kHeatMapBarHeight = 32;

/// The colour of a hit error of `errorTexels` (>= 0) on the heat map's scale.
glm::vec3 hitErrorColor(double errorTexels);

/// Compares render `a` with render `b` (usually the reference).
/// When `difference` is not null it receives a heat map of the shaded difference: heatColor(4 x
/// the largest channel difference of the sRGB-encoded values) per pixel, magenta where the
/// coverage differs.
/// When `hitErrorMap` is not null it receives the hit error on a width x (height +
/// kHeatMapBarHeight) image: each pixel where both hit in hitErrorColor (mid grey where neither
/// render knows a texel scale), magenta where the coverage differs, dark grey where both miss;
/// below the image a colour bar from kHeatMapMinTexels to kHeatMapMaxTexels with ticks and labels
/// at each power of ten and the unit ("texels"), clipped to the width (labels need about 160
/// pixels).
/// Throws InputError, naming the layer and both sizes, when any layer's size differs from
/// a.image's.
RenderComparison compareRenders(const RenderLayersView& a, const RenderLayersView& b,
                                Image* difference = nullptr, Image* hitErrorMap = nullptr);

/// The 8-bit difference of two images of one size: their sRGB codes as a PNG holds them
/// (render/image.h srgbCode8).
struct CodeDifference {
    double differingShare = 0.0;  ///< pixels where any channel differs by more than 1 code
    int maxCodes = 0;
    bool bitIdentical = true;  ///< every linear float equal
};

/// The 8-bit difference of `a` and `b`. Throws std::logic_error when their sizes differ.
CodeDifference codeDifference(const Image& a, const Image& b);

}  // namespace distile
