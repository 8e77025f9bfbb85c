// Tests of render/compare.h: known answers on synthetic render layers for the figures, the
// interior/silhouette split and the hit-error heat map.
#include "render/compare.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>

#include "check/reports.h"
#include "common/error.h"
#include "render/renderer.h"

namespace distile {
namespace {

/// Render layers held by value, for synthetic comparisons.
struct Layers {
    Image image, depth, normal, texelScale;
    explicit Layers(int width, int height)
        : image(width, height, glm::vec3(0.5f)),
          depth(width, height, glm::vec3(2.0f)),
          normal(width, height, glm::vec3(0.5f, 0.5f, 1.0f)),
          texelScale(width, height, glm::vec3(100.0f)) {}
    RenderLayersView view() const { return {image, depth, normal, texelScale}; }
};

TEST(CompareRenders, IdenticalRendersHaveNoErrorAndInfinitePsnr) {
    const Layers a(8, 4);
    const RenderComparison c = compareRenders(a.view(), a.view());
    EXPECT_EQ(c.pixels, 32u);
    EXPECT_EQ(c.bothHit, 32u);
    EXPECT_EQ(c.coverageMismatches, 0u);
    EXPECT_EQ(c.meanHitErrorTexels, 0.0);
    EXPECT_EQ(c.maxHitErrorTexels, 0.0);
    EXPECT_EQ(c.meanNormalErrorDeg, 0.0);
    EXPECT_TRUE(std::isinf(c.psnrDb) && c.psnrDb > 0.0);
}

TEST(CompareRenders, WithoutATexelScaleTheHitErrorIsUnknownNotZero) {
    // World references write no texel scale: two of them, their depths 0.001 apart, have no hit
    // error in texels. Reported as 0, it read as a perfect match.
    Layers a(8, 4), b(8, 4);
    for (Layers* layers : {&a, &b})
        for (glm::vec3& scale : layers->texelScale.rgbLinear) scale = glm::vec3(0.0f);
    for (glm::vec3& depth : b.depth.rgbLinear) depth += 0.001f;
    const RenderComparison c = compareRenders(a.view(), b.view());
    EXPECT_EQ(c.bothHit, 32u);
    EXPECT_EQ(c.hitErrorSamples, 0u);
    const nlohmann::json report = renderComparisonJson(c);
    EXPECT_TRUE(report["interior"]["hit_error_mean"].is_null()) << report.dump();
    EXPECT_TRUE(report["all_both_hit"]["hit_error_max"].is_null()) << report.dump();
    // With A's scale the same depths measure 0.1 texel.
    for (glm::vec3& scale : a.texelScale.rgbLinear) scale = glm::vec3(100.0f);
    const nlohmann::json measured = renderComparisonJson(compareRenders(a.view(), b.view()));
    EXPECT_NEAR(measured["all_both_hit"]["hit_error_mean"].get<double>(), 0.1, 1e-4);
}

TEST(CompareRenders, KnownDepthOffsetNormalTurnAndMissingHit) {
    Layers a(20, 10), b(20, 10);
    // B's hits are 0.001 world units farther: 0.1 texel at 100 texels per world unit (float
    // depths near 2 carry ~1e-7 relative error: tolerance 1e-4 texel).
    for (glm::vec3& depth : b.depth.rgbLinear) depth += 0.001f;
    // One pixel's hit in B is 0.005 world units off (0.5 texel): the maximum. The 99th percentile
    // of the 199 samples by nearest rank is rank ceil(0.99 * 199) = 198, i.e. 0.1 texel.
    b.depth.at(3, 3) = glm::vec3(2.005f);
    // One pixel missed in B: one mismatch in 200 pixels.
    b.depth.at(7, 7) = glm::vec3(0.0f);
    // Every normal of B turned 90 degrees (z -> x): mean normal error 90 degrees over both-hit
    // pixels.
    for (glm::vec3& normal : b.normal.rgbLinear) normal = glm::vec3(1.0f, 0.5f, 0.5f);
    // Shaded difference of 0.1 in sRGB-encoded values everywhere: PSNR = 20 log10(1 / 0.1) = 20 dB.
    for (glm::vec3& color : b.image.rgbLinear)
        color = glm::vec3(linearFromSrgb(srgbFromLinear(0.5f) + 0.1f));
    Image difference;
    const RenderComparison c = compareRenders(a.view(), b.view(), &difference);
    EXPECT_EQ(c.coverageMismatches, 1u);
    EXPECT_DOUBLE_EQ(c.coverageMismatchShare, 0.005);
    EXPECT_EQ(c.bothHit, 199u);
    EXPECT_EQ(c.hitErrorSamples, 199u);
    EXPECT_NEAR(c.meanHitErrorTexels, (198 * 0.1 + 0.5) / 199.0, 1e-4);
    EXPECT_NEAR(c.p99HitErrorTexels, 0.1, 1e-4);
    EXPECT_NEAR(c.maxHitErrorTexels, 0.5, 1e-4);
    EXPECT_NEAR(c.meanNormalErrorDeg, 90.0, 1e-3);
    EXPECT_NEAR(c.psnrDb, 20.0, 0.01);  // the sRGB round trip is accurate to ~1e-6
    ASSERT_EQ(difference.width, 20);
    EXPECT_EQ(difference.at(7, 7), glm::vec3(1.0f, 0.0f, 1.0f));  // coverage mismatch in magenta
    EXPECT_NE(difference.at(0, 0), heatColor(0.0f));              // a visible shaded difference
}

TEST(CompareRenders, RejectsLayersOfAnotherSize) {
    const Layers a(8, 4), b(4, 8);
    EXPECT_THROW(compareRenders(a.view(), b.view()), InputError);
}

/// Both renders miss from column `firstMissColumn` on: a silhouette down the image.
void missFrom(Layers& layers, int firstMissColumn) {
    for (int y = 0; y < layers.depth.height; ++y) {
        for (int x = firstMissColumn; x < layers.depth.width; ++x) {
            layers.depth.at(x, y) = glm::vec3(0.0f);
            layers.normal.at(x, y) = glm::vec3(0.0f);
        }
    }
}

TEST(CompareRenders, AFarHitAtASilhouetteStaysOutOfTheInteriorFigures) {
    // 20 x 10 pixels; both renders hit columns 0-14 (150 pixels) and miss columns 15-19.
    Layers a(20, 10), b(20, 10);
    missFrom(a, 15);
    missFrom(b, 15);
    // B's hits are 0.001 world units farther: 0.1 texel at 100 texels per world unit (float
    // depths near 2 carry ~1e-7 relative error: tolerance 1e-4 texel).
    for (glm::vec3& depth : b.depth.rgbLinear)
        if (depth.x > 0.0f) depth += 0.001f;
    // An interior pixel 0.5 texel off: its steps to its neighbours (0.4 texel) are no jump.
    b.depth.at(5, 5) = glm::vec3(2.005f);
    // At the silhouette B hits a surface one world unit behind: 100 texels, with its normal
    // turned 90 degrees (z -> x).
    b.depth.at(14, 5) = glm::vec3(3.0f);
    b.normal.at(14, 5) = glm::vec3(1.0f, 0.5f, 0.5f);

    const RenderComparison c = compareRenders(a.view(), b.view());
    EXPECT_EQ(c.pixels, 200u);
    EXPECT_EQ(c.coverageMismatches, 0u);
    EXPECT_EQ(c.bothHit, 150u);
    // Silhouette: column 14 (next to the misses, 10 pixels) and the three pixels of column 13
    // beside the far hit, across a 100-texel step in B between steps of 0.
    EXPECT_EQ(c.silhouette.pixels, 13u);
    EXPECT_EQ(c.interior.pixels, 137u);
    EXPECT_EQ(c.interior.hitErrorSamples + c.silhouette.hitErrorSamples, c.hitErrorSamples);
    EXPECT_EQ(c.hitErrorSamples, 150u);

    // Interior: 136 pixels at 0.1 texel and one at 0.5; nearest rank ceil(0.99 * 137) = 136.
    EXPECT_NEAR(c.interior.meanHitErrorTexels, (136 * 0.1 + 0.5) / 137.0, 1e-4);
    EXPECT_NEAR(c.interior.p99HitErrorTexels, 0.1, 1e-4);
    EXPECT_NEAR(c.interior.maxHitErrorTexels, 0.5, 1e-4);
    EXPECT_NEAR(c.interior.meanNormalErrorDeg, 0.0, 1e-9);
    // Silhouette: 12 pixels at 0.1 texel and the far hit at 100; rank ceil(0.99 * 13) = 13.
    EXPECT_NEAR(c.silhouette.meanHitErrorTexels, (12 * 0.1 + 100.0) / 13.0, 1e-3);
    EXPECT_NEAR(c.silhouette.p99HitErrorTexels, 100.0, 1e-3);
    EXPECT_NEAR(c.silhouette.maxHitErrorTexels, 100.0, 1e-3);
    EXPECT_NEAR(c.silhouette.meanNormalErrorDeg, 90.0 / 13.0, 1e-3);
    // All both-hit pixels: the one far hit pulls the mean above the 99th percentile (rank
    // ceil(0.99 * 150) = 149: the 0.5-texel pixel).
    EXPECT_NEAR(c.meanHitErrorTexels, (148 * 0.1 + 0.5 + 100.0) / 150.0, 1e-3);
    EXPECT_NEAR(c.p99HitErrorTexels, 0.5, 1e-4);
    EXPECT_NEAR(c.maxHitErrorTexels, 100.0, 1e-3);
    EXPECT_GT(c.meanHitErrorTexels, c.p99HitErrorTexels);
    EXPECT_NEAR(c.meanNormalErrorDeg, 90.0 / 150.0, 1e-4);
}

TEST(CompareRenders, ADepthJumpIsASilhouetteAndASlopeIsNot) {
    // Both renders see a slope rising 0.05 world units (5 texels) per column, far steeper than the
    // 1-texel floor, with a 0.5 world unit (50 texel) step down between columns 9 and 10: only
    // the two columns on either side of the step are silhouette pixels, at any slope.
    Layers a(20, 10), b(20, 10);
    for (int y = 0; y < 10; ++y) {
        for (int x = 0; x < 20; ++x) {
            const float depth = 2.0f + 0.05f * float(x) + (x >= 10 ? 0.5f : 0.0f);
            a.depth.at(x, y) = glm::vec3(depth);
            b.depth.at(x, y) = glm::vec3(depth);
        }
    }
    // One interior pixel with a known error: 0.002 world units, 0.2 texel.
    b.depth.at(4, 4) += 0.002f;
    const RenderComparison c = compareRenders(a.view(), b.view());
    EXPECT_EQ(c.bothHit, 200u);
    EXPECT_EQ(c.silhouette.pixels, 20u);
    EXPECT_EQ(c.interior.pixels, 180u);
    EXPECT_NEAR(c.interior.maxHitErrorTexels, 0.2, 1e-3);
    EXPECT_NEAR(c.interior.meanHitErrorTexels, 0.2 / 180.0, 1e-5);
    EXPECT_EQ(c.silhouette.maxHitErrorTexels, 0.0);
}

TEST(CompareRenders, APixelAloneThroughAGapIsASilhouetteNotAnInteriorOutlier) {
    // Both renders hit a plane at depth 2 everywhere, 100 texels per world unit, with B 0.1 texel
    // farther; at (5, 5) B alone sees through a gap to a surface one world unit behind (100
    // texels). Its steps to each neighbour and back the other way on every line through it make
    // it and its 8 neighbours silhouette pixels, so the interior keeps its 0.1 texel.
    Layers a(20, 10), b(20, 10);
    for (glm::vec3& depth : b.depth.rgbLinear) depth += 0.001f;
    b.depth.at(5, 5) = glm::vec3(3.0f);
    const RenderComparison c = compareRenders(a.view(), b.view());
    EXPECT_EQ(c.bothHit, 200u);
    EXPECT_EQ(c.silhouette.pixels, 9u);
    EXPECT_EQ(c.interior.pixels, 191u);
    EXPECT_NEAR(c.interior.maxHitErrorTexels, 0.1, 1e-4);
    EXPECT_NEAR(c.interior.meanHitErrorTexels, 0.1, 1e-4);
    EXPECT_NEAR(c.silhouette.maxHitErrorTexels, 100.0, 1e-3);
    EXPECT_LE(c.interior.meanHitErrorTexels, c.interior.p99HitErrorTexels + 1e-9);
}

TEST(CompareRenders, HeatMapColoursTheHitErrorInTexelsAndDrawsItsColourBar) {
    // 200 x 12 pixels, 128 texels per world unit: depth steps of 1/128 world unit are exactly
    // one texel, and depths of 2 + k/128 are exact floats.
    constexpr int width = 200, height = 12;
    Layers a(width, height), b(width, height);
    for (glm::vec3& scale : a.texelScale.rgbLinear) scale = glm::vec3(128.0f);
    b.depth.at(20, 6) = glm::vec3(2.0f + 1.0f / 128.0f);  // 1 texel: the middle of the scale
    b.depth.at(40, 6) = glm::vec3(0.0f);                  // B misses: a coverage mismatch
    a.depth.at(60, 6) = glm::vec3(0.0f);                  // both miss
    b.depth.at(60, 6) = glm::vec3(0.0f);
    Image heatMap;
    const RenderComparison c = compareRenders(a.view(), b.view(), nullptr, &heatMap);
    EXPECT_EQ(c.coverageMismatches, 1u);
    EXPECT_DOUBLE_EQ(c.maxHitErrorTexels, 1.0);

    ASSERT_EQ(heatMap.width, width);
    ASSERT_EQ(heatMap.height, height + kHeatMapBarHeight);
    // Log scale from 0.01 to 100 texels: 1 texel is halfway, heatColor(0.5), pure green.
    EXPECT_EQ(hitErrorColor(1.0), glm::vec3(0.0f, 1.0f, 0.0f));
    EXPECT_EQ(heatMap.at(20, 6), glm::vec3(0.0f, 1.0f, 0.0f));
    EXPECT_EQ(heatMap.at(21, 6), heatColor(0.0f));              // no error: the bottom of the scale
    EXPECT_EQ(hitErrorColor(1e6), heatColor(1.0f));             // beyond the scale: its top
    EXPECT_EQ(heatMap.at(40, 6), glm::vec3(1.0f, 0.0f, 1.0f));  // magenta
    const glm::vec3 bothMiss = heatMap.at(60, 6);
    EXPECT_EQ(bothMiss.x, bothMiss.y);  // grey
    EXPECT_LT(bothMiss.x, 0.1f);        // dark

    // The colour bar: along a row through it, the colours run from the bottom of the scale on
    // the left to its top on the right; below it, white ticks and labels.
    const int barRow = height + 8;
    int first = -1, last = -1;
    for (int x = 0; x < width; ++x) {
        if (heatMap.at(x, barRow) == glm::vec3(0.0f)) continue;
        if (first < 0) first = x;
        last = x;
    }
    ASSERT_GE(first, 0);
    EXPECT_GT(last - first, width / 2);
    EXPECT_EQ(heatMap.at(first, barRow), heatColor(0.0f));
    EXPECT_EQ(heatMap.at(last, barRow), heatColor(1.0f));
    int whitePixels = 0;
    for (int y = height + 14; y < height + kHeatMapBarHeight; ++y)
        for (int x = 0; x < width; ++x) whitePixels += heatMap.at(x, y) == glm::vec3(1.0f);
    // Five ticks of 3 pixels and the labels "0.01 0.1 1 10 100 texels" (hundreds of pixels).
    EXPECT_GT(whitePixels, 200);
}

}  // namespace
}  // namespace distile
