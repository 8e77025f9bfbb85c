// The peers of `distile bench` (bench/peers/peers.h) against distile's reference render on a small
// sheet: where both hit, the depth along the same camera ray must agree to within the peer's own
// accuracy, converted to texels with the reference's texel scale.
#include "bench/peers/peers.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <vector>

#include "bake/bake.h"
#include "common/error.h"
#include "render/renderer.h"

namespace distile {
namespace {

constexpr int kWidth = 64;
constexpr int kHeight = 48;
/// Pixels whose coverage may differ where the sheet's open edge cuts a ring: 0.5% of the view
/// (measured: none at the 0.02-texel bound, 4 at 0.1).
constexpr int kEdgePixels = kWidth * kHeight / 200;

/// A small data/scenes/sheet.json: one 64 x 64 x 16 tile of chain mail (2 x 2 rings of the default
/// proportions: spacing 32 texels, R = 22.5, r = 2.1) on a plane of side 1 with cubic texels
/// (64 per world unit, depth 16 / 64), seen from the sheet's camera scaled to the plane.
Scene smallSheet() {
    ChainmailOptions chainmail;
    chainmail.ringsPerRow = 2;
    chainmail.rowsPerTile = 2;
    BakeOptions bake;
    bake.size = {64, 64, 16};
    static const auto tile = std::make_shared<const Tile>(bakeChainmail(chainmail, bake).tile);
    Scene scene;
    scene.camera = {{0.0f, -0.525f, 0.3675f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    SceneObject sheet;
    sheet.mesh = makePlane(1.0f, 1);
    sheet.material.tile = tile;
    sheet.material.depthWorld = 0.25f;
    ProceduralOptions procedural;
    procedural.chainmail = chainmail;
    sheet.material.analyticDistance =
        proceduralDistance(procedural, tile->size()).signedDistanceTexels;
    scene.objects.push_back(std::move(sheet));
    return scene;
}

const RenderAovs& reference() {
    static const RenderAovs aovs = [] {
        RenderOptions options;
        options.width = kWidth;
        options.height = kHeight;
        options.reference = true;
        options.outputAovs = true;
        options.shadowFilter = ShadowFilter::None;
        options.selfShadows = false;
        return *renderScene(smallSheet(), options).aovs;
    }();
    return aovs;
}

struct DepthAgreement {
    int referenceHits = 0;
    int peerHits = 0;
    int peerOnly = 0;                  ///< pixels the peer hits and the reference misses
    std::vector<double> errorsTexels;  ///< |depth difference| x texel scale where both hit, sorted
    double quantile(double q) const {
        return errorsTexels[std::size_t(q * double(errorsTexels.size() - 1))];
    }
    double shareAbove(double texels) const {
        return double(errorsTexels.end() -
                      std::upper_bound(errorsTexels.begin(), errorsTexels.end(), texels)) /
               double(errorsTexels.size());
    }
};

DepthAgreement agreement(const PeerRender& peer) {
    const RenderAovs& truth = reference();
    DepthAgreement result;
    for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) {
            const float truthDepth = truth.depth.at(x, y).x;
            const float peerDepth = peer.depth.at(x, y).x;
            result.referenceHits += truthDepth > 0.0f;
            result.peerHits += peerDepth > 0.0f;
            result.peerOnly += peerDepth > 0.0f && truthDepth == 0.0f;
            if (!(truthDepth > 0.0f && peerDepth > 0.0f)) continue;
            result.errorsTexels.push_back(std::abs(double(peerDepth) - double(truthDepth)) *
                                          truth.texelScale.at(x, y).x);
        }
    }
    std::sort(result.errorsTexels.begin(), result.errorsTexels.end());
    std::printf(
        "%s: %d hits of %d reference hits (%d not in it); error texels median %.4f, p95 "
        "%.4f, p99 %.4f, max %.4f, share > 0.1: %.4f\n",
        peer.name.c_str(), result.peerHits, result.referenceHits, result.peerOnly,
        result.quantile(0.5), result.quantile(0.95), result.quantile(0.99),
        result.errorsTexels.back(), result.shareAbove(0.1));
    return result;
}

TEST(EmbreePeer, HitsTheReferenceSurfaceWithinTheTessellationBound) {
    const PeerRender peer = renderSheetWithEmbree(smallSheet(), kWidth, kHeight, 2);
    if (!peer.available) GTEST_SKIP() << peer.unavailableReason;
    EXPECT_GT(peer.memoryBytes, 0u);
    const DepthAgreement a = agreement(peer);
    // The floor is part of the Embree scene and only rays entering through the base mesh are
    // traced, so both cover the same pixels, but where the plane's open edge cuts a ring: a ray
    // that meets the ring within the tessellation bound of the cut can hit inside the edge in one
    // and leave the shell beyond it in the other (a pixel here and there along the edges).
    EXPECT_LE(std::abs(a.peerHits - a.referenceHits), kEdgePixels);
    EXPECT_LE(a.peerOnly, kEdgePixels);
    // Faces lie within the default tessellation bound (0.02 texel) of the surface; along the ray
    // that is 0.02 / cos(incidence); the reference converges to 1e-3 texel, float rays add ~1e-4.
    EXPECT_LT(a.quantile(0.5), 0.5 * EmbreePeerOptions{}.tessellationErrorTexels);
    EXPECT_LT(a.quantile(0.95), 0.1);
    // Silhouettes: a ray grazing a wire within 0.02 texel hits the true surface but passes the
    // inscribed faces and lands on what is behind (measured: 0.3% of the pixels here).
    EXPECT_LT(a.shareAbove(0.1), 0.01);
}

TEST(EmbreePeer, PacketsOfQuadsAtACoarserBoundHitWithinThatBound) {
    EmbreePeerOptions options;
    options.tessellationErrorTexels = 0.1;
    options.raysPerPacket = embreeNativePacketWidth();
    options.quads = true;
    options.highQualityBvh = true;
    const PeerRender peer = renderSheetWithEmbree(smallSheet(), kWidth, kHeight, 2, options);
    if (!peer.available) GTEST_SKIP() << peer.unavailableReason;
    const DepthAgreement a = agreement(peer);
    EXPECT_LE(std::abs(a.peerHits - a.referenceHits), kEdgePixels);  // as above
    EXPECT_LE(a.peerOnly, kEdgePixels);
    // The faces lie inside the rings, at most 0.1 texel from the surface (0.1 / cos(incidence)
    // along the ray); a typical hit is well inside that, as at the finer bound above.
    EXPECT_LT(a.quantile(0.5), 0.5 * options.tessellationErrorTexels);
    EXPECT_LT(a.quantile(0.95), 5.0 * options.tessellationErrorTexels);
}

/// Pixels where two renders of the same Embree scene differ: in coverage, or in depth by more
/// than `relative` of it.
int differingPixels(const PeerRender& a, const PeerRender& b, float relative) {
    int differing = 0;
    for (int y = 0; y < a.depth.height; ++y)
        for (int x = 0; x < a.depth.width; ++x) {
            const float depthA = a.depth.at(x, y).x;
            const float depthB = b.depth.at(x, y).x;
            differing += (depthA > 0.0f) != (depthB > 0.0f) ||
                         std::abs(depthA - depthB) > relative * std::max(depthA, depthB);
        }
    return differing;
}

TEST(EmbreePeer, PacketsAndQuadsHitWhatSingleRaysOnTrianglesHit) {
    // Not a multiple of any tile size: the last packets of each row and column are partly empty.
    constexpr int kOddWidth = 61;
    constexpr int kOddHeight = 45;
    EmbreePeerOptions single;
    single.tessellationErrorTexels = 0.05;
    const PeerRender singleRays =
        renderSheetWithEmbree(smallSheet(), kOddWidth, kOddHeight, 2, single);
    if (!singleRays.available) GTEST_SKIP() << singleRays.unavailableReason;
    int hits = 0;
    for (const glm::vec3& depth : singleRays.depth.rgbLinear) hits += depth.x > 0.0f;
    ASSERT_GT(hits, kOddWidth * kOddHeight / 2);
    for (const int rays : {4, 8, 16}) {
        for (const bool quads : {false, true}) {
            EmbreePeerOptions options = single;
            options.raysPerPacket = rays;
            options.quads = quads;
            const PeerRender packets =
                renderSheetWithEmbree(smallSheet(), kOddWidth, kOddHeight, 2, options);
            if (!packets.available) continue;  // no native packets of this width
            const int differing = differingPixels(singleRays, packets, 1e-5f);
            std::printf("%d rays per packet, %s: %d of %d pixels differ\n", rays,
                        quads ? "quads" : "triangles", differing, kOddWidth * kOddHeight);
            // The same planar faces (a quad is its two triangles) and the same rays: the hits
            // agree to float rounding (1e-5 of the depth); a ray through a shared edge or
            // grazing a silhouette may land on either side (measured: no pixel here).
            EXPECT_LE(differing, kOddWidth * kOddHeight / 1000)
                << rays << " rays per packet, quads " << quads;
        }
    }
}

TEST(EmbreePeer, CallsItsHookBeforeEachTraceAndRefusesBadOptions) {
    EmbreePeerOptions options;
    options.tessellationErrorTexels = 0.2;
    options.traceRuns = 3;
    int calls = 0;
    options.beforeEachTrace = [&] { ++calls; };
    const PeerRender peer = renderSheetWithEmbree(smallSheet(), 16, 16, 1, options);
    if (!peer.available) GTEST_SKIP() << peer.unavailableReason;
    EXPECT_EQ(calls, 3);
    EXPECT_GT(peer.traceSeconds, 0.0);
    for (const auto& change : std::vector<std::function<void(EmbreePeerOptions&)>>{
             [](EmbreePeerOptions& o) { o.tessellationErrorTexels = 0.0; },
             [](EmbreePeerOptions& o) { o.tessellationErrorTexels = std::nan(""); },
             [](EmbreePeerOptions& o) { o.raysPerPacket = 2; },
             [](EmbreePeerOptions& o) { o.traceRuns = 0; }}) {
        EmbreePeerOptions bad;
        change(bad);
        EXPECT_THROW(renderSheetWithEmbree(smallSheet(), 16, 16, 1, bad), InputError);
    }
}

TEST(VdbRenderPeer, HitsTheReferenceSurfaceWithinTheLevelSetAccuracy) {
    const std::filesystem::path workDir = std::filesystem::temp_directory_path() /
                                          ("distile_peers_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(workDir);
    const PeerRender peer = renderSheetWithVdbRender(smallSheet(), kWidth, kHeight, 2, workDir);
    std::filesystem::remove_all(workDir);
    if (!peer.available) GTEST_SKIP() << peer.unavailableReason;
    EXPECT_GT(peer.memoryBytes, 0u);
    const DepthAgreement a = agreement(peer);
    // The level set has no floor: the peer hits the rings only, a subset of the reference's hits.
    EXPECT_EQ(a.peerOnly, 0);
    EXPECT_GT(a.peerHits, a.referenceHits / 4);
    // vdb_render interpolates the exact distances of a 1-texel grid trilinearly and finds the root
    // linearly between its ray-march samples: on a wire of radius 2.1 texels the interpolated
    // surface sits some h^2 / (8 r) ~ 0.06 texel inside (measured: median 0.056, p95 0.23 texel);
    // silhouettes and contacts between rings, where the grid cannot resolve the gap, do worse.
    EXPECT_LT(a.quantile(0.5), 0.1);
    EXPECT_LT(a.quantile(0.95), 0.5);
}

}  // namespace
}  // namespace distile
