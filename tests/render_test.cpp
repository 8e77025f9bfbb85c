// Tests of render/: the ch. 8 march lands exactly on known surfaces, the base-mesh BVH finds the
// same hits as brute force, and whole renders are finite and thread-count independent.
#include <gtest/gtest.h>

#include <tbb/global_control.h>

#include <cmath>
#include <random>

#include <glm/geometric.hpp>

#include "common/error.h"
#include "render/bvh.h"
#include "render/march.h"
#include "render/renderer.h"
#include "sampler/filters.h"

namespace distile {
namespace {

constexpr float kPi = 3.14159265f;

/// A tile whose detail is the horizontal plane z = heightTexels (solid below).
Tile flatTile(const Size3& size, float heightTexels) {
    Tile tile(size);
    for (int z = 0; z < size.depth; ++z)
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x) tile.at(x, y, z) = (z + 0.5f) - heightTexels;
    return tile;
}

TEST(March, LandsOnAFlatDetailPlane) {
    // The tile holds the exact distance to z = 4 (trilinear reproduces it below the top half
    // texel, and underestimates it above, which is safe), so every step is exact along the ray:
    // the march converges geometrically onto the plane, never through it.
    const Tile tile = flatTile({32, 32, 16}, 4.0f);
    const TrilinearFilter filter(tile);
    for (float elevationDeg : {90.0f, 60.0f, 30.0f, 10.0f, 3.0f}) {
        for (float azimuthDeg : {0.0f, 45.0f, 200.0f}) {
            const float elevation = elevationDeg * kPi / 180.0f;
            const float azimuth = azimuthDeg * kPi / 180.0f;
            const glm::vec3 direction{std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                                      -std::sin(elevation)};
            const glm::vec3 entry{7.25f, 19.5f, 16.0f};
            const float epsilon = 1e-4f;
            const MarchResult result = march(filter, entry, direction, Floor::Solid, 4096, epsilon);
            ASSERT_TRUE(result.converged) << elevationDeg;
            EXPECT_FALSE(result.onFloor);
            EXPECT_GE(result.texelPosition.z, 4.0f - 1e-4f) << elevationDeg;  // never below the surface
            EXPECT_NEAR(result.texelPosition.z, 4.0f, 2e-4f) << elevationDeg;
            // On the ray: the travelled length reproduces the end point.
            const glm::vec3 expected = entry + direction * result.travelTexels;
            EXPECT_NEAR(glm::length(result.texelPosition - expected), 0.0f, 1e-3f);
            EXPECT_NEAR(result.travelTexels, (16.0f - 4.0f) / std::sin(elevation), 2e-3f / std::sin(elevation));
        }
    }
}

TEST(March, HitsTheSolidFloorExactlyOrPassesAnOpenOne) {
    // An empty tile (all distances 100): the first step crosses z = 0, where the floor is hit
    // exactly, in one iteration.
    Tile empty({16, 16, 8}, 100.0f);
    const TrilinearFilter filter(empty);
    const glm::vec3 direction = glm::normalize(glm::vec3(0.3f, -0.2f, -1.0f));
    const glm::vec3 entry{3.0f, 3.0f, 8.0f};
    const MarchResult solid = march(filter, entry, direction, Floor::Solid, 16, 0.01f);
    EXPECT_TRUE(solid.onFloor);
    EXPECT_EQ(solid.iterations, 1);
    EXPECT_EQ(solid.texelPosition.z, 0.0f);
    EXPECT_NEAR(solid.texelPosition.x, 3.0f + 0.3f * 8.0f, 1e-5f);
    EXPECT_NEAR(solid.texelPosition.y, 3.0f - 0.2f * 8.0f, 1e-5f);
    const MarchResult open = march(filter, entry, direction, Floor::Open, 16, 0.01f);
    EXPECT_TRUE(open.exitedFloor);
    EXPECT_FALSE(open.converged);
}

TEST(TriangleBvh, FindsTheSameNearestHitAsBruteForce) {
    std::mt19937 random(5);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::vector<glm::vec3> corners;
    for (int i = 0; i < 3 * 500; ++i) corners.emplace_back(unit(random), unit(random), unit(random));
    const TriangleBvh bvh(corners);
    int hits = 0;
    for (int i = 0; i < 2000; ++i) {
        const Ray ray{glm::vec3(unit(random), unit(random), 3.0f),
                      glm::normalize(glm::vec3(0.3f * unit(random), 0.3f * unit(random), -1.0f))};
        // Brute force, the same double-precision test the BVH uses, on every triangle.
        float nearest = std::numeric_limits<float>::max();
        int nearestTriangle = -1;
        for (int t = 0; t < 500; ++t) {
            const TriangleBvh single({corners[3 * t], corners[3 * t + 1], corners[3 * t + 2]});
            TriangleHit hit;
            if (single.intersect(ray, 0.0f, nearest, hit)) {
                nearest = hit.distanceWorld;
                nearestTriangle = t;
            }
        }
        TriangleHit hit;
        const bool found = bvh.intersect(ray, 0.0f, std::numeric_limits<float>::max(), hit);
        ASSERT_EQ(found, nearestTriangle >= 0);
        if (found) {
            ++hits;
            EXPECT_EQ(int(hit.triangle), nearestTriangle);
            EXPECT_FLOAT_EQ(hit.distanceWorld, nearest);
        }
    }
    EXPECT_GT(hits, 500);  // the test exercised hits, not only misses
}

TEST(TriangleBvh, RaysThroughASharedEdgeDoNotSlipBetweenTriangles) {
    // Two triangles of a unit quad share the diagonal x = y; rays aimed at points on it must hit.
    const TriangleBvh quad({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}});
    for (int i = 0; i <= 1000; ++i) {
        const float s = 0.0005f + 0.999f * float(i) / 1000.0f;
        const glm::vec3 target(s, s, 0.0f);
        const glm::vec3 origin(0.37f, -0.61f, 2.0f);
        TriangleHit hit;
        ASSERT_TRUE(quad.intersect({origin, glm::normalize(target - origin)}, 0.0f, 100.0f, hit)) << s;
        EXPECT_NEAR(hit.distanceWorld, glm::length(target - origin), 1e-5f);
    }
}

Scene planeScene(std::shared_ptr<const Tile> tile) {
    Scene scene;
    scene.camera = {{0.3f, -1.6f, 1.2f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    SceneObject plane;
    plane.mesh = makePlane(2.0f, 1);
    plane.material.tile = std::move(tile);
    plane.material.uvScale = {2.0f, 2.0f};
    plane.material.depthWorld = 1.0f / 16.0f * 16.0f / 32.0f;
    scene.objects.push_back(std::move(plane));
    return scene;
}

TEST(Renderer, ImageIsFiniteAndIndependentOfTheThreadCount) {
    // A wavy height field: distances are a bound, not exact, but any bug that produces NaN or a
    // thread-dependent pixel shows here.
    Tile tile({32, 32, 16});
    for (int z = 0; z < 16; ++z)
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 32; ++x)
                tile.at(x, y, z) = 0.5f * ((z + 0.5f) - (8.0f + 4.0f * std::sin(2 * kPi * (x + 0.5f) / 32) *
                                                                    std::cos(2 * kPi * (y + 0.5f) / 32)));
    const Scene scene = planeScene(std::make_shared<const Tile>(std::move(tile)));
    RenderOptions options;
    options.width = 96;
    options.height = 64;
    options.outputAovs = true;
    RenderResult first;
    {
        tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
        first = renderScene(scene, options);
    }
    RenderResult second;
    {
        tbb::global_control pair(tbb::global_control::max_allowed_parallelism, 2);
        second = renderScene(scene, options);
    }
    const Image& one = first.image;
    const Image& two = second.image;
    const RenderStats& stats = first.stats;
    EXPECT_EQ(first.aovs->depth.rgbLinear, second.aovs->depth.rgbLinear);
    EXPECT_EQ(first.aovs->iterations.rgbLinear, second.aovs->iterations.rgbLinear);
    ASSERT_EQ(one.rgbLinear.size(), two.rgbLinear.size());
    for (std::size_t i = 0; i < one.rgbLinear.size(); ++i) {
        ASSERT_TRUE(std::isfinite(one.rgbLinear[i].x) && std::isfinite(one.rgbLinear[i].y) &&
                    std::isfinite(one.rgbLinear[i].z));
        ASSERT_EQ(one.rgbLinear[i], two.rgbLinear[i]) << "pixel " << i;
    }
    EXPECT_EQ(stats.rays, std::uint64_t(96 * 64));
    EXPECT_GT(stats.baseHits, stats.rays / 2);  // the plane fills most of the view
}

TEST(Renderer, RejectsBadOptionsAndScenes) {
    const Scene scene = planeScene(std::make_shared<const Tile>(Size3{8, 8, 4}, 1.0f));
    RenderOptions options;
    options.width = 0;
    EXPECT_THROW(renderScene(scene, options), InputError);
    Scene noObjects = scene;
    noObjects.objects.clear();
    EXPECT_THROW(renderScene(noObjects, RenderOptions{}), InputError);
    Scene badCamera = scene;
    badCamera.camera.eye.x = std::nanf("");
    EXPECT_THROW(renderScene(badCamera, RenderOptions{}), InputError);
    Scene badDepth = scene;
    badDepth.objects[0].material.depthWorld = -1.0f;
    EXPECT_THROW(renderScene(badDepth, RenderOptions{}), InputError);
}

}  // namespace
}  // namespace distile
