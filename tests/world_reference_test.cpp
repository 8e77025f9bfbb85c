// World-space reference renders (render/world_reference.h, vdb/displaced_level_set.h).
#include "render/world_reference.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>

#include "mesh/base_mesh.h"
#include "render/compare.h"
#include "render/renderer.h"
#include "sampler/bake.h"
#include "vdb/procedural.h"

namespace distile {
namespace {

/// A 64 x 64 x 16 chain-mail tile with its analytic distance (small, so the level sets are quick).
Material chainmailMaterial(glm::vec2 uvScale, float depthWorld) {
    BakeOptions bake;
    bake.size = {64, 64, 16};
    static const auto tile = std::make_shared<const Tile>(bakeChainmail({}, bake).tile);
    Material material;
    material.tile = tile;
    material.uvScale = uvScale;
    material.depthWorld = depthWorld;
    material.analyticDistance =
        proceduralDistance(ProceduralOptions{}, tile->size()).signedDistanceTexels;
    return material;
}

RenderComparison compare(const RenderResult& tested, const RenderResult& truth) {
    return compareRenders(
        {tested.image, tested.aovs->depth, tested.aovs->normal, tested.aovs->texelScale},
        {truth.image, truth.aovs->depth, truth.aovs->normal, truth.aovs->texelScale});
}

RenderOptions smallRender(bool reference) {
    RenderOptions options;
    options.width = 160;
    options.height = 128;
    options.outputAovs = true;
    options.shadowFilter = ShadowFilter::None;
    options.selfShadows = false;
    options.reference = reference;
    return options;
}

WorldReferenceResult worldReference(const Scene& scene) {
    WorldReferenceOptions options;
    options.width = 160;
    options.height = 128;
    options.outputAovs = true;  // voxels of half a texel (the default)
    // On a 64-texel tile the default chain mail's wire radius is about half a texel: the
    // isosurface is extracted from 4 samples per texel so no wire falls between samples.
    options.levelSet.samplesPerTexel = 4;
    options.levelSet.voxelsPerTexel = 8.0;
    return renderWorldReference(scene, options);
}

TEST(WorldReference, OnAFlatPlaneItAgreesWithTheAnalyticReference) {
    // A plane of 1 x 1 world units carrying 2 x 2 tiles (texels of 1/128 world unit, cubic with
    // depth 16/128), seen from 35 degrees above, the plane filling the image. On a plane the
    // shell mapping is exactly the planar one of ch. 8, so the two references differ only by the
    // level set: its mesh extracted at 1 sample per texel and re-sampled at voxels of half a
    // texel. Tolerance 0.1 texel mean (a fifth of a voxel); measured: see the printout.
    Scene scene;
    scene.camera = {{0.0f, -0.55f, 0.385f}, {0.0f, -0.2f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    SceneObject plane;
    plane.mesh = makePlane(1.0f, 1);
    plane.material = chainmailMaterial({2.0f, 2.0f}, 16.0f / 128.0f);
    scene.objects.push_back(std::move(plane));

    const RenderResult analytic = renderScene(scene, smallRender(true));
    const WorldReferenceResult world = worldReference(scene);
    ASSERT_EQ(world.levelSets.size(), 1u);
    EXPECT_NEAR(world.levelSets[0].texelSizeWorld, 1.0 / 128.0, 1e-6);
    EXPECT_FALSE(world.levelSets[0].wrapsU);
    const RenderComparison c = compare(analytic, world.render);
    std::printf(
        "flat: mean %.4f p99 %.4f max %.4f texels over %llu hits, coverage mismatch %.3f%%, "
        "normals %.2f deg; level set %zu voxels, %.1f MB, built in %.2f s\n",
        c.meanHitErrorTexels, c.p99HitErrorTexels, c.maxHitErrorTexels,
        static_cast<unsigned long long>(c.hitErrorSamples), 100.0 * c.coverageMismatchShare,
        c.meanNormalErrorDeg, world.levelSets[0].activeVoxels, world.levelSets[0].memoryBytes / 1e6,
        world.buildSeconds);
    EXPECT_GT(c.hitErrorSamples, 0.5 * double(c.pixels));
    EXPECT_LT(c.meanHitErrorTexels, 0.1);
    EXPECT_LT(c.coverageMismatchShare, 0.01);
}

TEST(WorldReference, OnATorusItMeasuresThePlanarApproximation) {
    // The demo's torus shape with 4 x 2 tiles: an ordinary render (planar tangent frame per pixel,
    // ch. 8) against the world-space reference. Only printed: its size is what the reference is
    // for. Asserted: finite figures and mostly the same coverage.
    Scene scene;
    scene.camera = {{0.0f, -2.2f, 1.5f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 38.0f};
    SceneObject torus;
    const float minorRadius = 0.32f;
    torus.mesh = makeTorus(0.75f, minorRadius, 96, 32);
    const float tileWorld = 2.0f * 3.14159265f * minorRadius / 2.0f;
    torus.material = chainmailMaterial({4.0f, 2.0f}, tileWorld * 16.0f / 64.0f);
    scene.objects.push_back(std::move(torus));

    const RenderResult ordinary = renderScene(scene, smallRender(false));
    const WorldReferenceResult world = worldReference(scene);
    ASSERT_EQ(world.levelSets.size(), 1u);
    EXPECT_TRUE(world.levelSets[0].wrapsU);
    EXPECT_TRUE(world.levelSets[0].wrapsV);
    const RenderComparison c = compare(ordinary, world.render);
    std::printf(
        "torus, planar approximation: mean %.4f p99 %.4f max %.4f texels over %llu hits, "
        "coverage mismatch %.3f%%, normals %.2f deg; level set %zu voxels, %.1f MB, "
        "built in %.2f s\n",
        c.meanHitErrorTexels, c.p99HitErrorTexels, c.maxHitErrorTexels,
        static_cast<unsigned long long>(c.hitErrorSamples), 100.0 * c.coverageMismatchShare,
        c.meanNormalErrorDeg, world.levelSets[0].activeVoxels, world.levelSets[0].memoryBytes / 1e6,
        world.buildSeconds);
    EXPECT_GT(c.hitErrorSamples, 0u);
    EXPECT_TRUE(std::isfinite(c.meanHitErrorTexels));
    EXPECT_TRUE(std::isfinite(c.p99HitErrorTexels));
    EXPECT_LT(c.coverageMismatchShare, 0.05);
}

}  // namespace
}  // namespace distile
