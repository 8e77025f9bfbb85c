// World-space reference renders (render/world_reference.h, vdb/displaced_level_set.h).
#include "render/world_reference.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "common/error.h"
#include "mesh/base_mesh.h"
#include "render/compare.h"
#include "render/renderer.h"
#include "sampler/bake.h"
#include "vdb/displaced_level_set.h"
#include "vdb/procedural.h"

namespace distile {
namespace {

/// European 4-in-1 chain mail on a 64 x 64 x 16 tile with 2 rings per row and 2 rows: the wire
/// radius is 0.065625 x 32 = 2.1 texels, so a lattice of one sample per texel and voxels of half
/// a texel resolve it (the default 8 x 10 rings would have wires of half a texel).
ProceduralOptions thickChainmail() {
    ProceduralOptions options;
    options.chainmail.ringsPerRow = 2;
    options.chainmail.rowsPerTile = 2;
    return options;
}

Material chainmailMaterial(glm::vec2 uvScale, float depthWorld) {
    BakeOptions bake;
    bake.size = {64, 64, 16};
    static const auto tile =
        std::make_shared<const Tile>(bakeChainmail(thickChainmail().chainmail, bake).tile);
    Material material;
    material.tile = tile;
    material.uvScale = uvScale;
    material.depthWorld = depthWorld;
    material.analyticDistance =
        proceduralDistance(thickChainmail(), tile->size()).signedDistanceTexels;
    return material;
}

RenderComparison compare(const RenderResult& tested, const RenderResult& truth) {
    return compareRenders(
        {tested.image, tested.aovs->depth, tested.aovs->normal, tested.aovs->texelScale},
        {truth.image, truth.aovs->depth, truth.aovs->normal, truth.aovs->texelScale});
}

/// The share of all pixels where both renders hit within `toleranceTexels` of each other along
/// the ray (texels by the truth's texel scale, as compareRenders): unlike the mean, it is not
/// dominated by the few silhouette pixels where one render hits a wire and the other the floor.
double shareAgreeingWithin(const RenderResult& tested, const RenderResult& truth,
                           double toleranceTexels) {
    std::uint64_t agreeing = 0;
    const Image& depthA = tested.aovs->depth;
    for (int y = 0; y < depthA.height; ++y) {
        for (int x = 0; x < depthA.width; ++x) {
            const float a = depthA.at(x, y).x, b = truth.aovs->depth.at(x, y).x;
            const float texelsPerWorld =
                std::max(tested.aovs->texelScale.at(x, y).x, truth.aovs->texelScale.at(x, y).x);
            if (a > 0.0f && b > 0.0f && std::abs(a - b) * texelsPerWorld <= toleranceTexels) {
                ++agreeing;
            }
        }
    }
    return double(agreeing) / (double(depthA.width) * depthA.height);
}

constexpr int kWidth = 160;
constexpr int kHeight = 128;

RenderOptions smallRender(bool reference) {
    RenderOptions options;
    options.width = kWidth;
    options.height = kHeight;
    options.outputAovs = true;
    options.shadowFilter = ShadowFilter::None;
    options.selfShadows = false;
    options.reference = reference;
    return options;
}

WorldReferenceResult worldReference(const Scene& scene, double voxelsPerTexel) {
    WorldReferenceOptions options;
    options.width = kWidth;
    options.height = kHeight;
    options.outputAovs = true;
    options.levelSet.voxelsPerTexel = voxelsPerTexel;  // one lattice sample per texel (default)
    return renderWorldReference(scene, options);
}

void printComparison(const char* what, const RenderComparison& c,
                     const WorldReferenceResult& world) {
    const DisplacedLevelSetStats& levelSet = world.levelSets.at(0);
    std::printf(
        "%s: mean %.4f p99 %.4f max %.4f texels over %llu hits, coverage mismatch %.3f%% "
        "(%llu pixels), normals %.2f deg; level set from %zu polygons (%zu + %zu tile copies), "
        "%zu voxels, %.1f MB, built in %.2f s\n",
        what, c.meanHitErrorTexels, c.p99HitErrorTexels, c.maxHitErrorTexels,
        static_cast<unsigned long long>(c.hitErrorSamples), 100.0 * c.coverageMismatchShare,
        static_cast<unsigned long long>(c.coverageMismatches), c.meanNormalErrorDeg,
        levelSet.meshPolygons, levelSet.tileCopies, levelSet.edgeCopies, levelSet.activeVoxels,
        double(levelSet.memoryBytes) / 1e6, world.buildSeconds);
}

TEST(DisplacedLevelSet, AFlatDetailOnAPlaneIsAPlaneAtItsDepthAcrossTileSeams) {
    // Detail z - D/2: a flat surface half the shell depth below the base plane z = 0. A plane of
    // 1 x 1 world units with 3 x 3 tiles of 32 x 32 x 8 texels: texels of 1/96 world unit, the
    // surface at z = -depth / 2. The centre tile is the shared tile mesh, the 8 around it are
    // extracted with the walls; vertical rays across the tile seams (x = +-1/6) must hit the
    // surface within a tenth of a voxel (the level set of a plane is exact up to float rounding
    // and the intersector's linear interpolation).
    const BaseMesh plane = makePlane(1.0f, 2);
    const double depthWorld = 8.0 / 96.0;
    const DisplacementShell shell{plane.positions, plane.normals, plane.uvs, plane.triangles,
                                  glm::dvec2(3.0), depthWorld,    true};
    const DisplacedLevelSet levelSet = DisplacedLevelSet::build(
        [](const glm::dvec3& texel) { return texel.z - 4.0; }, {32, 32, 8}, shell);
    const DisplacedLevelSetStats& stats = levelSet.stats();
    EXPECT_NEAR(stats.texelSizeWorld, 1.0 / 96.0, 1e-9);
    EXPECT_EQ(stats.tileCopies, 1u);
    EXPECT_EQ(stats.edgeCopies, 8u);
    EXPECT_FALSE(stats.wrapsU);
    EXPECT_FALSE(stats.wrapsV);
    const double tolerance = 0.1 * stats.voxelSizeWorld;
    for (double x : {-0.4, -1.0 / 6.0, 0.0, 1.0 / 6.0, 0.3}) {
        for (double y : {-0.3, -1.0 / 6.0, 0.05, 1.0 / 6.0, 0.45}) {
            double distance = 0.0;
            glm::dvec3 normal;
            ASSERT_TRUE(levelSet.intersect({x, y, 1.0}, {0.0, 0.0, -1.0}, 10.0, distance, normal))
                << x << ", " << y;
            EXPECT_NEAR(distance, 1.0 + depthWorld / 2.0, tolerance) << x << ", " << y;
            EXPECT_GT(normal.z, 0.999) << x << ", " << y;
        }
    }
}

TEST(DisplacedLevelSet, OnATorusTheFloorIsATubeAtTheShellDepth) {
    // No detail (distance 100 texels everywhere): only the solid floor, z = 0 of the shell, a tube
    // of radius r - depth around the torus's centre circle. 4 x 2 tiles of 32 x 32 x 8 on a torus
    // R = 0.75, r = 0.32, depth 0.08: the chart wraps both ways, so every copy is the shared one
    // and the seams must close. Vertical rays onto the tube's crown at several angles (seams at
    // u = 0, v = 0 included) hit at z = r - depth, within a voxel (the base mesh is a polygon of
    // 48 x 32 segments: its chords sag by r (1 - cos(pi / 32)) = 0.0015 world units).
    const float majorRadius = 0.75f, minorRadius = 0.32f;
    const BaseMesh torus = makeTorus(majorRadius, minorRadius, 48, 32);
    const double depthWorld = 0.08;
    const DisplacementShell shell{torus.positions,      torus.normals, torus.uvs, torus.triangles,
                                  glm::dvec2(4.0, 2.0), depthWorld,    true};
    const DisplacedLevelSet levelSet =
        DisplacedLevelSet::build([](const glm::dvec3&) { return 100.0; }, {32, 32, 8}, shell);
    const DisplacedLevelSetStats& stats = levelSet.stats();
    EXPECT_TRUE(stats.wrapsU);
    EXPECT_TRUE(stats.wrapsV);
    EXPECT_EQ(stats.tileCopies, 8u);
    EXPECT_EQ(stats.edgeCopies, 0u);
    for (double angle : {0.0, 0.3, 1.0, 2.5, 4.0}) {
        const glm::dvec3 above(majorRadius * std::cos(angle), majorRadius * std::sin(angle), 1.0);
        double distance = 0.0;
        glm::dvec3 normal;
        ASSERT_TRUE(levelSet.intersect(above, {0.0, 0.0, -1.0}, 10.0, distance, normal)) << angle;
        EXPECT_NEAR(1.0 - distance, minorRadius - depthWorld, stats.voxelSizeWorld) << angle;
    }
}

TEST(DisplacedLevelSet, RejectsBadOptions) {
    const BaseMesh plane = makePlane(1.0f, 1);
    const DisplacementShell shell{plane.positions, plane.normals, plane.uvs, plane.triangles};
    const auto flat = [](const glm::dvec3& texel) { return texel.z - 4.0; };
    DisplacedLevelSetOptions options;
    options.voxelsPerTexel = 0.0;
    EXPECT_THROW(DisplacedLevelSet::build(flat, {32, 32, 8}, shell, options), InputError);
    DisplacementShell noDepth = shell;
    noDepth.depthWorld = 0.0;
    EXPECT_THROW(DisplacedLevelSet::build(flat, {32, 32, 8}, noDepth), InputError);
}

TEST(WorldReference, OnAFlatPlaneItAgreesWithTheAnalyticReference) {
    // A plane of 1 x 1 world units carrying 2 x 2 tiles (texels of 1/128 world unit, cubic with
    // depth 16/128), seen from 45 degrees above; the whole image lies inside the plane, so
    // neither reference sees its edges (the analytic one marches on past them, the world one
    // stops at a wall there). On a plane the shell mapping is exactly the planar one of ch. 8,
    // so the two references differ only by the level set: its mesh is extracted from samples one
    // texel apart (vertices within about 0.1 texel of the true surface on wires of 2.1 texels)
    // and resampled at voxels of half a texel (OpenVDB's intersector interpolates trilinearly).
    Scene scene;
    scene.camera = {{0.0f, -0.15f, 0.15f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    SceneObject plane;
    plane.mesh = makePlane(1.0f, 1);
    plane.material = chainmailMaterial({2.0f, 2.0f}, 16.0f / 128.0f);
    scene.objects.push_back(std::move(plane));

    const RenderResult analytic = renderScene(scene, smallRender(true));
    const WorldReferenceResult world = worldReference(scene, 2.0);
    ASSERT_EQ(world.levelSets.size(), 1u);
    EXPECT_NEAR(world.levelSets[0].texelSizeWorld, 1.0 / 128.0, 1e-6);
    EXPECT_FALSE(world.levelSets[0].wrapsU);
    const RenderComparison c = compare(analytic, world.render);
    printComparison("flat plane, world against analytic reference", c, world);
    const double withinHalfTexel = shareAgreeingWithin(world.render, analytic, 0.5);
    const double withinTenthTexel = shareAgreeingWithin(world.render, analytic, 0.1);
    std::printf("  pixels within 0.5 texel: %.2f%%, within 0.1 texel: %.2f%%\n",
                100.0 * withinHalfTexel, 100.0 * withinTenthTexel);
    // Measured: no coverage mismatch; 96.8% of the pixels within 0.5 texel (one voxel), 59%
    // within 0.1 texel; mean 0.35 texel and p99 12.5 texels, both from the silhouettes, where
    // a shift of a fraction of a texel turns a wire hit into a floor hit 8 texels deeper.
    EXPECT_EQ(c.bothHit, c.pixels);  // the plane fills the image, the floor is solid
    EXPECT_EQ(c.coverageMismatches, 0u);
    EXPECT_GT(withinHalfTexel, 0.93);
    EXPECT_GT(withinTenthTexel, 0.5);
    EXPECT_LT(c.meanHitErrorTexels, 0.5);
    EXPECT_LT(c.meanNormalErrorDeg, 8.0);
}

TEST(WorldReference, OnATorusItMeasuresThePlanarApproximation) {
    // The demo's torus shape with 8 x 4 tiles: an ordinary render (planar tangent frame per pixel,
    // ch. 8) against the world-space reference. The error is what the reference is for: only
    // printed. Asserted: the chart wraps both ways (no walls), the figures are finite and the
    // coverage mostly agrees. Voxels of one texel keep the test quick; the planar error is
    // several texels.
    Scene scene;
    scene.camera = {{0.0f, -2.2f, 1.5f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 38.0f};
    SceneObject torus;
    const float minorRadius = 0.32f;
    torus.mesh = makeTorus(0.75f, minorRadius, 96, 32);
    const float tileWorld = 2.0f * 3.14159265f * minorRadius / 4.0f;
    torus.material = chainmailMaterial({8.0f, 4.0f}, tileWorld * 16.0f / 64.0f);
    scene.objects.push_back(std::move(torus));

    const RenderResult ordinary = renderScene(scene, smallRender(false));
    const WorldReferenceResult world = worldReference(scene, 1.0);
    ASSERT_EQ(world.levelSets.size(), 1u);
    EXPECT_TRUE(world.levelSets[0].wrapsU);
    EXPECT_TRUE(world.levelSets[0].wrapsV);
    EXPECT_EQ(world.levelSets[0].tileCopies, 32u);
    EXPECT_EQ(world.levelSets[0].edgeCopies, 0u);
    const RenderComparison c = compare(ordinary, world.render);
    printComparison("torus, planar approximation against the world reference", c, world);
    std::printf("  pixels within 0.5 texel: %.2f%%, within 2 texels: %.2f%%\n",
                100.0 * shareAgreeingWithin(ordinary, world.render, 0.5),
                100.0 * shareAgreeingWithin(ordinary, world.render, 2.0));
    // Measured (160 x 128): mean 4.2 p99 34.7 texels, coverage mismatch 6.4%, 25% of the
    // pixels within 0.5 texel. The shell is deep (depth = 0.39 of the tube radius): the planar
    // frame keeps the floor solid under every pixel, while in the shell it is a thin tube that
    // rays through the rings' gaps can miss.
    EXPECT_GT(c.hitErrorSamples, c.pixels / 10);
    EXPECT_TRUE(std::isfinite(c.meanHitErrorTexels));
    EXPECT_TRUE(std::isfinite(c.p99HitErrorTexels));
    EXPECT_LT(c.coverageMismatchShare, 0.1);
}

}  // namespace
}  // namespace distile
