// Tests of render/: the ch. 8 march lands exactly on known surfaces, the base-mesh BVH finds the
// same hits as brute force, and whole renders are finite and thread-count independent.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "common/error.h"
#include "common/simd.h"
#include "render/bvh.h"
#include "render/coverage.h"
#include "render/detail/disk_pattern.h"
#include "render/image.h"
#include "render/march.h"
#include "render/renderer.h"
#include "render/shadow_map.h"
#include "sampler/filters.h"
#include "sampler/tile_columns.h"
#include "tests/on_threads.h"

namespace distile {
namespace {

constexpr float kPi = 3.14159265f;

/// The one map of a light over a scene whose receivers form one group (shadowMapAreas).
const ShadowMap& onlyMap(const LightShadowMaps& maps) {
    EXPECT_EQ(maps.size(), 1u);
    return maps[0];
}

/// A tile whose detail is the horizontal plane z = heightTexels (solid below).
Tile flatTile(const Size3& size, float heightTexels) {
    Tile tile(size);
    for (int z = 0; z < size.depth; ++z)
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x) tile.at(x, y, z) = (z + 0.5f) - heightTexels;
    return tile;
}

TEST(March, LandsOnAFlatDetailPlane) {
    // The tile holds the exact distance to z = 4 (trilinear reproduces it up to the top z = D,
    // extending the top cell linearly), so every step is exact along the ray: the march converges
    // geometrically onto the plane, never through it.
    const Tile tile = flatTile({32, 32, 16}, 4.0f);
    const TrilinearFilter filter(tile);
    for (float elevationDeg : {90.0f, 60.0f, 30.0f, 10.0f, 3.0f}) {
        for (float azimuthDeg : {0.0f, 45.0f, 200.0f}) {
            const float elevation = elevationDeg * kPi / 180.0f;
            const float azimuth = azimuthDeg * kPi / 180.0f;
            const glm::vec3 direction{std::cos(elevation) * std::cos(azimuth),
                                      std::cos(elevation) * std::sin(azimuth),
                                      -std::sin(elevation)};
            const glm::vec3 entry{7.25f, 19.5f, 16.0f};
            const float epsilon = 1e-4f;
            const MarchResult result = march(filter, entry, direction, Floor::Solid, 4096, epsilon);
            ASSERT_TRUE(result.converged) << elevationDeg;
            EXPECT_FALSE(result.onFloor);
            EXPECT_GE(result.texelPosition.z, 4.0f - 1e-4f)
                << elevationDeg;  // never below the surface
            EXPECT_NEAR(result.texelPosition.z, 4.0f, 2e-4f) << elevationDeg;
            // On the ray: the travelled length reproduces the end point.
            const glm::vec3 expected = entry + direction * result.travelTexels;
            EXPECT_NEAR(glm::length(result.texelPosition - expected), 0.0f, 1e-3f);
            EXPECT_NEAR(result.travelTexels, (16.0f - 4.0f) / std::sin(elevation),
                        2e-3f / std::sin(elevation));
        }
    }
}

TEST(March, EveryMethodLandsOnAFlatDetailPlane) {
    // The exact plane z = 4 (as above): over-relaxed and budgeted sphere tracing reach it within
    // epsilon; fixed steps and relief mapping bracket it and refine linearly (exact on a linear
    // field) or by bisection (halving a bracket of at most 28 texels 12 times: < 0.01 texel).
    const Tile tile = flatTile({32, 32, 16}, 4.0f);
    const TrilinearFilter filter(tile);
    for (MarchMethod method :
         {MarchMethod::SphereTracing, MarchMethod::OverRelaxed, MarchMethod::Budgeted,
          MarchMethod::Relief, MarchMethod::FixedSteps}) {
        for (float elevationDeg : {90.0f, 30.0f, 3.0f}) {
            const float elevation = elevationDeg * kPi / 180.0f;
            const glm::vec3 direction{std::cos(elevation) * 0.6f, std::cos(elevation) * 0.8f,
                                      -std::sin(elevation)};
            MarchSettings settings;
            settings.method = method;
            settings.maxIterations = method == MarchMethod::Relief ? 48 : 4096;
            settings.epsilonTexels = 1e-3f;
            const MarchResult result =
                march(filter, glm::vec3{7.25f, 19.5f, 16.0f}, direction, Floor::Solid, settings);
            const char* name = marchMethodName(method);
            ASSERT_TRUE(result.converged) << name << " " << elevationDeg;
            EXPECT_FALSE(result.onFloor) << name;
            EXPECT_LE(result.iterations, settings.maxIterations) << name;
            const float tolerance = method == MarchMethod::Relief ? 0.01f : 2e-3f;
            EXPECT_NEAR(result.texelPosition.z, 4.0f, tolerance) << name << " " << elevationDeg;
            EXPECT_NEAR(result.travelTexels, 12.0f / std::sin(elevation),
                        tolerance / std::sin(elevation))
                << name << " " << elevationDeg;
        }
    }
}

TEST(March, TheBudgetedMarchsSecantStepsReachAPlaneInFewSamples) {
    // The exact plane z = 4, 12 texels below the start. A sphere step along a ray at elevation e
    // leaves (1 - sin e) of the distance, so sphere tracing needs 15 samples at 30 degrees (12 /
    // 2^14 < 1e-3) and 6 at 60. The budgeted march steps toward where the last two samples' line
    // reaches zero, at most 1 texel beyond the distance: at 30 degrees from t = 0 (distance 12)
    // by 12, then 7, 3.5 and 1.5 onto the plane (t = 24): 5 samples; at 60 degrees by 12, then
    // the whole 1.857 left: 3 samples.
    const Tile tile = flatTile({32, 32, 16}, 4.0f);
    const TrilinearFilter filter(tile);
    for (const auto& [elevationDeg, sphereSamples, budgetedSamples] :
         {std::tuple{30.0f, 15, 5}, std::tuple{60.0f, 6, 3}}) {
        const float elevation = elevationDeg * kPi / 180.0f;
        const glm::vec3 direction{std::cos(elevation) * 0.6f, std::cos(elevation) * 0.8f,
                                  -std::sin(elevation)};
        for (MarchMethod method : {MarchMethod::SphereTracing, MarchMethod::Budgeted}) {
            MarchSettings settings;
            settings.method = method;
            settings.maxIterations = 4096;
            settings.epsilonTexels = 1e-3f;
            const MarchResult result =
                march(filter, glm::vec3{7.25f, 19.5f, 16.0f}, direction, Floor::Solid, settings);
            const char* name = marchMethodName(method);
            ASSERT_TRUE(result.converged) << name << " " << elevationDeg;
            EXPECT_EQ(result.iterations,
                      method == MarchMethod::Budgeted ? budgetedSamples : sphereSamples)
                << name << " " << elevationDeg;
            EXPECT_NEAR(result.texelPosition.z, 4.0f, 1e-3f) << name << " " << elevationDeg;
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

TEST(March, InterleavedMarchesAreBitIdenticalToSingleOnes) {
    // Spheres of radius 5 texels repeating every 16 texels (exact distances): rays at 2 to 80
    // degrees, every sphere-tracing method, budgets small enough to run out and to force the
    // budgeted march's long steps past the surface (regula falsi), NaN rays and a ray far out
    // (x = 3e9, beyond the wide filter's near case). Interleaving only reorders independent rays,
    // so every field of every result must be equal, through marchInterleaved (the wide kernel of
    // render/march_wide.h where the processor has it) and through the scalar interleave.
    const Size3 size{32, 32, 16};
    Tile tile(size);
    for (int z = 0; z < size.depth; ++z)
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x) {
                const glm::vec3 local(std::fmod(x + 0.5f, 16.0f), std::fmod(y + 0.5f, 16.0f),
                                      z + 0.5f);
                tile.at(x, y, z) = glm::length(local - glm::vec3(8.0f, 8.0f, 7.0f)) - 5.0f;
            }
    const TileColumns columns(tile);
    const BasicTrilinearFilter<ColumnTexels> filter(columns);
    std::mt19937 random(3);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    int converged = 0, outOfBudget = 0, refused = 0;
    for (MarchMethod method :
         {MarchMethod::SphereTracing, MarchMethod::OverRelaxed, MarchMethod::Budgeted}) {
        for (int budget : {3, 8, 16}) {
            MarchSettings settings;
            settings.method = method;
            settings.maxIterations = budget;
            // Not a multiple of the lanes; more than one call of the wide kernel (64 rays), and
            // more than its two groups of sixteen lanes take at once (refills, the last rays
            // moved into one group).
            constexpr int kRays = 101;
            std::vector<glm::vec3> starts, directions;
            for (int i = 0; i < kRays; ++i) {
                const float elevation = (2.0f + 78.0f * unit(random)) * kPi / 180.0f;
                const float azimuth = 2.0f * kPi * unit(random);
                directions.emplace_back(std::cos(elevation) * std::cos(azimuth),
                                        std::cos(elevation) * std::sin(azimuth),
                                        -std::sin(elevation));
                starts.emplace_back(32.0f * unit(random), 32.0f * unit(random), 16.0f);
            }
            starts[5].x = std::nanf("");
            starts[11].x = 3.0e9f;
            std::vector<detail::SphereTraceRay> rays(kRays), scalarRays(kRays);
            std::vector<detail::SphereTraceRay*> pointers, scalarPointers;
            std::vector<MarchResult> single;
            for (int i = 0; i < kRays; ++i) {
                single.push_back(march(filter, starts[i], directions[i], Floor::Solid, settings));
                if (refusedMarch(starts[i], directions[i], settings)) {
                    ++refused;
                    continue;
                }
                rays[i].start(starts[i], directions[i], Floor::Solid, settings);
                pointers.push_back(&rays[i]);
                scalarRays[i].start(starts[i], directions[i], Floor::Solid, settings);
                scalarPointers.push_back(&scalarRays[i]);
            }
            marchInterleaved(filter, std::span<detail::SphereTraceRay* const>(pointers));
            detail::marchInterleavedScalar(
                filter, std::span<detail::SphereTraceRay* const>(scalarPointers));
            for (int i = 0; i < kRays; ++i) {
                if (i == 5) continue;
                const MarchResult& a = single[i];
                for (const MarchResult& b : {rays[i].result(), scalarRays[i].result()}) {
                    const std::string what = std::string(marchMethodName(method)) + " budget " +
                                             std::to_string(budget) + " ray " + std::to_string(i);
                    EXPECT_EQ(a.texelPosition.x, b.texelPosition.x) << what;
                    EXPECT_EQ(a.texelPosition.y, b.texelPosition.y) << what;
                    EXPECT_EQ(a.texelPosition.z, b.texelPosition.z) << what;
                    EXPECT_EQ(a.travelTexels, b.travelTexels) << what;
                    EXPECT_EQ(a.iterations, b.iterations) << what;
                    EXPECT_EQ(a.converged, b.converged) << what;
                    EXPECT_EQ(a.onFloor, b.onFloor) << what;
                    EXPECT_EQ(a.exitedFloor, b.exitedFloor) << what;
                }
                (a.converged ? converged : outOfBudget) += 1;
            }
        }
    }
    // The rays took both ends: converged (surface or floor) and out of budget.
    EXPECT_GT(converged, 100);
    EXPECT_GT(outOfBudget, 20);
    EXPECT_EQ(refused, 9);
}

TEST(TriangleBvh, FindsTheSameNearestHitAsBruteForce) {
    std::mt19937 random(5);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::vector<glm::vec3> corners;
    for (int i = 0; i < 3 * 500; ++i)
        corners.emplace_back(unit(random), unit(random), unit(random));
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

TEST(TriangleBvh, ALargeTreeBuiltInParallelHasTheBruteForceHitsOnAnyThreadCount) {
    // 20000 triangles: the upper levels of the tree build their two sides in parallel (from
    // 4096 triangles). Each ray's nearest hit must be brute force's, and the same with the tree
    // built on one thread.
    std::mt19937 random(23);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    constexpr int kTriangles = 20000;
    std::vector<glm::vec3> corners;
    for (int t = 0; t < kTriangles; ++t) {
        const glm::vec3 centre(unit(random), unit(random), unit(random));
        for (int corner = 0; corner < 3; ++corner)
            corners.push_back(centre + 0.05f * glm::vec3(unit(random), unit(random), unit(random)));
    }
    const TriangleBvh bvh(corners);
    const TriangleBvh serialBvh = [&] {
        const tbb::global_control oneThread(tbb::global_control::max_allowed_parallelism, 1);
        return TriangleBvh(corners);
    }();
    int hits = 0;
    for (int i = 0; i < 400; ++i) {
        const Ray ray{glm::vec3(unit(random), unit(random), 3.0f),
                      glm::normalize(glm::vec3(0.3f * unit(random), 0.3f * unit(random), -1.0f))};
        double nearest = std::numeric_limits<double>::max();
        int nearestTriangle = -1;
        for (int t = 0; t < kTriangles; ++t) {
            double distance = 0.0, b1 = 0.0, b2 = 0.0;
            if (intersectTriangle(ray, corners[3 * t], corners[3 * t + 1], corners[3 * t + 2], 0.0,
                                  nearest, distance, b1, b2)) {
                nearest = distance;
                nearestTriangle = t;
            }
        }
        TriangleHit hit, serialHit;
        const bool found = bvh.intersect(ray, 0.0f, std::numeric_limits<float>::max(), hit);
        ASSERT_EQ(found, nearestTriangle >= 0) << i;
        ASSERT_EQ(serialBvh.intersect(ray, 0.0f, std::numeric_limits<float>::max(), serialHit),
                  found);
        if (!found) continue;
        ++hits;
        EXPECT_EQ(int(hit.triangle), nearestTriangle) << i;
        EXPECT_FLOAT_EQ(hit.distanceWorld, float(nearest)) << i;
        EXPECT_EQ(serialHit.triangle, hit.triangle) << i;
        EXPECT_EQ(serialHit.distanceWorld, hit.distanceWorld) << i;
        EXPECT_EQ(serialHit.b1, hit.b1) << i;
        EXPECT_EQ(serialHit.b2, hit.b2) << i;
    }
    EXPECT_GT(hits, 200);  // most rays hit: the test is about hits, not misses
}

/// The corners of `count` random triangles in [-1, 1]^2 x [-0.5, 0.5], a floor much larger than
/// all of them (split off at the root by the surface area heuristic), then every triangle again
/// in reverse order: each copy lies in another part of a tree over them, is hit at exactly the
/// distance of its original, and must lose to it. The originals are the first count + 1.
std::vector<glm::vec3> trianglesAndTheirCopies(std::mt19937& random, int count) {
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::vector<glm::vec3> corners;
    for (int i = 0; i < 3 * count; ++i)
        corners.emplace_back(unit(random), unit(random), 0.5f * unit(random));
    corners.insert(corners.end(), {{-9, -9, -1}, {9, -9, -1}, {0, 9, -1}});
    for (std::size_t t = std::size_t(count) + 1; t-- > 0;)
        corners.insert(corners.end(), {corners[3 * t], corners[3 * t + 1], corners[3 * t + 2]});
    return corners;
}

TEST(TriangleBvh, EquallyNearTrianglesGoToTheLowestIndexWhateverTheTree) {
    std::mt19937 random(11);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    const std::size_t originals = 300 + 1;
    const TriangleBvh bvh(trianglesAndTheirCopies(random, 300));
    int hits = 0;
    for (int i = 0; i < 2000; ++i) {
        const Ray ray{glm::vec3(unit(random), unit(random), 3.0f),
                      glm::normalize(glm::vec3(0.3f * unit(random), 0.3f * unit(random), -1.0f))};
        TriangleHit hit;
        ASSERT_TRUE(bvh.intersect(ray, 0.0f, std::numeric_limits<float>::max(), hit));
        ASSERT_LT(hit.triangle, originals) << i;
        hits += hit.triangle + 1 < originals ? 1 : 0;  // not the floor
    }
    EXPECT_GT(hits, 500);
}

TEST(TriangleBvh, RaysThroughASharedEdgeDoNotSlipBetweenTriangles) {
    // Two triangles of a unit quad share the diagonal x = y; rays aimed at points on it must hit.
    const TriangleBvh quad({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}});
    for (int i = 0; i <= 1000; ++i) {
        const float s = 0.0005f + 0.999f * float(i) / 1000.0f;
        const glm::vec3 target(s, s, 0.0f);
        const glm::vec3 origin(0.37f, -0.61f, 2.0f);
        TriangleHit hit;
        ASSERT_TRUE(quad.intersect({origin, glm::normalize(target - origin)}, 0.0f, 100.0f, hit))
            << s;
        EXPECT_NEAR(hit.distanceWorld, glm::length(target - origin), 1e-5f);
    }
}

TEST(TriangleBvh, RaysInThePlaneOfABoxFaceHitWhatIsThere) {
    // A grid of 4 x 4 unit quads over [0, 4]^2 (32 triangles, so boxes have faces at x, y =
    // 0 ... 4). Rays that do not move along x (or y) and start exactly on such a face plane lie
    // in it: the slab test once multiplied 0 by an infinite inverse direction there, got NaN and
    // missed the box, and with it every triangle along that grid line: the ray went through the
    // mesh. Each ray below comes down at 45 degrees onto a point of an inner grid line, between
    // vertices, where two triangles meet, and must hit one of them (on the outer border, a ray
    // exactly on the edge of the only triangle there may go either way).
    std::vector<glm::vec3> corners;
    for (int y = 0; y < 4; ++y) {
        for (int x = 0; x < 4; ++x) {
            const glm::vec3 p00(x, y, 0), p10(x + 1, y, 0), p11(x + 1, y + 1, 0), p01(x, y + 1, 0);
            corners.insert(corners.end(), {p00, p10, p11, p00, p11, p01});
        }
    }
    const TriangleBvh grid(std::move(corners));
    const float diagonal = std::sqrt(0.5f);
    int rays = 0;
    for (int line = 1; line <= 3; ++line) {
        for (const float along : {0.3f, 1.7f, 3.5f}) {
            for (const float sign : {1.0f, -1.0f}) {
                const glm::vec3 targets[2] = {{float(line), along, 0.0f},
                                              {along, float(line), 0.0f}};
                const glm::vec3 directions[2] = {{0.0f, sign * diagonal, -diagonal},
                                                 {sign * diagonal, 0.0f, -diagonal}};
                for (int axis = 0; axis < 2; ++axis) {
                    const Ray ray{targets[axis] - directions[axis] * 2.0f, directions[axis]};
                    TriangleHit hit;
                    ASSERT_TRUE(grid.intersect(ray, 0.0f, 100.0f, hit))
                        << "line " << line << " along " << along << " axis " << axis;
                    EXPECT_NEAR(hit.distanceWorld, 2.0f, 1e-5f);
                    ++rays;
                }
            }
        }
    }
    EXPECT_EQ(rays, 36);
}

TEST(TriangleBvh, ParallelRaysTracedTogetherHitWhatEachHitsAlone) {
    // intersectParallel must give each ray exactly intersect's hit: the same triangle (ties to
    // the lowest index included), distance and weights. The scene: trianglesAndTheirCopies of
    // 400, and a grid of unit quads at z = -0.5 whose box faces lie on grid lines. Rays in
    // packets of 1 to 16 along one direction (oblique, along the grid's lines, straight down),
    // from coherent 4 x 4 blocks and from scattered origins, each from its own minimum
    // distance.
    std::mt19937 random(29);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::vector<glm::vec3> corners = trianglesAndTheirCopies(random, 400);
    for (int y = -2; y < 2; ++y)
        for (int x = -2; x < 2; ++x) {
            const glm::vec3 p00(x, y, -0.5f), p10(x + 1, y, -0.5f), p11(x + 1, y + 1, -0.5f),
                p01(x, y + 1, -0.5f);
            corners.insert(corners.end(), {p00, p10, p11, p00, p11, p01});
        }
    const TriangleBvh bvh(corners);
    const float diagonal = std::sqrt(0.5f);
    const glm::vec3 directions[] = {glm::normalize(glm::vec3(-0.45f, 0.35f, -1.0f)),
                                    {0.0f, diagonal, -diagonal},
                                    {-diagonal, 0.0f, -diagonal},
                                    {0.0f, 0.0f, -1.0f}};
    constexpr float kFar = std::numeric_limits<float>::max();
    int rays = 0, hits = 0, lateStarts = 0;
    for (const glm::vec3& direction : directions) {
        for (int packet = 0; packet < 400; ++packet) {
            const int count = 1 + packet % int(TriangleBvh::kPacketRays);
            const bool coherent = packet % 2 == 0;
            const glm::vec3 corner(unit(random), unit(random), 0.0f);
            std::vector<Ray> packetRays;
            std::vector<float> from;
            for (int k = 0; k < count; ++k) {
                // On the grid's lines (whole coordinates) for a quarter of the coherent packets.
                const float spacing = packet % 8 == 0 ? 1.0f : 0.01f;
                const glm::vec3 target =
                    coherent ? corner * (packet % 8 == 0 ? 0.0f : 1.0f) +
                                   spacing * glm::vec3(float(k % 4 - 2), float(k / 4 - 2), 0.0f)
                             : glm::vec3(unit(random), unit(random), 0.0f);
                packetRays.push_back({target - 3.0f * direction, direction});
                from.push_back(k % 3 == 0 ? 2.5f + 0.5f * unit(random) : 0.0f);
            }
            std::vector<TriangleHit> together(std::size_t(count), TriangleHit{});
            std::unique_ptr<bool[]> found(new bool[std::size_t(count)]);
            bvh.intersectParallel(packetRays, from, kFar, together,
                                  std::span<bool>(found.get(), std::size_t(count)));
            for (int k = 0; k < count; ++k) {
                TriangleHit alone;
                const bool foundAlone =
                    bvh.intersect(packetRays[std::size_t(k)], from[std::size_t(k)], kFar, alone);
                ++rays;
                ASSERT_EQ(found[std::size_t(k)], foundAlone) << packet << " " << k;
                if (!foundAlone) continue;
                ++hits;
                lateStarts += from[std::size_t(k)] > 0.0f ? 1 : 0;
                const TriangleHit& hit = together[std::size_t(k)];
                EXPECT_EQ(hit.triangle, alone.triangle) << packet << " " << k;
                EXPECT_EQ(hit.distanceWorld, alone.distanceWorld) << packet << " " << k;
                EXPECT_EQ(hit.b1, alone.b1) << packet << " " << k;
                EXPECT_EQ(hit.b2, alone.b2) << packet << " " << k;
            }
        }
    }
    EXPECT_EQ(rays, 4 * 25 * 136);   // 4 directions, 25 times packets of 1 to 16 rays
    EXPECT_GT(hits, rays * 9 / 10);  // the floor and the grid catch most rays: hits are tested
    EXPECT_GT(lateStarts, rays / 5);
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

/// A wavy height field of 32 x 32 x 16 texels: distances are a bound, not exact.
Tile wavyTile() {
    Tile tile({32, 32, 16});
    for (int z = 0; z < 16; ++z)
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 32; ++x)
                tile.at(x, y, z) =
                    0.5f * ((z + 0.5f) - (8.0f + 4.0f * std::sin(2 * kPi * (x + 0.5f) / 32) *
                                                     std::cos(2 * kPi * (y + 0.5f) / 32)));
    return tile;
}

TEST(Renderer, ImageIsFiniteAndIndependentOfTheThreadCount) {
    // Any bug that produces NaN or a thread-dependent pixel shows here.
    const Scene scene = planeScene(std::make_shared<const Tile>(wavyTile()));
    RenderOptions options;
    options.width = 96;
    options.height = 64;
    options.outputAovs = true;
    const RenderResult first = onThreads(1, [&] { return renderScene(scene, options); });
    const RenderResult second = onThreads(2, [&] { return renderScene(scene, options); });
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

TEST(Renderer, ReportsProgressOnTheCallingThreadWithoutChangingAPixel) {
    // Progress comes from the calling thread as it finishes blocks of pixels (the other threads
    // never wait for it), rises to 1 and leaves the image as it is without it.
    const Scene scene = planeScene(std::make_shared<const Tile>(wavyTile()));
    RenderOptions options;
    options.width = 96;
    options.height = 64;  // 6 x 4 blocks
    const RenderResult quiet = renderScene(scene, options);
    for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        const std::thread::id caller = std::this_thread::get_id();
        std::vector<double> reported;
        bool elsewhere = false;
        const RenderResult result = renderScene(scene, options, [&](double fractionDone) {
            elsewhere |= std::this_thread::get_id() != caller;
            reported.push_back(fractionDone);
        });
        EXPECT_FALSE(elsewhere) << threads << " threads";
        ASSERT_FALSE(reported.empty());
        EXPECT_TRUE(std::is_sorted(reported.begin(), reported.end())) << threads << " threads";
        EXPECT_GT(reported.front(), 0.0);
        EXPECT_EQ(reported.back(), 1.0);
        EXPECT_EQ(result.image.rgbLinear, quiet.image.rgbLinear) << threads << " threads";
    }
}

/// A bare (untiled) square of side `sizeWorld` at height `heightWorld`, facing +z.
SceneObject bareSquare(float sizeWorld, float heightWorld) {
    SceneObject square;
    square.mesh = makePlane(sizeWorld, 1);
    applyTransform(square.mesh, {{0.0f, 0.0f, heightWorld}, {0.0f, 0.0f, 0.0f}, 1.0f});
    return square;
}

TEST(Renderer, TheConvergedShareCountsOnlyHitsOnATile) {
    // Looking straight down on the tiled plane (flat detail: every ray converges), whose view a
    // bare square at z = 0.5 partly hides: every pixel hits a surface, the square's pixels hit
    // no tile, and all the tile's hits converged.
    Scene scene = planeScene(std::make_shared<const Tile>(flatTile({32, 32, 16}, 8.0f)));
    scene.camera = {{0.01f, 0.02f, 2.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}, 40.0f};
    scene.objects.push_back(bareSquare(0.5f, 0.5f));
    RenderOptions options;
    options.width = 64;
    options.height = 48;
    options.shadowFilter = ShadowFilter::None;
    options.selfShadows = false;
    const RenderStats stats = renderScene(scene, options).stats;
    // The square's pixels, from the pixel rays and the plane z = 0.5 (none within 1e-4 of its
    // edge here, so rounding cannot move a pixel across it).
    const PinholeProjection projection(scene.camera, options.width, options.height);
    std::uint64_t onSquare = 0;
    for (int y = 0; y < options.height; ++y)
        for (int x = 0; x < options.width; ++x) {
            const Ray ray = projection.ray(float(x) + 0.5f, float(y) + 0.5f);
            const glm::vec3 at =
                ray.origin + ray.direction * ((0.5f - ray.origin.z) / ray.direction.z);
            const float fromEdge = 0.25f - std::max(std::abs(at.x), std::abs(at.y));
            ASSERT_GT(std::abs(fromEdge), 1e-4f) << x << ", " << y;
            onSquare += fromEdge > 0.0f;
        }
    ASSERT_GT(onSquare, 100u);
    EXPECT_EQ(stats.rays, std::uint64_t(64 * 48));
    EXPECT_EQ(stats.baseHits, stats.rays);
    EXPECT_EQ(stats.detailHits, stats.rays - onSquare);
    EXPECT_EQ(stats.converged, stats.detailHits);
    EXPECT_EQ(stats.convergedShare(), 1.0);
}

TEST(Renderer, AnImageOfSkyAloneIsWarnedOf) {
    // The tiled plane at z = 0 seen from an eye at its level: the rays that descend start on its
    // top (distance 0, not a hit) and pass under it, so nothing is hit. Looking away from it, the
    // same. An eye a little above it sees the plane below the horizon: no warning.
    Scene scene = planeScene(std::make_shared<const Tile>(flatTile({32, 32, 16}, 8.0f)));
    RenderOptions options;
    options.width = 32;
    options.height = 24;
    options.shadowFilter = ShadowFilter::None;
    const auto skyWarnings = [&](const Camera& camera) {
        scene.camera = camera;
        const RenderResult result = renderScene(scene, options);
        std::size_t count = 0;
        for (const std::string& warning : result.warnings)
            count += warning.find("no camera ray meets any object") != std::string::npos;
        return std::pair(count, result.stats.baseHits);
    };
    const glm::vec3 up(0.0f, 0.0f, 1.0f);
    EXPECT_EQ(skyWarnings({{0.0f, -0.5f, 0.0f}, {0.0f, 0.5f, 0.0f}, up, 40.0f}),
              std::pair(std::size_t(1), std::uint64_t(0)));
    EXPECT_EQ(skyWarnings({{0.3f, -1.6f, 1.2f}, {0.3f, -3.2f, 2.4f}, up, 40.0f}),
              std::pair(std::size_t(1), std::uint64_t(0)));
    const auto [warnings, hits] =
        skyWarnings({{0.0f, -0.5f, 0.01f}, {0.0f, 0.5f, 0.01f}, up, 40.0f});
    EXPECT_EQ(warnings, 0u);
    EXPECT_GT(hits, std::uint64_t(32 * 24 / 4));
}

/// Ground (2 x 2 at z = 0) under a 0.5 x 0.5 occluder at z = 0.5, lit straight down by a light
/// of 2 degrees: the shadow is the occluder's square, with penumbrae tan(1 deg) * 0.5 = 8.7 mm
/// (4.5 map texels at 1024 texels over 2 units) to either side of its edges.
Scene occluderScene() {
    Scene scene;
    scene.lights = {DirectionalLight{{0.0f, 0.0f, -1.0f}, {1.0f, 1.0f, 1.0f}, 2.0f}};
    scene.objects.push_back(bareSquare(2.0f, 0.0f));
    scene.objects.push_back(bareSquare(0.5f, 0.5f));
    return scene;
}

TEST(ShadowMap, ShadowsUnderAnOccluderLightsBesideItAndSkipsBackFaces) {
    const Scene scene = occluderScene();
    const SceneTracer tracer(scene, TraceOptions{});
    const LightShadowMaps maps(tracer, scene.lights[0], 1024);
    const ShadowMap& map = onlyMap(maps);
    EXPECT_EQ(std::max(map.width(), map.height()), 1024);
    const glm::vec3 up(0.0f, 0.0f, 1.0f);
    for (ShadowFilter filter : {ShadowFilter::Full, ShadowFilter::Adaptive}) {
        const std::uint64_t perLookup = filter == ShadowFilter::Full
                                            ? kShadowRingSamples + kShadowDiskSamples
                                            : kShadowRingSamples;
        for (std::uint32_t seed = 0; seed < 16; ++seed) {
            std::uint64_t samples = 0;
            // Under the occluder's middle: every sample of the disk (radius 8.7 mm) is blocked.
            EXPECT_EQ(map.visibility({{0.05f, -0.03f, 0.0f}, up}, filter, seed, samples), 0.0f);
            EXPECT_EQ(samples, perLookup);
            // 0.5 units beside the occluder: nothing between it and the light.
            samples = 0;
            EXPECT_EQ(map.visibility({{0.8f, 0.7f, 0.0f}, up}, filter, seed, samples), 1.0f);
            EXPECT_EQ(samples, perLookup);
            // A surface facing away from the light takes no sample at all.
            samples = 0;
            EXPECT_EQ(map.visibility({{0.8f, 0.7f, 0.0f}, -up}, filter, seed, samples), 0.0f);
            EXPECT_EQ(samples, 0u);
        }
    }
    // Right under the occluder's edge x = 0.25, half of the light's disk is covered. The mean
    // over seeds of 64 stratified samples is within a few per cent of 1/2; texel quantisation
    // (half a texel of a 4.5-texel radius) moves the edge by up to ~0.1 of the disk: tolerance
    // 0.12.
    double sum = 0.0;
    for (std::uint32_t seed = 0; seed < 32; ++seed) {
        std::uint64_t samples = 0;
        const float visibility =
            map.visibility({{0.25f, 0.0f, 0.0f}, up}, ShadowFilter::Full, seed, samples);
        EXPECT_GT(visibility, 0.0f);
        EXPECT_LT(visibility, 1.0f);
        sum += visibility;
    }
    EXPECT_NEAR(sum / 32.0, 0.5, 0.12);
    // An object with a tiled top never shadows itself through the map: the plane with the flat
    // detail at mid-depth is lit everywhere.
    Scene tiled;
    tiled.lights = {DirectionalLight{{-0.3f, 0.2f, -1.0f}, {1.0f, 1.0f, 1.0f}, 4.0f}};
    tiled.objects.push_back(bareSquare(2.0f, 0.0f));
    tiled.objects[0].material.tile = std::make_shared<const Tile>(flatTile({32, 32, 16}, 8.0f));
    tiled.objects[0].material.uvScale = {8.0f, 8.0f};
    tiled.objects[0].material.depthWorld = 0.125f;
    // An occluder off the tested line (its shadow lands around (0.52, -0.58), 0.6 wide), so the
    // blocker search radius is several texels and the test exercises the full disk, not one
    // sample. It is wide enough that the map covers the whole plane: a square of 0.1 makes the
    // scene's bounds more than 4 times as wide as the region anything can be shadowed in (its
    // footprint), and the map covers that alone; the lookups on the line outside it are lit
    // without a sample (AGroundFarWiderThanTheObjectsOnItKeepsTheirShadows).
    tiled.objects.push_back(bareSquare(0.6f, 0.0f));
    applyTransform(tiled.objects[1].mesh, {{0.7f, -0.7f, 0.6f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    const SceneTracer tiledTracer(tiled, TraceOptions{});
    const LightShadowMaps tiledMaps(tiledTracer, tiled.lights[0], 512);
    const ShadowMap& tiledMap = onlyMap(tiledMaps);
    std::uint64_t samples = 0;
    int lookups = 0;
    for (float x = -0.9f; x < 0.9f; x += 0.0137f, ++lookups) {
        EXPECT_EQ(tiledMap.visibility({{x, 0.3f * x, 0.0f}, up}, ShadowFilter::Full, 7, samples),
                  1.0f)
            << x;
    }
    EXPECT_EQ(samples, std::uint64_t((kShadowRingSamples + kShadowDiskSamples) * lookups));
}

TEST(ShadowMap, ReceiversFarOffTheMapOrAtInfinityAreLitWithoutSamples) {
    // The renderer looks a detail hit up where the light ray from it leaves its shell: the hit's
    // depth below the top over the light's facing, along the light. A light grazing the base at a
    // denormal angle (a fuzz input: direction (-1e-30, 1e12, -1e-30)) puts that point at
    // infinity; a nearly grazing one, so far off the map that its tile index is beyond int's
    // range. Nothing in the map lies there: lit, without a sample, under a narrow light (the
    // blocker search) and a wide one (the line test).
    constexpr float kInfinity = std::numeric_limits<float>::infinity();
    const glm::vec3 up(0.0f, 0.0f, 1.0f);
    for (const float angleDeg : {2.0f, 30.0f}) {
        Scene scene = occluderScene();
        scene.lights[0].angleDeg = angleDeg;
        const SceneTracer tracer(scene, TraceOptions{});
        const LightShadowMaps maps(tracer, scene.lights[0], 1024);
        const ShadowMap& map = onlyMap(maps);
        for (const glm::vec3& far :
             {glm::vec3(1e30f, 0.0f, 0.0f), glm::vec3(-3e29f, 1e30f, 0.0f),
              glm::vec3(5e9f, 0.0f, -1e12f), glm::vec3(kInfinity, 0.0f, 0.0f),
              glm::vec3(0.0f, -kInfinity, 0.0f), glm::vec3(0.0f, 0.0f, kInfinity),
              glm::vec3(std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f)}) {
            for (ShadowFilter filter : {ShadowFilter::Full, ShadowFilter::Adaptive}) {
                std::uint64_t samples = 0;
                EXPECT_EQ(map.visibility({far, up}, filter, 5, samples), 1.0f)
                    << angleDeg << " degrees, at " << far.x << ", " << far.y << ", " << far.z;
                EXPECT_EQ(samples, 0u);
            }
        }
    }
}

TEST(ShadowMap, ReceiversOnAFlatSlabWithNothingElseOverTheirDiskTakeNoSamples) {
    const Scene scene = occluderScene();
    ASSERT_TRUE(isFlatSlab(scene.objects[0]));
    SceneObject bent = scene.objects[0];
    bent.mesh.positions[0].z += 0.1f;  // one corner raised: no longer planar
    EXPECT_FALSE(isFlatSlab(bent));
    const SceneTracer tracer(scene, TraceOptions{});
    const LightShadowMaps maps(tracer, scene.lights[0], 1024);
    const ShadowMap& map = onlyMap(maps);
    const glm::vec3 up(0.0f, 0.0f, 1.0f);
    map.nearestDepth();  // its search traces the tiles over the occluder, once
    for (ShadowFilter filter : {ShadowFilter::Full, ShadowFilter::Adaptive}) {
        const std::uint64_t traced = map.tracedTexels();
        // On the ground (object 0) far beside the occluder: only the ground's own slab is over
        // the disk, and it lies behind the receiver's plane. Lit, nothing sampled or traced.
        std::uint64_t samples = 0;
        EXPECT_EQ(map.visibility({{0.8f, 0.7f, 0.0f}, up, 0.0f, 0}, filter, 3, samples), 1.0f);
        EXPECT_EQ(samples, 0u);
        EXPECT_EQ(map.tracedTexels(), traced);
        // Under the occluder the other slab is over the disk: sampled, in shadow.
        EXPECT_EQ(map.visibility({{0.05f, -0.03f, 0.0f}, up, 0.0f, 0}, filter, 3, samples), 0.0f);
        EXPECT_EQ(samples, filter == ShadowFilter::Full
                               ? std::uint64_t(kShadowRingSamples + kShadowDiskSamples)
                               : std::uint64_t(kShadowRingSamples));
    }
    // Across the occluder's edges and beyond, a receiver known to lie on the ground gets what one
    // of unknown object (whose disk is always sampled) gets, bit for bit, with fewer samples; also
    // under a light grazing the ground (its reference plane's slope is limited there, so the
    // ground's own surface may block: no skip).
    for (const glm::vec3 direction :
         {glm::vec3(0.0f, 0.0f, -1.0f), glm::vec3(1.0f, 0.2f, -0.05f)}) {
        Scene lit = scene;
        lit.lights[0].direction = direction;
        const SceneTracer litTracer(lit, TraceOptions{});
        const LightShadowMaps litMaps(litTracer, lit.lights[0], 1024);
        const ShadowMap& litMap = onlyMap(litMaps);
        std::uint64_t onGround = 0, unknown = 0;
        for (float y = -0.6f; y < 0.6f; y += 0.0173f)
            for (float x = -0.6f; x < 0.6f; x += 0.0173f) {
                const auto seed = std::uint32_t(std::lround(1000.0f * (x + 2.0f * y)));
                ASSERT_EQ(
                    litMap.visibility({{x, y, 0.0f}, up, 0.0f, 0}, ShadowFilter::Adaptive, seed,
                                      onGround),
                    litMap.visibility({{x, y, 0.0f}, up}, ShadowFilter::Adaptive, seed, unknown))
                    << direction.x << ": " << x << " " << y;
            }
        if (direction.z == -1.0f) {
            EXPECT_LT(onGround, unknown / 2);
        }
    }
}

TEST(ShadowMap, TracesOnlyWhereLookupsReachAndAgreesWithEveryTileTraced) {
    const Scene scene = occluderScene();
    const SceneTracer tracer(scene, TraceOptions{});
    const LightShadowMaps lazyMaps(tracer, scene.lights[0], 1024);
    const ShadowMap& lazy = onlyMap(lazyMaps);
    const LightShadowMaps wholeMaps(tracer, scene.lights[0], 1024);
    const ShadowMap& whole = onlyMap(wholeMaps);
    const std::uint64_t allTexels = std::uint64_t(whole.width()) * std::uint64_t(whole.height());
    for (int y = 0; y < whole.height(); y += ShadowMap::kTileTexels)
        for (int x = 0; x < whole.width(); x += ShadowMap::kTileTexels) whole.depthAt(x, y);
    EXPECT_EQ(whole.tracedTexels(), allTexels);
    // Nothing is traced before a lookup asks; the search for the nearest depth (which a lookup
    // starts) traces only the tiles that may hold it: those over the occluder (256 x 256 of the
    // 1024 x 1024 texels) and a tile of margin around it.
    EXPECT_EQ(lazy.tracedTexels(), 0u);
    lazy.nearestDepth();
    const std::uint64_t searched = lazy.tracedTexels();
    EXPECT_GE(searched, std::uint64_t(256 * 256));
    EXPECT_LE(searched, std::uint64_t(320 * 320));
    // A lookup beside the occluder traces the tiles its disk (8.7 mm, 4.5 texels) reaches: a few.
    std::uint64_t samples = 0;
    EXPECT_EQ(
        lazy.visibility({{0.8f, 0.7f, 0.0f}, {0.0f, 0.0f, 1.0f}}, ShadowFilter::Full, 1, samples),
        1.0f);
    EXPECT_GT(lazy.tracedTexels(), searched);
    EXPECT_LE(lazy.tracedTexels(), searched + 4 * ShadowMap::kTileTexels * ShadowMap::kTileTexels);
    // Every lookup gives what the fully traced map gives, bit for bit (the nearest depth, which
    // sets the blocker search's radius, included): over a grid across the occluder's edges.
    for (float y = -0.4f; y < 0.4f; y += 0.0173f)
        for (float x = -0.4f; x < 0.4f; x += 0.0173f) {
            const ShadowReceiver receiver{{x, y, 0.0f}, {0.0f, 0.0f, 1.0f}};
            const auto seed = std::uint32_t(std::lround(1000.0f * (x + 2.0f * y)));
            std::uint64_t lazySamples = 0, wholeSamples = 0;
            ASSERT_EQ(lazy.visibility(receiver, ShadowFilter::Adaptive, seed, lazySamples),
                      whole.visibility(receiver, ShadowFilter::Adaptive, seed, wholeSamples))
                << x << " " << y;
            ASSERT_EQ(lazySamples, wholeSamples);
        }
    EXPECT_LT(lazy.tracedTexels(), allTexels / 4);  // the grid spans 0.8 of the 2 units
    for (int y = 0; y < whole.height(); y += 7)
        for (int x = 0; x < whole.width(); x += 7)
            ASSERT_EQ(lazy.depthAt(x, y), whole.depthAt(x, y));
}

TEST(ShadowMap, ReceiversWithLargeFootprintsReadCoarserLevels) {
    const Scene scene = occluderScene();
    const SceneTracer tracer(scene, TraceOptions{});
    const LightShadowMaps fineMaps(tracer, scene.lights[0], 1024);
    const ShadowMap& fine = onlyMap(fineMaps);
    const LightShadowMaps coarseMaps(tracer, scene.lights[0], 1024);
    const ShadowMap& coarse = onlyMap(coarseMaps);
    fine.nearestDepth();  // the same search in both maps, counted apart
    coarse.nearestDepth();
    ASSERT_EQ(fine.tracedTexels(), coarse.tracedTexels());  // the nearest depth's tiles
    const std::uint64_t searched = fine.tracedTexels();
    const glm::vec3 up(0.0f, 0.0f, 1.0f);
    // Pixels 8 finest texels wide read the coarsest level, whose texels are that wide.
    const float footprint = 8.0f * coarse.texelWorld();
    std::uint64_t samples = 0;
    for (std::uint32_t seed = 0; seed < 8; ++seed) {
        // Under the occluder's middle, and a grid beside it: the same answers at any level.
        EXPECT_EQ(coarse.visibility({{0.05f, -0.03f, 0.0f}, up, footprint}, ShadowFilter::Full,
                                    seed, samples),
                  0.0f);
        for (float y = 0.35f; y < 0.9f; y += 0.05f)
            for (float x = 0.35f; x < 0.9f; x += 0.05f) {
                EXPECT_EQ(fine.visibility({{x, y, 0.0f}, up}, ShadowFilter::Full, seed, samples),
                          1.0f);
                EXPECT_EQ(coarse.visibility({{x, y, 0.0f}, up, footprint}, ShadowFilter::Full, seed,
                                            samples),
                          1.0f);
            }
    }
    // The grid's 0.55 x 0.55 units: tiles of 16 x 16 finer texels for the blocker search's disk
    // (8.7 mm radius, texels of at most half of it: level 1), of 16 x 16 coarsest texels (8 x 8
    // times the area) for the large pixels.
    const std::uint64_t fineTexels = fine.tracedTexels() - searched;
    const std::uint64_t coarseTexels = coarse.tracedTexels() - searched;
    EXPECT_GT(coarseTexels, 0u);
    EXPECT_LT(8 * coarseTexels, fineTexels) << coarseTexels << " " << fineTexels;
}

/// The share of a light's disk, straight down and tan(angle / 2) = `tanHalf` wide, whose rays
/// from `from` meet nothing `meets` says they meet: the directions (w, 1), w uniform on the disk of
/// radius tanHalf (as the renderer and the world reference sample it), integrated at the centres
/// of 400 equal-area rings by 720 angles.
template <class Meets>
double exactLitShare(const glm::dvec3& from, double tanHalf, const Meets& meets) {
    constexpr int kRings = 400, kAngles = 720;
    int lit = 0;
    for (int ring = 0; ring < kRings; ++ring) {
        const double radius = tanHalf * std::sqrt((ring + 0.5) / kRings);
        for (int angle = 0; angle < kAngles; ++angle) {
            const double phi = 2.0 * 3.141592653589793 * (angle + 0.5) / kAngles;
            lit += !meets(from, glm::dvec3(radius * std::cos(phi), radius * std::sin(phi), 1.0));
        }
    }
    return double(lit) / double(kRings * kAngles);
}

/// The mean over 64 seeds (64 x 64 directions) of the share of the light `maps` lets reach an
/// upward-facing receiver at `at`, filtered in full.
double meanLitShare(const LightShadowMaps& maps, const glm::dvec3& at) {
    constexpr int kSeeds = 64;
    double sum = 0.0;
    for (std::uint32_t seed = 0; seed < kSeeds; ++seed) {
        std::uint64_t samples = 0;
        sum += maps.visibility({glm::vec3(at), {0.0f, 0.0f, 1.0f}, 0.0f, 0}, ShadowFilter::Full,
                               seed, samples);
    }
    return sum / kSeeds;
}

TEST(ShadowMap, WideLightsFollowEachRayOfTheDiskThroughTheMap) {
    // Under a 45-degree light straight down: a ball of radius 0.25 resting on the ground, and a
    // square of 0.4 floating 0.5 above it. Filtering (ShadowMap's file note) would count any
    // blocker over a disk sample's offset, whatever its height, and search at most 32 texels
    // (0.125 units here) where the square's penumbra reaches 0.21 beyond its edge.
    Scene scene;
    scene.lights = {DirectionalLight{{0.0f, 0.0f, -1.0f}, {1.0f, 1.0f, 1.0f}, 45.0f}};
    scene.objects.push_back(bareSquare(4.0f, 0.0f));
    SceneObject ball;
    ball.mesh = makeUvSphere(0.25f, 128, 64);
    applyTransform(ball.mesh, {{0.0f, 0.0f, 0.25f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    scene.objects.push_back(std::move(ball));
    scene.objects.push_back(bareSquare(0.4f, 0.5f));
    applyTransform(scene.objects[2].mesh, {{1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    // And a low one, 0.1 above the ground, for a receiver seen from afar.
    scene.objects.push_back(bareSquare(0.4f, 0.1f));
    applyTransform(scene.objects[3].mesh, {{-1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    const double tanHalf = std::tan(22.5 * 3.141592653589793 / 180.0);
    const auto meetsBall = [](const glm::dvec3& from, const glm::dvec3& direction) {
        const glm::dvec3 offset = from - glm::dvec3(0.0, 0.0, 0.25);
        const double b = glm::dot(offset, direction), a = glm::dot(direction, direction);
        return b < 0.0 && b * b - a * (glm::dot(offset, offset) - 0.0625) >= 0.0;
    };
    const auto meetsSquare = [](const glm::dvec3& from, const glm::dvec3& direction) {
        const glm::dvec3 at = from + direction * ((0.5 - from.z) / direction.z);
        return std::abs(at.x - 1.0) <= 0.2 && std::abs(at.y) <= 0.2;
    };
    const SceneTracer tracer(scene, TraceOptions{});
    // No blocker over one of the ball and the squares reaches under another (their footprints
    // lie 0.55 apart, the widest penumbra between them 0.5 tan 22.5 = 0.21): a map each.
    const LightShadowMaps maps(tracer, scene.lights[0], 1024);
    ASSERT_EQ(maps.size(), 3u);
    const LightShadowMaps whole(tracer, scene.lights[0], 1024);  // every tile traced first
    for (std::size_t index = 0; index < whole.size(); ++index)
        for (int y = 0; y < whole[index].height(); y += ShadowMap::kTileTexels)
            for (int x = 0; x < whole[index].width(); x += ShadowMap::kTileTexels)
                whole[index].depthAt(x, y);
    const glm::vec3 up(0.0f, 0.0f, 1.0f);
    struct Case {
        glm::dvec3 at;
        bool ball;
    };
    const Case cases[] = {{{0.04, 0.03, 0.0}, true},  {{-0.07, 0.09, 0.0}, true},
                          {{0.17, -0.05, 0.0}, true}, {{0.02, 0.3, 0.0}, true},
                          {{1.03, 0.02, 0.0}, false}, {{1.16, -0.04, 0.0}, false},
                          {{1.27, 0.05, 0.0}, false}, {{0.99, 0.36, 0.0}, false}};
    // The mean over 64 seeds (64 x 64 directions) of the map's answer against the exact share.
    // The edges the rays pass are placed to within the steps near them, a tenth of the offset
    // (0.02 units at the square's 0.2): on the square's penumbra, 0.42 units wide (0.5 tan 22.5
    // degrees to either side of its edge), that moves the share by up to about 0.05 where the
    // edge runs across the disk; the ball's curved edge averages it out. Tolerance 0.04 (the
    // cases measured within 0.023; filtering was 0.13 to 0.33 off under the square and 0.03 to
    // 0.06 beside it).
    for (const Case& c : cases) {
        const double exact = c.ball ? exactLitShare(c.at, tanHalf, meetsBall)
                                    : exactLitShare(c.at, tanHalf, meetsSquare);
        double sum = 0.0;
        constexpr int kSeeds = 64;
        for (std::uint32_t seed = 0; seed < kSeeds; ++seed) {
            std::uint64_t samples = 0, wholeSamples = 0;
            const ShadowReceiver receiver{glm::vec3(c.at), up, 0.0f, 0};
            const float visibility = maps.visibility(receiver, ShadowFilter::Full, seed, samples);
            sum += visibility;
            // Lazily traced tiles give what a whole map gives, bit for bit.
            ASSERT_EQ(visibility,
                      whole.visibility(receiver, ShadowFilter::Full, seed, wholeSamples));
            // Adaptive: the first half of the lines, or all of them where those disagree.
            std::uint64_t adaptiveSamples = 0;
            const float adaptive =
                maps.visibility(receiver, ShadowFilter::Adaptive, seed, adaptiveSamples);
            if (adaptive != 0.0f && adaptive != 1.0f) {
                ASSERT_EQ(adaptive, visibility);
            }
            ASSERT_LE(adaptiveSamples, samples);
        }
        EXPECT_NEAR(sum / kSeeds, exact, 0.04) << c.at.x << ", " << c.at.y;
    }
    // Under the low square's middle every ray meets it (0.1 tan 22.5 degrees = 0.04 units aside,
    // within its 0.2), also for a receiver whose pixel is 0.05 units wide, whose lines begin
    // that far out, where every ray has already risen in front of the square: it started
    // behind it.
    for (std::uint32_t seed = 0; seed < 8; ++seed) {
        std::uint64_t samples = 0;
        EXPECT_EQ(maps.visibility({{-1.02f, 0.01f, 0.0f}, up, 0.05f, 0}, ShadowFilter::Full, seed,
                                  samples),
                  0.0f);
    }
}

TEST(ShadowMap, RaysComingOutUnderABlockersEdgeAreNotBlockedByWhatLiesBeyondIt) {
    // Under a 45-degree light straight down: a square of 0.4 floating 0.5 above the ground, and
    // beyond its edge x = 1.2 a low slab 0.05 high. From a receiver 0.1 inside the edge, the rays
    // toward the far side of the disk pass under the edge, at a height of at least 0.24, and over
    // the slab: only the square shadows it. The line test saw those rays behind the square, then
    // in front of the slab, and took that for a ray rising through the square: every ray that
    // came out under the edge was counted blocked. (A receiver under a blocker near a surface
    // in front of its plane: the inner wall of a torus beside its hole, speckled dark under a
    // wide light where a tall object lengthened the lines.)
    Scene scene;
    scene.lights = {DirectionalLight{{0.0f, 0.0f, -1.0f}, {1.0f, 1.0f, 1.0f}, 45.0f}};
    scene.objects.push_back(bareSquare(4.0f, 0.0f));
    scene.objects.push_back(bareSquare(0.4f, 0.5f));
    applyTransform(scene.objects[1].mesh, {{1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    scene.objects.push_back(bareSquare(0.4f, 0.05f));
    applyTransform(scene.objects[2].mesh, {{1.4f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    const double tanHalf = std::tan(22.5 * 3.141592653589793 / 180.0);
    const auto meetsSquare = [](const glm::dvec3& from, const glm::dvec3& direction) {
        const glm::dvec3 at = from + direction * ((0.5 - from.z) / direction.z);
        return std::abs(at.x - 1.0) <= 0.2 && std::abs(at.y) <= 0.2;
    };
    const SceneTracer tracer(scene, TraceOptions{});
    const LightShadowMaps maps(tracer, scene.lights[0], 1024);
    const glm::dvec3 at(1.1, 0.02, 0.0);
    const double exact = exactLitShare(at, tanHalf, meetsSquare);
    const double lit = meanLitShare(maps, at);
    std::printf("[          ] lit share %.4f, exact %.4f\n", lit, exact);
    // The tolerance of WideLightsFollowEachRayOfTheDiskThroughTheMap, whose square this is.
    EXPECT_GT(exact, 0.1);
    EXPECT_NEAR(lit, exact, 0.04);
}

/// A stack of bare squares over the ground, centred over (1, 0), `squares` (side, height) from
/// the lowest up, each narrower in angle from the receiver than the one below it (side / height
/// shrinking upward), under a 45-degree light straight down: a receiver at `at` near (1, 0, 0)
/// sees only the top square from the light, the lower ones hidden behind it as the map's further
/// layers. Every ray that meets a higher square meets the lowest first, and a ray beside the
/// lowest passes beside them all, so the lit share is the lowest square's alone. Gives the mean
/// lit share of the maps and the exact one, after checking that.
struct StackedShares {
    double lit = 0.0;
    double exact = 0.0;
};
StackedShares litShareUnderStackedSquares(std::span<const std::pair<double, double>> squares,
                                          const glm::dvec3& at) {
    Scene scene;
    scene.lights = {DirectionalLight{{0.0f, 0.0f, -1.0f}, {1.0f, 1.0f, 1.0f}, 45.0f}};
    scene.objects.push_back(bareSquare(4.0f, 0.0f));
    for (const auto& [side, height] : squares) {
        scene.objects.push_back(bareSquare(float(side), float(height)));
        applyTransform(scene.objects.back().mesh, {{1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    }
    const auto meets = [](std::span<const std::pair<double, double>> stack) {
        return [stack](const glm::dvec3& from, const glm::dvec3& direction) {
            for (const auto& [side, height] : stack) {
                const glm::dvec3 hit = from + direction * ((height - from.z) / direction.z);
                if (std::abs(hit.x - 1.0) <= 0.5 * side && std::abs(hit.y) <= 0.5 * side)
                    return true;
            }
            return false;
        };
    };
    const double tanHalf = std::tan(22.5 * 3.141592653589793 / 180.0);
    const SceneTracer tracer(scene, TraceOptions{});
    const LightShadowMaps maps(tracer, scene.lights[0], 1024);
    StackedShares shares;
    shares.exact = exactLitShare(at, tanHalf, meets(squares));
    EXPECT_EQ(shares.exact, exactLitShare(at, tanHalf, meets(squares.first(1))));
    shares.lit = meanLitShare(maps, at);
    std::printf("[          ] lit share %.4f, exact %.4f\n", shares.lit, shares.exact);
    return shares;
}

TEST(ShadowMap, ABlockerHiddenBehindAHigherOneStillShadowsTheRaysThatMeetIt) {
    // A square of 0.3 floating 0.5 above the ground and a wider one of 0.8 at a height of 2 over
    // it: the low one is the map's second layer. With one layer it was invisible and its rays
    // lit (a receiver under a stack of tori came out lit: 0.73 here). The rays that rise past the
    // low square just before its edge are blocked only where the step that passes the edge
    // counts them (else 0.40).
    const std::pair<double, double> squares[] = {{0.3, 0.5}, {0.8, 2.0}};
    const StackedShares shares = litShareUnderStackedSquares(squares, {1.0, 0.02, 0.0});
    // The tolerance of WideLightsFollowEachRayOfTheDiskThroughTheMap.
    EXPECT_GT(shares.exact, 0.1);
    EXPECT_NEAR(shares.lit, shares.exact, 0.04);
}

TEST(ShadowMap, ABlockerHiddenBehindTwoHigherOnesStillShadowsTheRaysThatMeetIt) {
    // The same with a third square between the two (0.6 at a height of 1.2): the low one is the
    // map's third layer, which two layers per texel did not keep.
    const std::pair<double, double> squares[] = {{0.3, 0.5}, {0.6, 1.2}, {0.8, 2.0}};
    const StackedShares shares = litShareUnderStackedSquares(squares, {1.0, 0.02, 0.0});
    EXPECT_GT(shares.exact, 0.1);
    EXPECT_NEAR(shares.lit, shares.exact, 0.04);
}

TEST(ShadowMap, PenumbraeOfObjectsApartOverlappingOnTheGroundShareAMap) {
    // Two balls of radius 2 floating 20 above the ground, their footprints 5 apart, under a
    // light 20 degrees wide straight down: each one's penumbra spreads tan(10) x 20 = 3.5 around
    // it on the ground, over the points between them. With a map each, such a point took one of
    // them and saw the other's blocker nowhere. They are one group: their depths reach the
    // ground under their penumbrae, and a point may lie in the penumbra of one yet nearer the
    // other (a gap up to twice the penumbra's reach).
    Scene scene;
    scene.lights = {DirectionalLight{{0.0f, 0.0f, -1.0f}, {1.0f, 1.0f, 1.0f}, 20.0f}};
    scene.objects.push_back(bareSquare(40.0f, 0.0f));  // too wide for the whole scene's map
    const glm::dvec3 centres[2] = {{4.5, 0.0, 20.0}, {-4.5, 0.0, 20.0}};
    for (const glm::dvec3& centre : centres) {
        SceneObject ball;
        ball.mesh = makeUvSphere(2.0f, 128, 64);
        applyTransform(ball.mesh, {glm::vec3(centre), {0.0f, 0.0f, 0.0f}, 1.0f});
        scene.objects.push_back(std::move(ball));
    }
    const SceneTracer tracer(scene, TraceOptions{});
    const LightShadowMaps maps(tracer, scene.lights[0], 1024);
    EXPECT_EQ(maps.size(), 1u);
    const auto meetsABall = [&](const glm::dvec3& from, const glm::dvec3& direction) {
        for (const glm::dvec3& centre : centres) {
            const glm::dvec3 offset = from - centre;
            const double b = glm::dot(offset, direction), a = glm::dot(direction, direction);
            if (b < 0.0 && b * b - a * (glm::dot(offset, offset) - 4.0) >= 0.0) return true;
        }
        return false;
    };
    const double tanHalf = std::tan(10.0 * 3.141592653589793 / 180.0);
    for (const double x : {-0.3, 0.0, 0.2}) {
        const glm::dvec3 at(x, 0.1, 0.0);
        const double exact = exactLitShare(at, tanHalf, meetsABall);
        const double lit = meanLitShare(maps, at);
        std::printf("[          ] x %.1f: lit share %.3f, exact %.3f\n", x, lit, exact);
        EXPECT_LT(exact, 0.9) << x;  // both balls' penumbrae are over the point
        EXPECT_NEAR(lit, exact, 0.04) << x;
    }
}

TEST(ShadowMap, RejectsBadResolutions) {
    const Scene scene = occluderScene();
    const SceneTracer tracer(scene, TraceOptions{});
    EXPECT_THROW(LightShadowMaps(tracer, scene.lights[0], 8), InputError);
    EXPECT_THROW(LightShadowMaps(tracer, scene.lights[0], 20000), InputError);
    RenderOptions options;
    options.shadowMapResolution = 8;  // 0 is automatic; below 16 is refused
    EXPECT_THROW(renderScene(scene, options), InputError);
}

TEST(ShadowMap, DiskPatternPutsOneSampleInEachCellAtItsTrigonometricPlace) {
    using detail::DiskPattern;
    constexpr int kStrata = DiskPattern::kStrata;
    const double twoPi = 2.0 * 3.14159265358979323846;
    for (std::uint32_t seed : {0u, 1u, 77u, 0xdeadbeefu}) {
        for (float rotation : {0.0f, 1.0f, 5.5f}) {
            const DiskPattern disk(seed, rotation);
            std::array<int, kStrata * kStrata> perCell{};
            for (int radial = 0; radial < kStrata; ++radial) {
                for (int angular = 0; angular < kStrata; ++angular) {
                    const glm::vec2 offset = disk.offset(angular, radial);
                    // Its cell, from the offset alone: the radial stratum by its area share
                    // (r^2), the angular one by its angle from the rotation.
                    const double areaShare = double(glm::dot(offset, offset));
                    double angle = std::atan2(double(offset.y), double(offset.x)) - rotation;
                    angle -= twoPi * std::floor(angle / twoPi);
                    const int cellRadial = int(areaShare * kStrata);
                    const int cellAngular = int(angle / twoPi * kStrata) % kStrata;
                    ASSERT_LT(areaShare, 1.0);
                    ++perCell[std::size_t(cellRadial * kStrata + cellAngular)];
                    // The same sample by the direct formula: angle 2 pi u + rotation, radius
                    // sqrt(v), u and v the cell's corner plus the jitter hashed from the seed.
                    const std::uint32_t bits = detail::mixBits(
                        seed ^
                        detail::mixBits(std::uint32_t(radial * kStrata + angular) + 0x9e3779b9U));
                    const double u = (angular + double(detail::unitFloat(bits))) / kStrata;
                    const double v =
                        (radial + double(detail::unitFloat(detail::mixBits(bits)))) / kStrata;
                    const double direct = twoPi * u + rotation;
                    // Float rounding of a unit vector turned twice: a few 1e-7.
                    EXPECT_NEAR(offset.x, std::sqrt(v) * std::cos(direct), 1e-6);
                    EXPECT_NEAR(offset.y, std::sqrt(v) * std::sin(direct), 1e-6);
                }
            }
            for (int count : perCell) EXPECT_EQ(count, 1);
        }
    }
}

/// A sphere of radius 0.3 floating 0.3 above a 3 x 3 plane, under a light of 6 degrees:
/// penumbrae of tan(3 deg) * 0.3..0.9 = 16..47 mm around the shadow, seen by `camera`.
Scene sphereAbovePlane(const Camera& camera, float lightAngleDeg = 6.0f) {
    Scene scene;
    scene.camera = camera;
    scene.lights = {DirectionalLight{{-0.5f, 0.3f, -1.0f}, {1.0f, 1.0f, 1.0f}, lightAngleDeg}};
    scene.objects.push_back(bareSquare(3.0f, 0.0f));
    SceneObject sphere;
    sphere.mesh = makeUvSphere(0.3f, 64, 32);
    applyTransform(sphere.mesh, {{0.0f, 0.0f, 0.6f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    scene.objects.push_back(std::move(sphere));
    return scene;
}

/// The share of the pixels whose 8-bit sRGB values differ by at most 2 between `a` and `b`.
double shareWithin2Codes(const Image& a, const Image& b) {
    const auto srgb8 = [](float linear) {
        return int(std::lround(255.0f * srgbFromLinear(linear)));
    };
    std::size_t close = 0;
    for (std::size_t i = 0; i < a.rgbLinear.size(); ++i) {
        int difference = 0;
        for (int c = 0; c < 3; ++c)
            difference =
                std::max(difference, std::abs(srgb8(a.rgbLinear[i][c]) - srgb8(b.rgbLinear[i][c])));
        close += difference <= 2 ? 1 : 0;
    }
    return double(close) / double(a.rgbLinear.size());
}

/// Renders `alone` (a sphere above its square, seen from above) and `other` at 96 x 96 with
/// 512-texel shadow maps; success when both show the same shadow: as many pixels darker than
/// half the lit ground (the shadow, and the sphere's side away from the light) within a tenth,
/// the alone render holding more than 1/40 of them, and 97% of the pixels within 2 codes.
/// `what` names `other` in the printed figures.
::testing::AssertionResult castsTheShadowOfTheSphereAlone(const Scene& alone, const Scene& other,
                                                          const char* what) {
    RenderOptions options;
    options.width = 96;
    options.height = 96;
    options.shadowMapResolution = 512;
    const RenderResult aloneRender = renderScene(alone, options);
    const RenderResult otherRender = renderScene(other, options);
    const float litGround = aloneRender.image.at(2, 2).x;
    const auto darkPixels = [&](const Image& image) {
        return std::count_if(image.rgbLinear.begin(), image.rgbLinear.end(),
                             [&](const glm::vec3& pixel) { return pixel.x < 0.5f * litGround; });
    };
    const auto aloneDark = darkPixels(aloneRender.image);
    const auto otherDark = darkPixels(otherRender.image);
    const double close = shareWithin2Codes(aloneRender.image, otherRender.image);
    std::printf("[          ] %s: %td dark pixels (alone %td), %.2f%% of pixels within 2 codes\n",
                what, otherDark, aloneDark, 100.0 * close);
    if (!(aloneDark > 96 * 96 / 40))
        return ::testing::AssertionFailure() << "alone: only " << aloneDark << " dark pixels";
    if (!(std::abs(double(otherDark) - double(aloneDark)) <= 0.1 * double(aloneDark)))
        return ::testing::AssertionFailure()
               << what << ": " << otherDark << " dark pixels, alone " << aloneDark;
    if (!(close > 0.97))
        return ::testing::AssertionFailure()
               << what << ": " << 100.0 * close << "% of pixels within 2 codes";
    return ::testing::AssertionSuccess();
}

/// The sphere above the plane and its shadow seen from above, under a light `angleDeg` wide, at
/// 160 x 128 with each shadow filter.
struct RendersByShadowFilter {
    RenderResult full, adaptive, none;
};
RendersByShadowFilter rendersByShadowFilter(float angleDeg) {
    const Scene scene = sphereAbovePlane(
        {{0.4f, -1.2f, 1.8f}, {0.15f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 45.0f}, angleDeg);
    RenderOptions options;
    options.width = 160;
    options.height = 128;
    options.shadowMapResolution = 512;
    RendersByShadowFilter renders;
    options.shadowFilter = ShadowFilter::Full;
    renders.full = renderScene(scene, options);
    options.shadowFilter = ShadowFilter::Adaptive;
    renders.adaptive = renderScene(scene, options);
    options.shadowFilter = ShadowFilter::None;
    renders.none = renderScene(scene, options);
    return renders;
}

TEST(ShadowMap, AGroundFarWiderThanTheObjectsOnItKeepsTheirShadows) {
    // The sphere above its 3 x 3 square, and above a square 3e5 wide, seen from above where the
    // view holds the small square alone (and the sphere's shadow): the same picture. Over the
    // whole ground, the map's texels were 1.5e5 / 512 = 290 units wide, and the shadow was lost;
    // over the region a receiver can be shadowed in (the sphere's footprint, the ground counting
    // only where something reaches behind it), they are 4 x 0.6 / 512 units. The ground's
    // shadows read the finest level both ways, so the maps differ only in their texels' size and
    // place: a few pixels of the penumbra.
    const Camera above{{0.2f, -0.1f, 3.0f}, {0.2f, -0.1f, 0.0f}, {0.0f, 1.0f, 0.0f}, 40.0f};
    const Scene small = sphereAbovePlane(above);
    Scene wide = small;
    wide.objects[0] = bareSquare(3e5f, 0.0f);
    EXPECT_TRUE(castsTheShadowOfTheSphereAlone(small, wide, "ground 3e5 wide"));
}

TEST(ShadowMap, GroupsOfObjectsFarApartHaveAMapEach) {
    // The sphere above its square, and a copy of both 1e4 units away, out of view: the same
    // picture. With one map over both groups its texels were 1e4 / 512 = 20 units wide and the
    // shadow was lost; no blocker of one group can shadow the other, so each has a map of its own.
    const Camera above{{0.2f, -0.1f, 3.0f}, {0.2f, -0.1f, 0.0f}, {0.0f, 1.0f, 0.0f}, 40.0f};
    const Scene alone = sphereAbovePlane(above);
    Scene apart = alone;
    for (std::size_t object = 0; object < alone.objects.size(); ++object) {
        SceneObject copy = alone.objects[object];
        applyTransform(copy.mesh, {{1e4f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
        apart.objects.push_back(std::move(copy));
    }
    const SceneTracer tracer(apart, TraceOptions{});
    const LightShadowMaps maps(tracer, apart.lights[0], 512);
    ASSERT_EQ(maps.size(), 2u);
    const ShadowMap& nearMap = maps.mapFor({0.0f, 0.0f, 0.0f});
    EXPECT_NE(&nearMap, &maps.mapFor({1e4f, 0.0f, 0.0f}));
    EXPECT_LT(nearMap.texelWorld(), 4.0f * 3.0f / 512.0f);
    EXPECT_TRUE(castsTheShadowOfTheSphereAlone(alone, apart, "a copy 1e4 away"));
}

TEST(ShadowMap, OnlyReceiversInViewGetMaps) {
    // The sphere above its square, copied onto a 5 x 5 grid 1e3 units apart: 25 groups, more
    // than a light's maps, of which the camera sees one. Merged into 8 maps, groups shared maps
    // hundreds of units wide, and the shadow was lost; the maps serve the groups in view alone.
    const Camera above{{0.2f, -0.1f, 3.0f}, {0.2f, -0.1f, 0.0f}, {0.0f, 1.0f, 0.0f}, 40.0f};
    const Scene alone = sphereAbovePlane(above);
    Scene grid;
    grid.camera = alone.camera;
    grid.lights = alone.lights;
    for (int row = 0; row < 5; ++row)
        for (int column = 0; column < 5; ++column)
            for (const SceneObject& object : alone.objects) {
                SceneObject copy = object;
                applyTransform(copy.mesh, {{1e3f * float(column - 2), 1e3f * float(row - 2), 0.0f},
                                           {0.0f, 0.0f, 0.0f},
                                           1.0f});
                grid.objects.push_back(std::move(copy));
            }
    const SceneTracer tracer(grid, TraceOptions{});
    const PinholeProjection view(grid.camera, 96, 96);
    // Without the view, the group in view shares a map with others far away.
    EXPECT_GT(LightShadowMaps(tracer, grid.lights[0], 512).mapFor({0.0f, 0.0f, 0.6f}).texelWorld(),
              4.0f * 3.0f / 512.0f);
    const LightShadowMaps inView(tracer, grid.lights[0], 512, &view);
    ASSERT_EQ(inView.size(), 1u);
    EXPECT_LT(inView[0].texelWorld(), 4.0f * 3.0f / 512.0f);
    EXPECT_TRUE(castsTheShadowOfTheSphereAlone(alone, grid, "25 copies 1e3 apart"));
    // A view from 1500 above, between two groups, 60 degrees wide (866 units either way): those
    // two.
    const Camera wide{{500.0f, 0.0f, 1500.0f}, {500.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}, 60.0f};
    const PinholeProjection wideView(wide, 96, 96);
    EXPECT_EQ(LightShadowMaps(tracer, grid.lights[0], 512, &wideView).size(), 2u);
}

TEST(ShadowMap, GroupsFarFromTheEyeShareMapsFirst) {
    // Twelve copies of the sphere above its square in a row receding from the camera, 20, 40,
    // 60, ... units apart, all in view: more groups than a light's maps. Merging the pair whose
    // union is smallest took the nearest two into one map 20 units wide; the pair whose union's
    // texels are smallest beside the pixels at its distance leaves the nearest a map of its own.
    const Camera along{{0.0f, -4.0f, 2.0f}, {0.0f, 10.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    const Scene alone = sphereAbovePlane(along);
    Scene row;
    row.camera = alone.camera;
    row.lights = alone.lights;
    for (int copy = 0; copy < 12; ++copy)
        for (const SceneObject& object : alone.objects) {
            SceneObject moved = object;
            applyTransform(
                moved.mesh,
                {{0.0f, 10.0f * float(copy * (copy + 1)), 0.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
            row.objects.push_back(std::move(moved));
        }
    const SceneTracer tracer(row, TraceOptions{});
    const PinholeProjection view(row.camera, 96, 96);
    const LightShadowMaps maps(tracer, row.lights[0], 512, &view);
    EXPECT_EQ(maps.size(), std::size_t(kMaxShadowMapsPerLight));
    EXPECT_LT(maps.mapFor({0.0f, 0.0f, 0.6f}).texelWorld(), 4.0f * 3.0f / 512.0f);
}

TEST(ShadowMap, AGroundSeenAtAnAngleLeavesObjectsFarApartInMapsOfTheirOwn) {
    // The sphere above its square, and a copy of the sphere 500 units away, over a ground 3e5
    // wide. The light falls at about 60 degrees, so the ground's depth along it spans 1.5e5
    // units. Bounding every receiver's depth by the deepest point of the scene spread each
    // sphere's possible penumbra (tan 3 degrees of that: 8000 units) over the other: one group,
    // whose map's texels (4 x 500 / 512 units) lost the shadow. The ground under a sphere's
    // penumbra lies about 0.3 to 0.9 below it: two groups.
    const Camera above{{0.2f, -0.1f, 3.0f}, {0.2f, -0.1f, 0.0f}, {0.0f, 1.0f, 0.0f}, 40.0f};
    const Scene alone = sphereAbovePlane(above);
    Scene apart = alone;
    apart.objects[0] = bareSquare(3e5f, 0.0f);
    SceneObject copy = alone.objects[1];
    applyTransform(copy.mesh, {{500.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    apart.objects.push_back(std::move(copy));
    EXPECT_EQ(shadowMapAreas(apart, apart.lights[0]).size(), 2u);
    EXPECT_TRUE(castsTheShadowOfTheSphereAlone(alone, apart, "a copy 500 away, ground 3e5 wide"));
}

TEST(ShadowMap, NearReceiversOfACoarseMapReadFinerLevels) {
    // The sphere's hard shadow (a light of angle 0) seen from 1.5 units at 96 x 96: pixels of
    // about 1.5 x tan(20 deg) / 48 = 11 mm where the shadow falls. A map of 64 texels over the
    // scene's 4.2 units has texels of 66 mm: its shadow's edge is a staircase. With the view,
    // the map adds finer levels until its texels are at most kMaxTexelOverPixel pixels of the
    // nearest receiver: the edge follows the shadow of a map of 4096 texels (1 mm).
    const Camera nearby{{0.5f, -0.9f, 1.2f}, {0.3f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    const Scene scene = sphereAbovePlane(nearby, 0.0f);
    const SceneTracer tracer(scene, TraceOptions{});
    const PinholeProjection view(scene.camera, 96, 96);
    const LightShadowMaps withoutView(tracer, scene.lights[0], 64);
    const LightShadowMaps withView(tracer, scene.lights[0], 64, &view);
    ASSERT_EQ(withView.size(), 1u);
    EXPECT_EQ(withoutView[0].levelCount(), ShadowMap::kLevels);
    EXPECT_EQ(withView[0].levelCount(), ShadowMap::kLevels + ShadowMap::kMaxFinerLevels);
    EXPECT_FLOAT_EQ(withView[0].texelWorld(),
                    withoutView[0].texelWorld() / float(1 << ShadowMap::kMaxFinerLevels));
    RenderOptions options;
    options.width = 96;
    options.height = 96;
    options.shadowMapResolution = 4096;
    const RenderResult fine = renderScene(scene, options);
    options.shadowMapResolution = 64;
    const RenderResult coarse = renderScene(scene, options);
    // Texels under a pixel leave differences of a few pixels at most where texel centres fall
    // beside the edge (measured: none); the 64-texel map alone, 46 pixels (0.5%).
    const double close = shareWithin2Codes(fine.image, coarse.image);
    std::printf("[          ] 64 texels with finer levels: %.2f%% of pixels within 2 codes\n",
                100.0 * close);
    EXPECT_GT(close, 0.999);
}

TEST(ShadowMap, SmallBlockersUnderALowWideSunKeepTheirShadows) {
    // The sphere above its square under a sun 30 degrees wide, 11 degrees above the horizon;
    // then over a ground 3e4 wide, with a copy of the sphere 300 units toward the sun. The sun's
    // lower rim is 4 degrees below the horizon, so the copy's penumbra may reach the first
    // sphere's ground, and the two share a map whose texels (0.45 units) are nearly as wide as
    // the sphere (0.6): a blurred, misplaced shadow, 6.5% of the pixels more than 2 codes off
    // the lone sphere's picture. A wide light's map adds finer levels while its texels are wider
    // than a sixteenth of the smallest blocker (at most 3: 0.056 units here).
    const Camera above{{0.2f, -0.1f, 3.0f}, {0.2f, -0.1f, 0.0f}, {0.0f, 1.0f, 0.0f}, 40.0f};
    Scene small = sphereAbovePlane(above, 30.0f);
    small.lights[0].direction = {0.98f, 0.0f, -0.19f};
    Scene wide = small;
    wide.objects[0] = bareSquare(3e4f, 0.0f);
    SceneObject copy = small.objects[1];
    applyTransform(copy.mesh, {{-300.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    wide.objects.push_back(std::move(copy));
    const SceneTracer tracer(wide, TraceOptions{});
    const PinholeProjection view(wide.camera, 96, 96);
    const LightShadowMaps maps(tracer, wide.lights[0], 512, &view);
    ASSERT_EQ(maps.size(), 1u);
    EXPECT_EQ(maps[0].levelCount(), ShadowMap::kLevels + ShadowMap::kMaxFinerLevels);
    RenderOptions options;
    options.width = 96;
    options.height = 96;
    options.shadowMapResolution = 512;
    const double close =
        shareWithin2Codes(renderScene(small, options).image, renderScene(wide, options).image);
    std::printf("[          ] %.2f%% of pixels within 2 codes of the lone sphere's\n",
                100.0 * close);
    // Measured 98.8% (the penumbra's noise); without the finer levels 93.5%.
    EXPECT_GT(close, 0.97);
}

TEST(ShadowMap, ALowBlockerKeepsItsShadowBesideATallOne) {
    // A small sphere just above a 3 x 3 square (radius 0.1, 0.05 above it) under a light 3
    // degrees wide and 21 degrees above the horizon, and a tall sphere 5 units up whose shadow
    // falls on the square's far corner. A lookup searches for blockers as far as the surface
    // nearest to the light anywhere in its map can cast a penumbra: 32 texels (0.2 units) here,
    // about as wide as the small sphere's shadow (0.2 across). The 8 samples of that ring fell
    // beside the shadow, and the adaptive filter called the middle of the umbra lit; the ring's
    // centre is now sampled too.
    Scene scene;
    scene.lights = {DirectionalLight{{0.93f, 0.0f, -0.36f}, {1.0f, 1.0f, 1.0f}, 3.0f}};
    scene.objects.push_back(bareSquare(3.0f, 0.0f));
    for (const auto& [radius, centre] : {std::pair(0.1f, glm::vec3(0.0f, 0.0f, 0.15f)),
                                         std::pair(0.2f, glm::vec3(-12.0f, 1.0f, 5.0f))}) {
        SceneObject sphere;
        sphere.mesh = makeUvSphere(radius, 64, 32);
        applyTransform(sphere.mesh, {centre, {0.0f, 0.0f, 0.0f}, 1.0f});
        scene.objects.push_back(std::move(sphere));
    }
    const SceneTracer tracer(scene, TraceOptions{});
    const LightShadowMaps maps(tracer, scene.lights[0], 512);
    ASSERT_EQ(maps.size(), 1u);
    // The middle of the small sphere's umbra on the ground: its centre's shadow is at x = 0.15 /
    // tan(21.2 deg) = 0.387, and the light ray from every point within 0.11 of that along x and
    // 0.04 across passes within 0.09 of the centre (the penumbra is tan(1.5 deg) x 0.4 = 0.01
    // wide). 0.3 to the side of it the ground is lit. Measured: before, all 60 receivers of the
    // umbra's middle were called lit.
    std::uint64_t samples = 0;
    std::uint32_t seed = 1;
    int litInUmbra = 0, darkBeside = 0, receivers = 0;
    for (float x = 0.28f; x <= 0.501f; x += 0.02f) {
        for (float y = -0.04f; y <= 0.041f; y += 0.02f) {
            const ShadowReceiver inUmbra{{x, y, 0.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, 0};
            litInUmbra += maps.visibility(inUmbra, ShadowFilter::Adaptive, seed++, samples) > 0.0f;
            const ShadowReceiver beside{{x, y + 0.3f, 0.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, 0};
            darkBeside += maps.visibility(beside, ShadowFilter::Adaptive, seed++, samples) < 1.0f;
            ++receivers;
        }
    }
    std::printf("[          ] of %d receivers in the umbra %d see light; beside it %d do not\n",
                receivers, litInUmbra, darkBeside);
    EXPECT_EQ(litInUmbra, 0);
    EXPECT_EQ(darkBeside, 0);
}

TEST(ShadowMap, ObjectsWithinAPenumbraOfEachOtherShareAMap) {
    // Two spheres 0.6 apart on the light's plane, one 1.5 above the other: a light 60 degrees
    // wide spreads the upper one's penumbra over tan(30) x 1.5 = 0.87 around its shadow, onto
    // the lower one, so they need one map; a light half a degree wide does not. A third sphere,
    // 100 units away, has a map of its own either way (and makes the scene too wide for any map
    // to cover all of it).
    Scene scene;
    scene.lights = {DirectionalLight{{0.0f, 0.0f, -1.0f}, {1.0f, 1.0f, 1.0f}, 60.0f}};
    for (const glm::vec3 centre : {glm::vec3(0.0f), glm::vec3(0.6f + 2.0f * 0.3f, 0.0f, 1.5f),
                                   glm::vec3(100.0f, 0.0f, 0.0f)}) {
        SceneObject sphere;
        sphere.mesh = makeUvSphere(0.3f, 16, 8);
        applyTransform(sphere.mesh, {centre, {0.0f, 0.0f, 0.0f}, 1.0f});
        scene.objects.push_back(std::move(sphere));
    }
    EXPECT_EQ(shadowMapAreas(scene, scene.lights[0]).size(), 2u);
    scene.lights[0].angleDeg = 0.5f;
    EXPECT_EQ(shadowMapAreas(scene, scene.lights[0]).size(), 3u);
}

TEST(Renderer, AdaptiveLineTestsMatchFullOnesWithFewerReads) {
    // Under a light wide enough for the line test.
    const auto [full, adaptive, none] = rendersByShadowFilter(2.0f * kLineTestMinAngleDeg);
    const double close = shareWithin2Codes(full.image, adaptive.image);
    std::printf(
        "[          ] line test: texel reads full %llu, adaptive %llu; %.3f%% of pixels "
        "within 2/255\n",
        (unsigned long long)full.stats.shadowMapSamples,
        (unsigned long long)adaptive.stats.shadowMapSamples, 100.0 * close);
    // Adaptive follows half of the lines where they agree (all lit or all blocked): most lookups
    // off the penumbra (measured: 0.61 of full's reads). The same bar as filtering's below.
    EXPECT_GT(full.stats.shadowMapSamples, 10000u);
    EXPECT_LE(double(adaptive.stats.shadowMapSamples), 0.75 * double(full.stats.shadowMapSamples));
    EXPECT_GE(close, 0.995);
}

TEST(Renderer, AdaptiveShadowsMatchFullOnesWithAtMostHalfTheSamples) {
    // Under a light narrow enough to be filtered.
    const auto [full, adaptive, none] = rendersByShadowFilter(0.8f * kLineTestMinAngleDeg);
    const int width = full.image.width, height = full.image.height;

    // Full takes the ring's 9 samples and the disk's 64 per lookup; adaptive the 9, and the 64
    // in a penumbra. Lookups on the plane whose disk holds nothing but the plane take none (the
    // sampled ones are counted here).
    constexpr std::uint64_t kFullLookup = kShadowRingSamples + kShadowDiskSamples;
    const std::uint64_t lookups = full.stats.shadowMapSamples / kFullLookup;
    ASSERT_EQ(full.stats.shadowMapSamples % kFullLookup, 0u);
    ASSERT_GT(lookups, 1000u);
    EXPECT_LT(lookups, std::uint64_t(width * height / 2));
    const std::uint64_t penumbraLookups =
        (adaptive.stats.shadowMapSamples - kShadowRingSamples * lookups) / kShadowDiskSamples;
    EXPECT_GT(penumbraLookups, 100u);  // the scene does have penumbrae
    EXPECT_LE(double(adaptive.stats.shadowMapSamples), 0.5 * double(full.stats.shadowMapSamples));
    EXPECT_EQ(none.stats.shadowMapSamples, 0u);

    // The acceptance criterion: 8-bit sRGB values differ by at most 2 in >= 99.5% of pixels.
    const double close = shareWithin2Codes(full.image, adaptive.image);
    auto srgb8 = [](float linear) { return int(std::lround(255.0f * srgbFromLinear(linear))); };
    std::size_t shadowed = 0;
    for (std::size_t i = 0; i < full.image.rgbLinear.size(); ++i)
        shadowed += srgb8(full.image.rgbLinear[i].x) + 8 < srgb8(none.image.rgbLinear[i].x) ? 1 : 0;
    std::printf(
        "[          ] shadow-map samples full %llu, adaptive %llu (%llu penumbra lookups); "
        "%.3f%% of pixels within 2/255; %zu pixels darkened by the shadow\n",
        (unsigned long long)full.stats.shadowMapSamples,
        (unsigned long long)adaptive.stats.shadowMapSamples, (unsigned long long)penumbraLookups,
        100.0 * close, shadowed);
    EXPECT_GE(close, 0.995);
    EXPECT_GT(shadowed, 500u);     // the sphere casts a visible shadow on the plane
    EXPECT_GE(lookups, shadowed);  // every pixel the shadow darkens was sampled
}

TEST(Renderer, ShadowMapsTraceWhatTheViewNeedsAndDoNotDependOnTheThreadCount) {
    // The sphere above the plane, seen from close by: the view holds a part of
    // the plane, so only a part of the light's map is traced; the tiles are traced by whichever
    // thread first needs them, and the image is the same on 1 and 2 threads.
    const Scene scene =
        sphereAbovePlane({{0.3f, -0.9f, 0.9f}, {0.15f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f});
    RenderOptions options;
    options.width = 160;
    options.height = 128;
    options.shadowMapResolution = 512;
    const RenderResult one = onThreads(1, [&] { return renderScene(scene, options); });
    const RenderResult two = onThreads(2, [&] { return renderScene(scene, options); });
    EXPECT_EQ(one.image.rgbLinear, two.image.rgbLinear);
    EXPECT_EQ(one.stats.shadowMapSamples, two.stats.shadowMapSamples);
    EXPECT_EQ(one.stats.shadowMapTexels, two.stats.shadowMapTexels);
    EXPECT_GT(one.stats.shadowMapSamples, 0u);
    EXPECT_GT(one.stats.shadowMapTexels, 0u);
    EXPECT_LT(one.stats.shadowMapTexels, one.stats.shadowMapTexelsAll / 2);
}

TEST(Renderer, AViewThatLooksUpFromTheSceneTracesNoShadowMap) {
    // The camera above the sphere and the plane looks up and away: the view is sky alone, no
    // lookup reaches the light's map, and the map traces nothing, not even the search for the
    // blocker nearest the light (which a lookup would start).
    const Scene scene =
        sphereAbovePlane({{0.3f, -0.9f, 0.9f}, {0.45f, -1.8f, 1.8f}, {0.0f, 0.0f, 1.0f}, 40.0f});
    RenderOptions options;
    options.width = 64;
    options.height = 48;
    options.shadowMapResolution = 512;
    const RenderResult result = renderScene(scene, options);
    EXPECT_EQ(result.stats.baseHits, 0u);
    EXPECT_GT(result.stats.shadowMapTexelsAll, 0u);  // the map exists
    EXPECT_EQ(result.stats.shadowMapSamples, 0u);
    EXPECT_EQ(result.stats.shadowMapTexels, 0u);
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
    // A value is shown as given (2, 0.1), not with six decimals (2.000000, 0.100000).
    RenderOptions badRelaxation;
    badRelaxation.march.relaxation = 2.0f;
    try {
        renderScene(scene, badRelaxation);
        ADD_FAILURE() << "a relaxation of 2 was accepted";
    } catch (const InputError& error) {
        EXPECT_EQ(error.problem().rfind("2 is not accepted", 0), 0u) << error.what();
    }
    badDepth.objects[0].material.depthWorld = -0.1f;
    try {
        renderScene(badDepth, RenderOptions{});
        ADD_FAILURE() << "a depth of -0.1 was accepted";
    } catch (const InputError& error) {
        EXPECT_NE(std::string(error.what()).find("-0.1 "), std::string::npos) << error.what();
        EXPECT_EQ(std::string(error.what()).find("-0.100000"), std::string::npos) << error.what();
    }
    // A hit threshold below what single precision resolves spent every ray's whole budget.
    RenderOptions small;
    small.width = 8;
    small.height = 8;
    small.march.epsilonTexels = 1e-6f;
    EXPECT_THROW(renderScene(scene, small), InputError);
    small.march.epsilonTexels = 1e-5f;
    EXPECT_NO_THROW(renderScene(scene, small));
    // An image past 2^24 pixels is refused for its size, whatever the sample count.
    RenderOptions huge;
    huge.width = 16384;
    huge.height = 16384;
    try {
        renderScene(scene, huge);
        ADD_FAILURE() << "a 16384x16384 image was accepted";
    } catch (const InputError& error) {
        EXPECT_EQ(error.field(), "width");
        EXPECT_NE(error.problem().find("16384x16384"), std::string::npos) << error.what();
    }
    // An eye so far away that the view direction's squared length overflows: refused as such
    // (it used to be reported as an up vector parallel to the view).
    Scene farEye = scene;
    farEye.camera.eye = {0.0f, -1e30f, 1e30f};
    try {
        renderScene(farEye, RenderOptions{});
        ADD_FAILURE() << "an eye at 1e30 was accepted";
    } catch (const InputError& error) {
        EXPECT_NE(std::string(error.what()).find("too far from camera.eye"), std::string::npos)
            << error.what();
    }
}

TEST(Renderer, OnlyTheDirectionOfALightAndOfTheCameraUpCounts) {
    // Lengths whose squares single precision cannot hold (1e19 and more, 1e-19 and less) render
    // as the unit vectors do, to rounding (they are normalised in double precision); they used to
    // drop the light (the image lost its direct light) and tilt the camera (most rays missed).
    Tile tile({16, 16, 8});
    for (int z = 0; z < 8; ++z)
        for (int y = 0; y < 16; ++y)
            for (int x = 0; x < 16; ++x)
                tile.at(x, y, z) = (z + 0.5f) - (3.0f + 2.0f * std::sin(2 * kPi * (x + 0.5f) / 16));
    Scene scene = planeScene(std::make_shared<const Tile>(std::move(tile)));
    scene.lights = {DirectionalLight{}};
    scene.lights[0].direction = {0.3f, 0.2f, -1.0f};
    RenderOptions options;
    options.width = 48;
    options.height = 32;
    const Image unit = renderScene(scene, options).image;
    const auto largestDifference = [&](const Scene& other) {
        const Image image = renderScene(other, options).image;
        float largest = 0.0f;
        for (std::size_t i = 0; i < unit.rgbLinear.size(); ++i) {
            const glm::vec3 difference = glm::abs(image.rgbLinear[i] - unit.rgbLinear[i]);
            largest = std::max({largest, difference.x, difference.y, difference.z});
        }
        return largest;
    };
    // Rounding: an ulp of a camera ray moves its self-shadow ray, whose estimate of the light's
    // disk is steep in the penumbra near its start (distance / (travel x tan), travel from 0.1
    // texel): up to 4e-4 in linear value (0.05 of an 8-bit code) on this tile.
    for (const float length : {1e-30f, 1e-20f, 2e19f, 1e30f}) {
        SCOPED_TRACE(length);
        Scene longer = scene;
        longer.lights[0].direction *= length;
        EXPECT_LT(largestDifference(longer), 1e-3f);
        longer = scene;
        longer.camera.up *= length;
        EXPECT_LT(largestDifference(longer), 1e-3f);
    }
    EXPECT_EQ(unitDirection(glm::vec3(0.0f)), glm::vec3(0.0f));
    EXPECT_EQ(unitDirection({0.0f, -1e30f, 0.0f}), glm::vec3(0.0f, -1.0f, 0.0f));
}

TEST(Image, EightBitSrgbCodesByTableAreTheCodesOfTheTransferFunction) {
    const auto exact = [](float linear) {
        return int(std::lround(srgbFromLinear(linear) * 255.0f));
    };
    const auto floatOf = [](std::uint32_t pattern) { return std::bit_cast<float>(pattern); };
    // Every 509th float of [0, 1] (non-negative floats are ordered as their bit patterns), and
    // wherever the code changed since the last one, every float within 4096 of there: a power
    // that was not monotonic would show there, and so would a threshold off by one float.
    const std::uint32_t one = std::bit_cast<std::uint32_t>(1.0f);
    constexpr std::uint32_t kStride = 509, kNear = 4096;
    std::size_t changes = 0;
    int previousCode = exact(0.0f);
    for (std::uint32_t pattern = 0; pattern <= one; pattern += kStride) {
        const float value = floatOf(pattern);
        const int code = exact(value);
        ASSERT_EQ(int(srgbCode8(value)), code) << value;
        if (code != previousCode) {
            ++changes;
            const std::uint32_t from = pattern > kStride + kNear ? pattern - kStride - kNear : 0;
            for (std::uint32_t near = from; near <= std::min(pattern + kNear, one); ++near)
                ASSERT_EQ(int(srgbCode8(floatOf(near))), exact(floatOf(near))) << floatOf(near);
        }
        previousCode = code;
    }
    EXPECT_EQ(changes, std::size_t(255));
    for (const float value : {0.0f, -0.0f, -1.0f, 1.0f, 1.5f, 1e30f, 0.0031308f,
                              std::numeric_limits<float>::denorm_min()}) {
        EXPECT_EQ(int(srgbCode8(value)), exact(value)) << value;
    }
}

TEST(Image, WritingRefusesTheFirstPixelThatIsNotFiniteAndWritesNothing) {
    // Bad pixels far apart (the check runs over ranges in parallel): the first one is named.
    Image image(300, 200, glm::vec3(0.5f));
    image.rgbLinear[std::size_t(150 * 300 + 7)].g = std::numeric_limits<float>::infinity();
    image.rgbLinear[std::size_t(60 * 300 + 250)].b = std::nanf("");
    image.rgbLinear[std::size_t(199 * 300 + 299)].r = -std::numeric_limits<float>::infinity();
    const std::string file = ::testing::TempDir() + "distile_not_finite.png";
    std::remove(file.c_str());
    try {
        writeImage(image, file);
        ADD_FAILURE() << "an image with a NaN was written";
    } catch (const InternalError& error) {
        EXPECT_NE(std::string(error.what()).find("pixel (250, 60)"), std::string::npos)
            << error.what();
    }
    EXPECT_FALSE(std::filesystem::exists(file));
}

TEST(Renderer, RejectsTexelSpacesTooDenseForFloatAndRendersTheDensestAccepted) {
    // Texels per world unit square into a texel-space ray's length: 1e20 along u (uv scale 2.5e19
    // on the 2-unit plane's 8 texels) overflowed to NaN pixels; now refused, naming the object
    // and the axis. Just below the limit the image is finite.
    RenderOptions options;
    options.width = 24;
    options.height = 16;
    const auto message = [&](const Scene& scene) {
        try {
            renderScene(scene, options);
        } catch (const InputError& error) {
            return std::string(error.what());
        }
        return std::string("accepted");
    };
    const Scene scene = planeScene(std::make_shared<const Tile>(Size3{8, 8, 4}, 1.0f));
    Scene denseU = scene;
    denseU.objects[0].material.uvScale.x = 2.5e19f;
    EXPECT_NE(message(denseU).find("objects[0].material: 1e+20 texels per world unit along u"),
              std::string::npos)
        << message(denseU);
    Scene thinDepth = scene;
    thinDepth.objects[0].material.depthWorld = 1e-20f;
    EXPECT_NE(message(thinDepth).find("texels per world unit along depth"), std::string::npos)
        << message(thinDepth);
    Scene densest = scene;
    densest.objects[0].material.uvScale = {2.4e14f, 2.4e14f};  // 9.6e14 texels per world unit
    densest.objects[0].material.depthWorld = 4.5e-15f;
    const RenderResult result = renderScene(densest, options);
    for (const glm::vec3& pixel : result.image.rgbLinear)
        ASSERT_TRUE(std::isfinite(pixel.x) && std::isfinite(pixel.y) && std::isfinite(pixel.z));
    EXPECT_GT(result.stats.baseHits, result.stats.rays / 2);
}

TEST(Renderer, RefusesColoursWhoseProductsOverflowAndRendersTheBrightestAccepted) {
    // A pixel sums albedo x light colour: at 1e30 each (a scene's colours were accepted up to
    // 1e30) the product overflowed to an infinite pixel. Now refused, naming the component; at
    // the bound (1e9), with six lights and four samples a pixel, the image is finite.
    RenderOptions options;
    options.width = 8;
    options.height = 6;
    options.samplesPerPixel = 4;
    const auto field = [&](const Scene& scene) {
        try {
            renderScene(scene, options);
        } catch (const InputError& error) {
            return error.field() + ": " + error.problem();
        }
        return std::string("accepted");
    };
    Scene overflowing = planeScene(nullptr);
    overflowing.lights[0].color = {1e30f, 1.0f, 1.0f};
    overflowing.objects[0].material.color = {1e30f, 0.5f, 0.5f};
    EXPECT_EQ(field(overflowing).rfind("lights[0].color[0]: 1e+30 is not accepted", 0), 0u)
        << field(overflowing);
    Scene brightAlbedo = planeScene(nullptr);
    brightAlbedo.objects[0].material.color = {0.5f, 2e9f, 0.5f};
    EXPECT_EQ(field(brightAlbedo).rfind("objects[0].material.color[1]: 2e+09", 0), 0u)
        << field(brightAlbedo);
    Scene brightest = planeScene(nullptr);
    brightest.lights.assign(6, DirectionalLight{{-0.4f, -0.3f, -1.0f}, glm::vec3(1e9f), 2.0f});
    brightest.objects[0].material.color = glm::vec3(1e9f);
    const RenderResult result = renderScene(brightest, options);
    for (const glm::vec3& pixel : result.image.rgbLinear)
        ASSERT_TRUE(std::isfinite(pixel.x) && std::isfinite(pixel.y) && std::isfinite(pixel.z));
    EXPECT_GT(result.stats.baseHits, result.stats.rays / 2);
}

// ---- Conservative rasterization (ch. 42): coverage and shell culling -------------------------

/// Exact overlap of a closed triangle and the closed box [x0, x1] x [y0, y1] in double precision,
/// by the separating axis theorem: the box's two axes and the triangle's three edge normals.
bool triangleBoxOverlapExact(const glm::dvec2 corners[3], double x0, double y0, double x1,
                             double y1) {
    const glm::dvec2 box[4] = {{x0, y0}, {x1, y0}, {x0, y1}, {x1, y1}};
    auto separated = [&](const glm::dvec2& axis) {
        double triangleMin = 1e300, triangleMax = -1e300, boxMin = 1e300, boxMax = -1e300;
        for (int i = 0; i < 3; ++i) {
            triangleMin = std::min(triangleMin, glm::dot(axis, corners[i]));
            triangleMax = std::max(triangleMax, glm::dot(axis, corners[i]));
        }
        for (const glm::dvec2& corner : box) {
            boxMin = std::min(boxMin, glm::dot(axis, corner));
            boxMax = std::max(boxMax, glm::dot(axis, corner));
        }
        return triangleMax < boxMin || boxMax < triangleMin;
    };
    if (separated({1.0, 0.0}) || separated({0.0, 1.0})) return false;
    for (int i = 0; i < 3; ++i) {
        const glm::dvec2 edge = corners[(i + 1) % 3] - corners[i];
        if (separated({-edge.y, edge.x})) return false;
    }
    return true;
}

/// Random triangles in pixel coordinates of a small screen: slivers under 0.1 pixel wide, tiny
/// ones inside one pixel, huge ones reaching past the screen, and ordinary ones.
std::vector<std::array<glm::dvec2, 3>> randomScreenTriangles(int count, double screenSize,
                                                             std::mt19937& random) {
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<std::array<glm::dvec2, 3>> triangles;
    for (int i = 0; i < count; ++i) {
        const glm::dvec2 a(unit(random) * screenSize, unit(random) * screenSize);
        std::array<glm::dvec2, 3> t;
        switch (i % 4) {
            case 0: {  // sliver: long and at most 0.1 pixel wide
                const double angle = unit(random) * 6.2831853;
                const glm::dvec2 along(std::cos(angle), std::sin(angle));
                const glm::dvec2 across(-along.y, along.x);
                const double length = 1.0 + unit(random) * screenSize;
                t = {a, a + along * length,
                     a + along * (unit(random) * length) + across * (unit(random) * 0.1)};
                break;
            }
            case 1: {  // tiny, inside one pixel
                const glm::dvec2 pixel = glm::floor(a);
                t = {pixel + glm::dvec2(unit(random), unit(random)),
                     pixel + glm::dvec2(unit(random), unit(random)),
                     pixel + glm::dvec2(unit(random), unit(random))};
                break;
            }
            case 2:  // huge: corners far outside the screen
                for (auto& corner : t)
                    corner = glm::dvec2(unit(random), unit(random)) * (6.0 * screenSize) -
                             2.5 * screenSize;
                break;
            default:
                t = {a, glm::dvec2(unit(random), unit(random)) * screenSize,
                     glm::dvec2(unit(random), unit(random)) * screenSize};
        }
        triangles.push_back(t);
    }
    return triangles;
}

TEST(Coverage, CameraRaysInBulkAreTheRaysOneAtATime) {
    // directions() takes four rays at a time (SSE2) and the rest one at a time; ray() takes one.
    // Bit for bit the same, and unit length and through the pixel within float rounding.
    const Camera camera{{0.2f, -2.5f, 1.3f}, {0.0f, 0.1f, 0.2f}, {0.0f, 0.0f, 1.0f}, 50.0f};
    const PinholeProjection projection(camera, 1280, 1024);
    std::mt19937 random(3);
    std::uniform_real_distribution<float> pixel(-2000.0f, 3000.0f);
    constexpr std::size_t kCount = 67;  // 16 groups of four, and three alone
    float xPixels[kCount], yPixels[kCount], x[kCount], y[kCount], z[kCount];
    for (std::size_t i = 0; i < kCount; ++i) {
        xPixels[i] = pixel(random);
        yPixels[i] = pixel(random);
    }
    projection.directions(xPixels, yPixels, kCount, x, y, z);
    for (std::size_t i = 0; i < kCount; ++i) {
        const Ray single = projection.ray(xPixels[i], yPixels[i]);
        ASSERT_EQ(single.direction, glm::vec3(x[i], y[i], z[i])) << i;
        ASSERT_EQ(single.origin, camera.eye);
        EXPECT_NEAR(glm::length(single.direction), 1.0f, 1e-6f);
        const glm::dvec2 back = projection.toPixels(
            projection.toView(camera.eye + single.direction) - projection.toView(camera.eye));
        EXPECT_NEAR(back.x, xPixels[i], 1e-3 * (1.0 + std::abs(xPixels[i])));
        EXPECT_NEAR(back.y, yPixels[i], 1e-3 * (1.0 + std::abs(yPixels[i])));
    }
}

TEST(Coverage, EveryTouchedPixelPassesAndFarPixelsFail) {
    // 4000 random triangles on a 32 x 32 screen, every pixel tested against the exact overlap.
    // The 2D test is the separating axis test itself, up to a 1e-12 relative rounding allowance,
    // so it must accept every touched pixel and reject every pixel 1e-6 pixel away or farther.
    std::mt19937 random(42);
    constexpr int kScreen = 32;
    std::uint64_t touched = 0, accepted = 0, farButAccepted = 0;
    for (const auto& corners : randomScreenTriangles(4000, kScreen, random)) {
        const ScreenTriangle triangle = screenTriangle(corners.data());
        for (int y = 0; y < kScreen; ++y) {
            for (int x = 0; x < kScreen; ++x) {
                const bool exact = triangleBoxOverlapExact(corners.data(), x, y, x + 1, y + 1);
                const bool conservative = trianglePixelOverlapConservative(triangle, x, y);
                touched += exact;
                accepted += conservative;
                ASSERT_TRUE(!exact || conservative)
                    << "pixel " << x << "," << y << " of a touching triangle skipped";
                const double e = 1e-6;
                if (!triangleBoxOverlapExact(corners.data(), x - e, y - e, x + 1 + e, y + 1 + e))
                    farButAccepted += conservative;
            }
        }
    }
    EXPECT_GT(touched, 50000u);  // the test exercised coverage, not only empty screens
    EXPECT_EQ(farButAccepted, 0u);
    std::printf(
        "[          ] 2D coverage: %llu touched pixels, %llu accepted (overestimation %.4f%%)\n",
        (unsigned long long)touched, (unsigned long long)accepted,
        100.0 * double(accepted - touched) / double(touched));
}

TEST(Coverage, ACoveredRectangleHasOnlyPixelsThatPass) {
    // triangleCoversRect lets the camera rays of a screen tile skip the per-pixel test: for 4000
    // random triangles and 4 x 4 pixel rectangles on a 32 x 32 screen, every pixel of a covered
    // rectangle must pass the per-pixel test and lie inside the triangle (exact test on the
    // pixel shrunk by 1e-6); and coverage must be found where the triangle is large.
    std::mt19937 random(43);
    constexpr int kScreen = 32;
    constexpr int kRect = 4;
    int covered = 0;
    for (const auto& corners : randomScreenTriangles(4000, kScreen, random)) {
        const ScreenTriangle triangle = screenTriangle(corners.data());
        for (int y0 = 0; y0 < kScreen; y0 += kRect) {
            for (int x0 = 0; x0 < kScreen; x0 += kRect) {
                if (!triangleCoversRect(triangle, x0, y0, x0 + kRect, y0 + kRect)) continue;
                ++covered;
                for (int y = y0; y < y0 + kRect; ++y) {
                    for (int x = x0; x < x0 + kRect; ++x) {
                        ASSERT_TRUE(trianglePixelOverlapConservative(triangle, x, y))
                            << x << "," << y;
                        const double e = 1e-6;
                        ASSERT_TRUE(triangleBoxOverlapExact(corners.data(), x + e, y + e, x + 1 - e,
                                                            y + 1 - e))
                            << x << "," << y;
                    }
                }
            }
        }
    }
    EXPECT_GT(covered, 1000);
}

TEST(Coverage, ProjectedTrianglesAreCoveredConservatively) {
    // The same triangles placed in 3D in front of a pinhole camera (each corner at its own depth),
    // and triangles crossing the plane of the eye. Truth for the first kind: the exact overlap of
    // the corners projected in double precision with a basis computed here. The single-precision
    // camera basis and rays justify the projection's margin (about 1e-4 pixel here), so pixels
    // 0.01 pixel or farther from the triangle must be rejected. For eye-crossing triangles the
    // truth is sampled: a camera ray through the pixel that hits the triangle needs a pass.
    std::mt19937 random(7);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    constexpr int kWidth = 48, kHeight = 32;
    const Camera camera{{0.2f, -2.5f, 1.3f}, {0.0f, 0.1f, 0.2f}, {0.0f, 0.0f, 1.0f}, 50.0f};
    const PinholeProjection projection(camera, kWidth, kHeight);
    ASSERT_LT(projection.marginPixels(), 1e-3);
    const glm::dvec3 forward = glm::normalize(glm::dvec3(camera.target) - glm::dvec3(camera.eye));
    const glm::dvec3 right = glm::normalize(glm::cross(forward, glm::dvec3(camera.up)));
    const glm::dvec3 up = glm::cross(right, forward);
    const double tanY = std::tan(0.5 * camera.fovDeg * 3.14159265358979 / 180.0);
    const double tanX = tanY * kWidth / kHeight;
    auto toPixels = [&](const glm::vec3& world) {
        const glm::dvec3 d = glm::dvec3(world) - glm::dvec3(camera.eye);
        const double z = glm::dot(d, forward);
        return glm::dvec2((glm::dot(d, right) / z / tanX + 1.0) * 0.5 * kWidth,
                          (1.0 - glm::dot(d, up) / z / tanY) * 0.5 * kHeight);
    };
    auto toWorld = [&](const glm::dvec2& pixels, double depth) {
        const glm::dvec3 direction = forward + right * ((2.0 * pixels.x / kWidth - 1.0) * tanX) +
                                     up * ((1.0 - 2.0 * pixels.y / kHeight) * tanY);
        return glm::vec3(glm::dvec3(camera.eye) + direction * depth);
    };
    std::uint64_t touched = 0, accepted = 0, farButAccepted = 0, sampledHits = 0;
    for (const auto& pixels : randomScreenTriangles(2000, kHeight, random)) {
        glm::vec3 world[3];
        glm::dvec2 projected[3];
        for (int i = 0; i < 3; ++i) {
            world[i] = toWorld(pixels[i] + glm::dvec2(8.0, 0.0), 0.5 + 3.0 * unit(random));
            projected[i] = toPixels(world[i]);
        }
        const ScreenTriangle triangle = projectTriangle(projection, world);
        for (int y = 0; y < kHeight; ++y) {
            for (int x = 0; x < kWidth; ++x) {
                const bool exact = triangleBoxOverlapExact(projected, x, y, x + 1, y + 1);
                const bool conservative = trianglePixelOverlapConservative(triangle, x, y);
                touched += exact;
                accepted += conservative;
                ASSERT_TRUE(!exact || conservative) << "pixel " << x << "," << y << " skipped";
                const double e = 0.01;
                if (!triangleBoxOverlapExact(projected, x - e, y - e, x + 1 + e, y + 1 + e))
                    farButAccepted += conservative;
            }
        }
    }
    EXPECT_GT(touched, 50000u);
    EXPECT_EQ(farButAccepted, 0u);
    std::printf(
        "[          ] projected coverage: %llu touched pixels, %llu accepted (overestimation "
        "%.4f%%)\n",
        (unsigned long long)touched, (unsigned long long)accepted,
        100.0 * double(accepted - touched) / double(touched));

    std::uniform_real_distribution<float> around(-3.0f, 3.0f);
    for (int i = 0; i < 300; ++i) {
        // One corner behind the eye (negative depth), two in front, then random offsets.
        glm::vec3 world[3] = {
            toWorld({unit(random) * kWidth, unit(random) * kHeight}, -0.5 - unit(random)),
            toWorld({unit(random) * kWidth, unit(random) * kHeight}, 0.2 + unit(random)),
            glm::vec3(around(random), around(random), around(random))};
        const ScreenTriangle triangle = projectTriangle(projection, world);
        for (int y = 0; y < kHeight; ++y) {
            for (int x = 0; x < kWidth; ++x) {
                for (int sample = 0; sample < 4; ++sample) {
                    const Ray ray =
                        projection.ray(float(x + unit(random)), float(y + unit(random)));
                    double distance, b1, b2;
                    if (!intersectTriangle(ray, world[0], world[1], world[2], 0.0, 1e30, distance,
                                           b1, b2))
                        continue;
                    ++sampledHits;
                    ASSERT_TRUE(trianglePixelOverlapConservative(triangle, x, y))
                        << "eye-crossing triangle " << i;
                }
            }
        }
    }
    EXPECT_GT(sampledHits, 10000u);
}

/// Planes stacked half a shell depth apart (overlapping shells) under a wavy height field whose
/// valleys cut through the floor: the top plane's floor is open, so rays see its detail and,
/// through its holes and between its crests, the detail of the planes below.
Scene stackedPlanesScene() {
    Tile tile({32, 32, 16});
    for (int z = 0; z < 16; ++z)
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 32; ++x)
                tile.at(x, y, z) =
                    0.5f * ((z + 0.5f) - (4.0f + 6.0f * std::sin(2 * kPi * (x + 0.5f) / 32) *
                                                     std::cos(2 * kPi * (y + 0.5f) / 32)));
    const auto shared = std::make_shared<const Tile>(std::move(tile));
    Scene scene;
    scene.camera = {{0.3f, -1.6f, 1.2f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    const float depthWorld = 0.25f;
    for (int layer = 0; layer < 6; ++layer) {
        SceneObject plane;
        plane.mesh = makePlane(2.0f, 12);
        applyTransform(
            plane.mesh,
            {{0.05f * layer, 0.0f, -0.5f * depthWorld * layer}, {0.0f, 0.0f, 7.0f * layer}, 1.0f});
        plane.material.tile = shared;
        plane.material.uvScale = {3.0f, 3.0f};
        plane.material.depthWorld = depthWorld;
        plane.material.floor = layer == 0 ? Floor::Open : Floor::Solid;
        scene.objects.push_back(std::move(plane));
    }
    return scene;
}

TEST(ShellCulling, SameImageWithAndWithoutCullingAndThreads) {
    const Scene scene = stackedPlanesScene();
    RenderOptions options;
    options.width = 80;
    options.height = 60;
    options.samplesPerPixel = 2;
    options.outputAovs = true;
    options.shadowFilter =
        ShadowFilter::None;  // shadow maps trace with the BVH: not under test here
    RenderResult reference;
    for (const bool culling : {false, true}) {
        for (const int threads : {1, 2}) {
            tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
            options.skips.shellCulling = culling;
            const RenderResult result = renderScene(scene, options);
            if (!culling && threads == 1) {
                reference = result;
                continue;
            }
            // Culling only skips shells that cannot be strictly nearer than the hit in hand, so the
            // hits, hence the image and depths, are bit-identical.
            EXPECT_EQ(result.image.rgbLinear, reference.image.rgbLinear)
                << culling << " " << threads;
            EXPECT_EQ(result.aovs->depth.rgbLinear, reference.aovs->depth.rgbLinear)
                << culling << " " << threads;
            EXPECT_EQ(result.stats.baseHits, reference.stats.baseHits);
            // Converged rays are counted per ray, by their nearest hit: culling (fewer marches)
            // leaves the count as it is, and no more rays converge than hit.
            EXPECT_EQ(result.stats.converged, reference.stats.converged);
            EXPECT_LE(reference.stats.converged, reference.stats.baseHits);
            EXPECT_GT(reference.stats.converged, reference.stats.baseHits / 2);
            if (!culling) {
                EXPECT_EQ(result.stats.shellsTraced, reference.stats.shellsTraced);
                continue;
            }
            std::printf(
                "[          ] shells tested %llu -> %llu, traced %llu -> %llu, march iterations "
                "%llu -> %llu\n",
                (unsigned long long)reference.stats.shellsTested,
                (unsigned long long)result.stats.shellsTested,
                (unsigned long long)reference.stats.shellsTraced,
                (unsigned long long)result.stats.shellsTraced,
                (unsigned long long)reference.stats.marchIterations,
                (unsigned long long)result.stats.marchIterations);
            // Six layers overlap everywhere, but the solid floor of the second, a shell depth below
            // the top, hides the last four: only the top two (plus neighbours sharing the pixel)
            // need tracing, about 2/6 of the shells; measured 0.51, asserted below 0.6.
            EXPECT_LT(result.stats.shellsTraced * 5, reference.stats.shellsTraced * 3);
            EXPECT_EQ(result.stats.shellsTested,
                      reference.stats.shellsTested);  // coverage tests come first
            EXPECT_LT(result.stats.marchIterations, reference.stats.marchIterations);
        }
    }
    EXPECT_GT(reference.stats.baseHits, reference.stats.rays / 2);
}

TEST(ShellCulling, BinsHoldEveryShellACameraRayEnters) {
    // Brute force over all shells: every front-facing top a camera ray hits must be binned to the
    // ray's tile and pass the pixel test, and its depth bound must not exceed the hit distance.
    const Scene scene = stackedPlanesScene();
    const SceneTracer tracer(scene, TraceOptions{});
    constexpr int kWidth = 70, kHeight = 50;
    const PinholeProjection projection(scene.camera, kWidth, kHeight);
    const ScreenShells shells(tracer, projection);
    std::mt19937 random(3);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::uint64_t entries = 0;
    for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) {
            const Ray ray = projection.ray(x + unit(random), y + unit(random));
            const auto bin =
                shells.tileShells(x / ScreenShells::kTilePixels, y / ScreenShells::kTilePixels);
            for (std::uint32_t shell = 0; shell < tracer.shellCount(); ++shell) {
                glm::vec3 top[3], bottom[3];
                tracer.shellCorners(shell, top, bottom);
                double distance, b1, b2;
                if (!intersectTriangle(ray, top[0], top[1], top[2], 0.0, 1e30, distance, b1, b2))
                    continue;
                if (glm::dot(glm::cross(top[1] - top[0], top[2] - top[0]), ray.direction) >= 0.0f)
                    continue;
                ++entries;
                ASSERT_NE(std::find(bin.begin(), bin.end(), shell), bin.end())
                    << x << "," << y << " shell " << shell;
                ASSERT_TRUE(trianglePixelOverlapConservative(shells.bounds(shell).top, x, y));
                ASSERT_LE(shells.pixelDepthBound(shell, x, y), float(distance));
            }
        }
    }
    EXPECT_GT(entries,
              std::uint64_t(kWidth * kHeight));  // layers overlap: more entries than pixels
    // Bins are nearest first.
    for (int tileY = 0; tileY < shells.tilesY(); ++tileY) {
        for (int tileX = 0; tileX < shells.tilesX(); ++tileX) {
            const auto bin = shells.tileShells(tileX, tileY);
            for (std::size_t i = 1; i < bin.size(); ++i) {
                EXPECT_LE(shells.bounds(bin[i - 1]).zMinWorld, shells.bounds(bin[i]).zMinWorld);
            }
        }
    }
}

TEST(ShellCulling, EveryShellPassingAPixelTestIsInThePixelsBin) {
    // The bins decide nothing: a shell whose top passes a pixel's test (its square grown by the
    // margin) is in the bin of that pixel's tile, also where the top's bounds end within the
    // margin of a tile's side. A fine torus (49 k small triangles) seen by the demo's camera at
    // full size has such tops; binning by the bare bounds left them out of the next tile. And the
    // ray of each pixel near a shell's bounds takes the shell exactly where the pixel's test
    // passes (the bin's pixel masks, taken once per bin entry).
    Scene scene;
    scene.camera = {{0.0f, -3.4f, 2.3f}, {0.0f, 0.1f, 0.25f}, {0.0f, 0.0f, 1.0f}, 38.0f};
    SceneObject torus;
    torus.mesh = makeTorus(0.75f, 0.32f, 192, 64);
    scene.objects.push_back(std::move(torus));
    const SceneTracer tracer(scene, TraceOptions{});
    constexpr int kWidth = 1280, kHeight = 1024;
    const PinholeProjection projection(scene.camera, kWidth, kHeight);
    const ScreenShells shells(tracer, projection);
    std::uint64_t passes = 0, besideBounds = 0;
    for (std::uint32_t shell = 0; shell < tracer.shellCount(); ++shell) {
        const ScreenTriangle& top = shells.bounds(shell).top;
        if (top.empty()) continue;
        const int x0 = std::max(int(std::floor(top.boundsMin.x)) - 1, 0);
        const int y0 = std::max(int(std::floor(top.boundsMin.y)) - 1, 0);
        const int x1 = std::min(int(std::floor(top.boundsMax.x)) + 1, kWidth - 1);
        const int y1 = std::min(int(std::floor(top.boundsMax.y)) + 1, kHeight - 1);
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                const bool pass = trianglePixelOverlapConservative(top, x, y);
                ASSERT_EQ(shells.pixelTakes(shell, x, y), pass)
                    << "pixel " << x << "," << y << " shell " << shell;
                if (!pass) continue;
                ++passes;
                // The pixel's square itself is beyond the bounds: only the margin reaches them.
                if (x > top.boundsMax.x || x + 1 < top.boundsMin.x || y > top.boundsMax.y ||
                    y + 1 < top.boundsMin.y)
                    ++besideBounds;
                const auto bin =
                    shells.tileShells(x / ScreenShells::kTilePixels, y / ScreenShells::kTilePixels);
                ASSERT_NE(std::find(bin.begin(), bin.end(), shell), bin.end())
                    << "pixel " << x << "," << y << " shell " << shell;
            }
    }
    EXPECT_GT(passes, std::uint64_t(kWidth * kHeight / 4));
    EXPECT_GT(besideBounds, 0u);  // the case that was missed is there
}

TEST(ShellCulling, BatchesTraceEveryRayAsItsOwnTrace) {
    // Six overlapping layers (an open floor on top): rays enter several shells one after another,
    // so a batch takes several rounds of interleaved marches. Each ray's hit and counters must be
    // those of tracing it alone, with and without culling, for any batch length.
    const Scene scene = stackedPlanesScene();
    const SceneTracer tracer(scene, TraceOptions{});
    constexpr int kWidth = 64, kHeight = 48;
    const PinholeProjection projection(scene.camera, kWidth, kHeight);
    const ScreenShells shells(tracer, projection);
    int multiRound = 0, hits = 0;
    for (const bool culling : {true, false}) {
        for (const std::size_t batch : {std::size_t(16), std::size_t(5)}) {
            for (int y = 0; y < kHeight; ++y) {
                for (int x0 = 0; x0 < kWidth; x0 += int(batch)) {
                    const std::size_t count = std::min(batch, std::size_t(kWidth - x0));
                    std::vector<ScreenShells::PixelRay> rays;
                    for (std::size_t k = 0; k < count; ++k) {
                        const int x = x0 + int(k);
                        rays.push_back({x, y, projection.ray(x + 0.5f, y + 0.5f)});
                    }
                    std::vector<SurfaceHit> batchHits(count);
                    bool batchFound[ScreenShells::kMaxBatchRays] = {};
                    std::vector<TraceCounters> batchCounters(count);
                    ShellCounters batchShells, singleShells;
                    shells.traceNearestBatch(rays, culling, batchHits,
                                             std::span<bool>(batchFound, count), batchCounters,
                                             batchShells);
                    for (std::size_t k = 0; k < count; ++k) {
                        SurfaceHit hit;
                        TraceCounters counters;
                        const bool found = shells.traceNearest(rays[k].x, y, rays[k].ray, culling,
                                                               hit, counters, singleShells);
                        const std::string where =
                            std::to_string(rays[k].x) + "," + std::to_string(y);
                        ASSERT_EQ(found, batchFound[k]) << where;
                        EXPECT_EQ(counters.shellEntries, batchCounters[k].shellEntries) << where;
                        EXPECT_EQ(counters.marchIterations, batchCounters[k].marchIterations)
                            << where;
                        if (counters.shellEntries > 1) ++multiRound;
                        if (!found) continue;
                        ++hits;
                        EXPECT_EQ(hit.object, batchHits[k].object) << where;
                        EXPECT_EQ(hit.distanceWorld, batchHits[k].distanceWorld) << where;
                        EXPECT_EQ(hit.normal.x, batchHits[k].normal.x) << where;
                        EXPECT_EQ(hit.normal.y, batchHits[k].normal.y) << where;
                        EXPECT_EQ(hit.normal.z, batchHits[k].normal.z) << where;
                    }
                    EXPECT_EQ(batchShells.tested, singleShells.tested);
                    EXPECT_EQ(batchShells.traced, singleShells.traced);
                    singleShells = {};
                }
            }
        }
    }
    EXPECT_GT(hits, 4 * kWidth * kHeight / 2);
    EXPECT_GT(multiRound, 1000);  // rays that marched through the open top layer into the next
}

TEST(ShellCulling, PixelsUnderMoreShellsThanKeptInlineFindTheBvhsHits) {
    // 72 planes stacked apart from one another under a camera looking straight down, each
    // filling the view: every pixel takes more candidate shells than a pixel keeps inline (64),
    // the rest in the batch's overflow vectors. The 70 upper planes hold empty tiles over open
    // floors, so every ray passes through them and hits one of the two deepest, whose shells
    // come last in the pixels' nearest-first candidates, in the overflow. Each ray's hit must be
    // the one the BVH's path finds for it (no candidates there; the shells do not overlap, so
    // the two paths run the same marches), with culling and without.
    const Scene stacked = stackedPlanesScene();
    const auto empty = std::make_shared<const Tile>(Size3{32, 32, 16}, 4.0f);
    Scene scene;
    scene.camera = {{0.1f, 0.05f, 3.0f}, {0.1f, 0.05f, 0.0f}, {0.0f, 1.0f, 0.0f}, 4.0f};
    for (int layer = 0; layer < 72; ++layer) {
        SceneObject plane = stacked.objects[1];
        applyTransform(plane.mesh,
                       {{0.0f, 0.0f, -1.05f * 0.25f * float(layer)}, {0.0f, 0.0f, 0.0f}, 1.0f});
        if (layer < 70) {
            plane.material.tile = empty;
            plane.material.floor = Floor::Open;
        }
        scene.objects.push_back(std::move(plane));
    }
    const SceneTracer tracer(scene, TraceOptions{});
    constexpr int kWidth = 32, kHeight = 24;
    const PinholeProjection projection(scene.camera, kWidth, kHeight);
    const ScreenShells shells(tracer, projection);
    int overflowing = 0, deepHits = 0;
    for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) {
            const auto bin =
                shells.tileShells(x / ScreenShells::kTilePixels, y / ScreenShells::kTilePixels);
            const auto taken = std::count_if(bin.begin(), bin.end(), [&](std::uint32_t shell) {
                return shells.pixelTakes(shell, x, y);
            });
            overflowing += taken > 64 ? 1 : 0;
        }
    }
    for (const bool culling : {true, false}) {
        for (int y = 0; y < kHeight; ++y) {
            std::vector<ScreenShells::PixelRay> rays;
            for (int x = 0; x < kWidth; ++x)
                rays.push_back({x, y, projection.ray(x + 0.5f, y + 0.5f)});
            std::vector<SurfaceHit> batchHits(rays.size());
            bool batchFound[ScreenShells::kMaxBatchRays] = {};
            std::vector<TraceCounters> batchCounters(rays.size());
            ShellCounters shellCounters;
            shells.traceNearestBatch(rays, culling, batchHits,
                                     std::span<bool>(batchFound, rays.size()), batchCounters,
                                     shellCounters);
            for (std::size_t k = 0; k < rays.size(); ++k) {
                SurfaceHit hit;
                TraceCounters counters;
                const bool found = tracer.traceNearest(rays[k].ray, 0.0f, hit, counters);
                const std::string where = std::to_string(rays[k].x) + "," + std::to_string(y);
                ASSERT_EQ(found, batchFound[k]) << where;
                if (!found) continue;
                deepHits += hit.object >= 70 ? 1 : 0;
                EXPECT_EQ(hit.object, batchHits[k].object) << where;
                // As where one plane is traced both ways: a ray through a shared edge may enter
                // either triangle, frames a few ulps apart.
                EXPECT_NEAR(hit.distanceWorld, batchHits[k].distanceWorld, 1e-5f) << where;
            }
        }
    }
    EXPECT_EQ(overflowing, kWidth * kHeight);
    EXPECT_GT(deepHits, kWidth * kHeight);  // most rays hit there, with culling and without
}

TEST(SceneTracer, BatchesTraceEveryRayAsItsOwnTrace) {
    // The BVH path (shadow-map rays) in batches: six overlapping layers, the top one with an open
    // floor, so rays leave a shell and go on (several passes per ray). Each ray's hit must be
    // that of traceNearest alone, for any batch length; the counters sum over the batch. Without
    // normals (shadow maps) the rays stop at the same places with the same work.
    const Scene scene = stackedPlanesScene();
    const SceneTracer tracer(scene, TraceOptions{});
    constexpr int kWidth = 64, kHeight = 48;
    const PinholeProjection projection(scene.camera, kWidth, kHeight);
    int passedThrough = 0, hits = 0;
    for (const std::size_t batch : {SceneTracer::kMaxBatchRays, std::size_t(3)}) {
        for (int y = 0; y < kHeight; ++y) {
            for (int x0 = 0; x0 < kWidth; x0 += int(batch)) {
                const std::size_t count = std::min(batch, std::size_t(kWidth - x0));
                std::vector<Ray> rays;
                for (std::size_t k = 0; k < count; ++k)
                    rays.push_back(projection.ray(float(x0 + int(k)) + 0.5f, y + 0.5f));
                std::vector<SurfaceHit> batchHits(count);
                bool batchFound[SceneTracer::kMaxBatchRays] = {};
                TraceCounters batchCounters, singleCounters;
                tracer.traceNearestBatch(rays, 0.0f, batchHits, std::span<bool>(batchFound, count),
                                         batchCounters);
                std::vector<SurfaceHit> bareHits(count);
                bool bareFound[SceneTracer::kMaxBatchRays] = {};
                TraceCounters bareCounters;
                tracer.traceNearestBatch(rays, 0.0f, bareHits, std::span<bool>(bareFound, count),
                                         bareCounters, /*withNormals=*/false);
                EXPECT_EQ(bareCounters.marchIterations, batchCounters.marchIterations);
                for (std::size_t k = 0; k < count; ++k) {
                    SurfaceHit hit;
                    TraceCounters counters;
                    const bool found = tracer.traceNearest(rays[k], 0.0f, hit, counters);
                    const std::string where = std::to_string(x0 + int(k)) + "," + std::to_string(y);
                    ASSERT_EQ(found, batchFound[k]) << where;
                    ASSERT_EQ(found, bareFound[k]) << where;
                    if (found) {
                        EXPECT_EQ(hit.distanceWorld, bareHits[k].distanceWorld) << where;
                    }
                    singleCounters.shellEntries += counters.shellEntries;
                    singleCounters.marchIterations += counters.marchIterations;
                    if (counters.shellEntries > 1) ++passedThrough;
                    if (!found) continue;
                    ++hits;
                    EXPECT_EQ(hit.object, batchHits[k].object) << where;
                    EXPECT_EQ(hit.distanceWorld, batchHits[k].distanceWorld) << where;
                    EXPECT_EQ(hit.normal.x, batchHits[k].normal.x) << where;
                    EXPECT_EQ(hit.normal.z, batchHits[k].normal.z) << where;
                }
                EXPECT_EQ(batchCounters.shellEntries, singleCounters.shellEntries);
                EXPECT_EQ(batchCounters.marchIterations, singleCounters.marchIterations);
            }
        }
    }
    EXPECT_GT(hits, kWidth * kHeight);  // most rays of both batch lengths hit
    EXPECT_GT(passedThrough, 300);      // rays through the open top layer into the next (410)
}

TEST(ShellCulling, MatchesTheBvhPathWhereShellsDoNotOverlap) {
    // One plane: the nearest shell entered is the only one, so the screen-space path and the BVH
    // path run the same march from the same entry and must agree exactly.
    Scene scene = stackedPlanesScene();
    scene.objects.resize(1);
    scene.objects[0].material.floor = Floor::Solid;
    const SceneTracer tracer(scene, TraceOptions{});
    constexpr int kWidth = 64, kHeight = 48;
    const PinholeProjection projection(scene.camera, kWidth, kHeight);
    const ScreenShells shells(tracer, projection);
    int hits = 0;
    for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) {
            const Ray ray = projection.ray(x + 0.5f, y + 0.5f);
            SurfaceHit bvhHit, screenHit;
            TraceCounters counters;
            ShellCounters shellCounters;
            const bool bvhFound = tracer.traceNearest(ray, 0.0f, bvhHit, counters);
            const bool screenFound =
                shells.traceNearest(x, y, ray, true, screenHit, counters, shellCounters);
            ASSERT_EQ(bvhFound, screenFound) << x << "," << y;
            if (!bvhFound) continue;
            ++hits;
            // Rays through a shared edge may enter either triangle: same point, frames a few ulps
            // apart.
            EXPECT_NEAR(bvhHit.distanceWorld, screenHit.distanceWorld, 1e-5f) << x << "," << y;
        }
    }
    EXPECT_GT(hits, kWidth * kHeight / 2);
}

}  // namespace
}  // namespace distile

namespace distile {
namespace {

TEST(Material, ColorTextureIsLookedUpBilinearlyAtTheBaseUvAndWraps) {
    // A 2 x 1 texture: left texel red, right texel blue. Texel centres sit at u = 0.25 and 0.75
    // (row 0 is the top, v = 1; one row means v does not matter).
    auto texture = std::make_shared<Image>(2, 1);
    texture->at(0, 0) = {1.0f, 0.0f, 0.0f};
    texture->at(1, 0) = {0.0f, 0.0f, 1.0f};
    Material material;
    material.colorTexture = texture;
    const glm::vec3 left = albedoAt(material, {0.25f, 0.3f});
    EXPECT_FLOAT_EQ(left.x, 1.0f);
    EXPECT_FLOAT_EQ(left.z, 0.0f);
    const glm::vec3 middle = albedoAt(material, {0.5f, 0.9f});  // halfway between the centres
    EXPECT_FLOAT_EQ(middle.x, 0.5f);
    EXPECT_FLOAT_EQ(middle.z, 0.5f);
    const glm::vec3 wrapped =
        albedoAt(material, {1.0f, 0.5f});  // u = 0 = 1: halfway across the wrap
    EXPECT_FLOAT_EQ(wrapped.x, 0.5f);
    EXPECT_FLOAT_EQ(wrapped.z, 0.5f);
    const glm::vec3 far = albedoAt(material, {3.25f, -7.5f});  // whole repeats away: the left texel
    EXPECT_FLOAT_EQ(far.x, 1.0f);
    Material plain;
    EXPECT_EQ(albedoAt(plain, {0.1f, 0.2f}), plain.color);
}

}  // namespace
}  // namespace distile

// ---------------------------------------------------------------------------------------------
// Reference renders (render/analytic_filter.h), measured with render/compare.h.

#include "bake/bake.h"
#include "render/analytic_filter.h"
#include "render/compare.h"
#include "vdb/procedural.h"

namespace distile {
namespace {

TEST(AnalyticFilter, DistanceAndGradientOfAPlane) {
    const AnalyticFilter::DistanceFunction plane = [](const glm::dvec3& p) {
        return 0.6 * p.x + 0.8 * p.z - 3.0;
    };
    const AnalyticFilter filter(plane);
    EXPECT_FLOAT_EQ(filter.distanceTexels({5.0f, 1.0f, 2.0f}), 1.6f);
    // Central differences are exact for a linear function up to rounding (~1e-11 here).
    const glm::vec3 gradient = filter.gradient({5.0f, 1.0f, 2.0f});
    EXPECT_NEAR(gradient.x, 0.6f, 1e-6f);
    EXPECT_NEAR(gradient.y, 0.0f, 1e-6f);
    EXPECT_NEAR(gradient.z, 0.8f, 1e-6f);
}

TEST(ReferenceRender, RejectsATileWithoutAnalyticDistanceNamingTheObject) {
    Scene scene = planeScene(std::make_shared<const Tile>(flatTile({16, 16, 8}, 4.0f)));
    RenderOptions options;
    options.width = 8;
    options.height = 8;
    options.reference = true;
    try {
        renderScene(scene, options);
        FAIL() << "a reference render of a tile without truth must throw";
    } catch (const InputError& error) {
        EXPECT_NE(std::string(error.what()).find("objects[0]"), std::string::npos) << error.what();
        EXPECT_NE(std::string(error.what()).find("reference"), std::string::npos) << error.what();
    }
}

/// data/scenes/sheet.json built in-process: a plane scaled to 4 x 4 world units carrying 4 x 4
/// default chain-mail tiles, seen from 35 degrees above the plane.
Scene sheetScene() {
    static const auto tile = std::make_shared<const Tile>(bakeChainmail({}, {}).tile);
    Scene scene;
    scene.camera = {{0.0f, -2.1f, 1.47f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    scene.lights = {DirectionalLight{{-0.4f, 0.3f, -1.0f}, {1.0f, 1.0f, 1.0f}, 2.0f}};
    SceneObject sheet;
    sheet.mesh = makePlane(2.0f, 1);
    applyTransform(sheet.mesh, Transform{{0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 2.0f});
    sheet.material.tile = tile;
    sheet.material.uvScale = {4.0f, 4.0f};
    sheet.material.depthWorld = 0.0625f;
    ProceduralOptions chainmail;
    chainmail.kind = ProceduralKind::Chainmail;
    sheet.material.analyticDistance =
        proceduralDistance(chainmail, tile->size()).signedDistanceTexels;
    scene.objects.push_back(std::move(sheet));
    return scene;
}

/// Removes the triangles of `mesh` whose centroid `drop` holds for; returns how many.
template <class Predicate>
std::size_t eraseTrianglesByCentroid(BaseMesh& mesh, Predicate drop) {
    return std::erase_if(mesh.triangles, [&](const glm::uvec3& triangle) {
        return drop((mesh.positions[triangle[0]] + mesh.positions[triangle[1]] +
                     mesh.positions[triangle[2]]) /
                    3.0f);
    });
}

/// Cuts the square |x|, |y| < 0.25 out of a plane (the triangles whose centroid lies in it): a
/// hole, an open border inside the mesh. Returns how many triangles it removed.
std::size_t cutSquareHole(BaseMesh& plane) {
    return eraseTrianglesByCentroid(plane, [](const glm::vec3& centroid) {
        return std::abs(centroid.x) < 0.25f && std::abs(centroid.y) < 0.25f;
    });
}

/// A ray that enters a plane's top at `entry` (it starts half a world unit before it), and what
/// it must do there: stop on the floor at `floorPoint`, or leave the shell (no hit).
struct BorderCase {
    glm::vec3 entry;
    glm::vec3 direction;  ///< unit, toward which the ray descends from `entry`
    bool hitsFloor;
    glm::vec3 floorPoint;
    Ray ray() const { return {entry - direction * 0.5f, direction}; }
};

/// traceNearest of the case's ray: a hit exactly when it must stop on the floor, and then on the
/// floor at its point within 1e-4. Returns whether it found a hit.
bool expectBorderCase(const SceneTracer& tracer, const BorderCase& expected) {
    SurfaceHit hit;
    TraceCounters counters;
    const bool found = tracer.traceNearest(expected.ray(), 0.0f, hit, counters);
    EXPECT_EQ(found, expected.hitsFloor);
    if (!found || !expected.hitsFloor) return found;
    EXPECT_TRUE(hit.march.onFloor);
    EXPECT_NEAR(hit.position.x, expected.floorPoint.x, 1e-4f);
    EXPECT_NEAR(hit.position.y, expected.floorPoint.y, 1e-4f);
    EXPECT_NEAR(hit.position.z, expected.floorPoint.z, 1e-4f);
    return found;
}

TEST(SceneTracer, ARayThatCrossesAnOpenBorderOfAFlatShellLeavesItThere) {
    // A plane of side 2 (x, y in [-1, 1]) with an empty tile over a solid floor 1 world unit
    // below the top (32 x 32 x 16 texels of 1/16 world unit). Rays enter the top at x = 0.95, 0.05
    // from the border x = 1, or at the centre. Beyond the border the mesh has no shell: a ray that
    // reaches it before the floor leaves (nothing else is there), where the march once ran on into
    // the tile's next repeat and stopped on the floor beyond the edge; a ray that reaches the floor
    // first stops on it, at the point the closed form gives. Both entry paths (the flat shells'
    // eight-wide one, and the one-at-a-time one the tricubic march takes), and in batches. The
    // plane in 2 triangles, and in 2 x 64 x 64: there rays cross up to 130 triangles on their way
    // out (the walk once gave up after 64, the ray then ran on past the border), and rays from the
    // centre start far from the border (the cull by the triangles' distance to it must not skip
    // them).
    const glm::vec3 nearBorder(0.95f, 0.0f, 0.0f), centre(0.0f);
    const BorderCase cases[] = {
        // The border at 0.05 first.
        {nearBorder, glm::normalize(glm::vec3(1.0f, 0.0f, -1.0f)), false, {}},
        {nearBorder, glm::normalize(glm::vec3(-1.0f, 0.0f, -1.0f)), true, {-0.05f, 0.0f, -1.0f}},
        {nearBorder, glm::normalize(glm::vec3(0.04f, 0.0f, -1.0f)), true, {0.99f, 0.0f, -1.0f}},
        // Along the border, out at y = 1.
        {nearBorder, glm::normalize(glm::vec3(0.0f, 1.0f, -0.4f)), false, {}},
        // From the centre: out at x = 1, 0.5 deep; the floor just before the border.
        {centre, glm::normalize(glm::vec3(1.0f, 0.0f, -0.5f)), false, {}},
        {centre, glm::normalize(glm::vec3(1.0f, 0.0f, -1.1f)), true, {1.0f / 1.1f, 0.0f, -1.0f}},
        {centre, glm::normalize(glm::vec3(-0.7f, 0.6f, -0.5f)), false, {}},
    };
    for (const int subdivisions : {1, 64}) {
        Scene scene;
        SceneObject plane;
        plane.mesh = makePlane(2.0f, subdivisions);
        plane.material.tile = std::make_shared<const Tile>(flatTile({32, 32, 16}, -10.0f));
        plane.material.uvScale = {1.0f, 1.0f};
        plane.material.depthWorld = 1.0f;
        scene.objects.push_back(std::move(plane));
        for (const FilterKind filter : {FilterKind::Trilinear, FilterKind::TricubicBSpline}) {
            TraceOptions options;
            options.filter = filter;
            const SceneTracer tracer(scene, options);
            std::vector<Ray> rays;
            for (const BorderCase& c : cases) rays.push_back(c.ray());
            std::vector<SurfaceHit> batchHits(rays.size());
            bool batchFound[8] = {};
            TraceCounters batchCounters;
            tracer.traceNearestBatch(rays, 0.0f, batchHits,
                                     std::span<bool>(batchFound, rays.size()), batchCounters);
            for (std::size_t k = 0; k < rays.size(); ++k) {
                SCOPED_TRACE(std::to_string(subdivisions) + " subdivisions, filter " +
                             std::to_string(int(filter)) + ", case " + std::to_string(k));
                EXPECT_EQ(batchFound[k], expectBorderCase(tracer, cases[k]));
            }
        }
    }
}

TEST(SceneTracer, AHoleInAFlatMeshIsAnOpenBorderToo) {
    // The plane of side 2 in 2 x 64 x 64 triangles less those over the square |x|, |y| < 0.25:
    // a hole, whose sides are an open border as much as the plane's edge. An empty tile over a
    // solid floor 0.2 world units deep. Rays enter at x = 0.4, 0.15 from the hole and 0.6 from
    // the edge, and descend at 45 degrees: toward the hole they cross its side 0.15 deep and
    // leave (the path to the floor, 0.28, is shorter than the distance to the plane's edge, so
    // the cull by the triangles' distance to the border must count the hole's sides); away from
    // it they stop on the floor 0.2 further on. Rays inside the hole's square meet nothing.
    Scene scene;
    SceneObject plane;
    plane.mesh = makePlane(2.0f, 64);
    ASSERT_EQ(cutSquareHole(plane.mesh), std::size_t(2 * 16 * 16));
    plane.material.tile = std::make_shared<const Tile>(flatTile({32, 32, 16}, -10.0f));
    plane.material.uvScale = {1.0f, 1.0f};
    plane.material.depthWorld = 0.2f;
    scene.objects.push_back(std::move(plane));
    const float diagonal = std::sqrt(0.5f);
    const BorderCase cases[] = {
        {{0.4f, 0.0f, 0.0f}, {-diagonal, 0.0f, -diagonal}, false, {}},  // into the hole
        {{0.4f, 0.0f, 0.0f}, {diagonal, 0.0f, -diagonal}, true, {0.6f, 0.0f, -0.2f}},
        {{0.0f, -0.4f, 0.0f}, {0.0f, diagonal, -diagonal}, false, {}},  // into it from below
        {{0.0f, -0.4f, 0.0f}, {0.0f, -diagonal, -diagonal}, true, {0.0f, -0.6f, -0.2f}},
        {{0.1f, 0.1f, 0.0f}, {0.0f, 0.0f, -1.0f}, false, {}},  // through the hole
    };
    for (const FilterKind filter : {FilterKind::Trilinear, FilterKind::TricubicBSpline}) {
        TraceOptions options;
        options.filter = filter;
        const SceneTracer tracer(scene, options);
        for (std::size_t k = 0; k < std::size(cases); ++k) {
            SCOPED_TRACE("filter " + std::to_string(int(filter)) + ", case " + std::to_string(k));
            expectBorderCase(tracer, cases[k]);
        }
    }
}

/// A plane of side 2 (x, y in [-1, 1]) in 2 x `subdivisions`^2 triangles, less those over the
/// square |x|, |y| < 0.25 with `hole`, over a tile of 32 x 32 x 16 texels of 1/16 world unit (a
/// shell 1 deep, solid floor) whose detail is a wall across the tile's middle, texels x in
/// [14, 18]: world x in [-0.125, 0.125], and again 2 further on in the tile's repeats, where the
/// plane has ended.
Scene walledPlaneScene(int subdivisions, bool hole = false) {
    Tile tile({32, 32, 16});
    for (int z = 0; z < 16; ++z)
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 32; ++x) tile.at(x, y, z) = std::abs(x + 0.5f - 16.0f) - 2.0f;
    Scene scene;
    SceneObject plane;
    plane.mesh = makePlane(2.0f, subdivisions);
    if (hole) {
        cutSquareHole(plane.mesh);
    }
    plane.material.tile = std::make_shared<const Tile>(std::move(tile));
    plane.material.uvScale = {1.0f, 1.0f};
    plane.material.depthWorld = 1.0f;
    scene.objects.push_back(std::move(plane));
    return scene;
}

/// A camera ray that enters a plane's top at `entry` along `direction` and stops on the floor,
/// and the height (texels) at which the self-shadow ray from there toward `toLight` must end.
struct SelfShadowTopCase {
    glm::vec3 entry, direction, toLight;
    float topTexels;
};

void expectSelfShadowTop(const SceneTracer& tracer, const SelfShadowTopCase& expected) {
    SurfaceHit hit;
    TraceCounters counters;
    ASSERT_TRUE(tracer.traceNearest(
        {expected.entry - expected.direction * 0.5f, expected.direction}, 0.0f, hit, counters));
    ASSERT_TRUE(hit.march.onFloor);
    // The renderer's start: the hit in texel space, the light's direction there.
    const glm::vec3 toLightTexels = glm::normalize(hit.entry.toTexel(expected.toLight));
    EXPECT_NEAR(tracer.selfShadowTopTexels(hit, expected.toLight, hit.march.texelPosition,
                                           toLightTexels, 16.0f),
                expected.topTexels, 1e-3f);
}

TEST(SceneTracer, SelfShadowRaysEndWhereTheyLeaveThroughAnOpenBorder) {
    // Floor hits of the walled plane (walledPlaneScene) and the height at which their self-shadow
    // rays must end: where they cross the plane's edge or the hole's side, 16 texels per world
    // unit of rise above the floor, or the top (16) when they reach it first. Beyond them the
    // tile's wall is not there, but a march up to the top would meet it.
    const glm::vec3 down(0.0f, 0.0f, -1.0f);
    const float rise = std::sqrt(0.5f);
    const glm::vec3 steep(0.5f, 0.0f, 0.5f * std::sqrt(3.0f));  // toward +x at 60 degrees
    const SelfShadowTopCase cases[] = {
        {{0.95f, 0.3f, 0.0f}, down, {rise, 0.0f, rise}, 0.8f},    // out at x = 1, 0.05 up
        {{0.95f, 0.3f, 0.0f}, down, {-rise, 0.0f, rise}, 16.0f},  // away from it
        {{-0.5f, 0.3f, 0.0f}, down, {rise, 0.0f, rise}, 16.0f},   // the top at x = 0.5
        {{-0.3f, 0.9f, 0.0f}, down, {0.0f, rise, rise}, 1.6f},    // out at y = 1, 0.1 up
        // From (0.9, 0, -1) toward x = 1 diagonally, out 0.1 up.
        {{0.2f, 0.0f, 0.0f},
         glm::normalize(glm::vec3(0.7f, 0.0f, -1.0f)),
         glm::normalize(glm::vec3(1.0f, 1.0f, 1.0f)),
         1.6f},
        // From (0.9, 0.3, -1), entered 0.85 from the edge, toward it at 60 degrees: out 0.173
        // up. The two paths, 1.25 and 1.15 long, reach no further than 2.41 from the entry, less
        // than 3 times its distance to the edge.
        {{0.15f, 0.3f, 0.0f},
         glm::normalize(glm::vec3(0.75f, 0.0f, -1.0f)),
         steep,
         16.0f * 0.1f * std::sqrt(3.0f)},
    };
    for (const int subdivisions : {1, 64}) {
        const Scene scene = walledPlaneScene(subdivisions);
        const SceneTracer tracer(scene, TraceOptions{});
        for (std::size_t k = 0; k < std::size(cases); ++k) {
            SCOPED_TRACE(std::to_string(subdivisions) + " subdivisions, case " + std::to_string(k));
            expectSelfShadowTop(tracer, cases[k]);
        }
    }
    // Around the hole: from (0.35, 0, -1) toward -x, its side at x = 0.25 0.1 up. The camera ray
    // came from below the hole, so the shell it entered is off that light ray's line, whose
    // walk must start from the shell under the hit.
    const SelfShadowTopCase aroundTheHole[] = {
        {{0.35f, -0.7f, 0.0f},
         glm::normalize(glm::vec3(0.0f, 0.7f, -1.0f)),
         {-rise, 0.0f, rise},
         1.6f},
        {{0.35f, 0.0f, 0.0f}, down, {-rise, 0.0f, rise}, 1.6f},
        {{0.35f, 0.0f, 0.0f}, down, steep, 16.0f},  // the top at x = 0.93, before the edge
    };
    const Scene holedScene = walledPlaneScene(64, true);
    const SceneTracer holed(holedScene, TraceOptions{});
    for (std::size_t k = 0; k < std::size(aroundTheHole); ++k) {
        SCOPED_TRACE("around the hole, case " + std::to_string(k));
        expectSelfShadowTop(holed, aroundTheHole[k]);
    }
}

/// Where `ray` first meets the box [low, high] (slab test), if it does: the distance.
std::optional<float> boxEntryDistance(const Ray& ray, const glm::vec3& low, const glm::vec3& high) {
    float enter = 0.0f, leave = std::numeric_limits<float>::max();
    for (int axis = 0; axis < 3; ++axis) {
        if (ray.direction[axis] == 0.0f) {
            if (ray.origin[axis] < low[axis] || ray.origin[axis] > high[axis]) return std::nullopt;
            continue;
        }
        float near = (low[axis] - ray.origin[axis]) / ray.direction[axis];
        float far = (high[axis] - ray.origin[axis]) / ray.direction[axis];
        if (near > far) std::swap(near, far);
        enter = std::max(enter, near);
        leave = std::min(leave, far);
    }
    if (!(enter <= leave)) return std::nullopt;
    return enter;
}

/// A scene's tracer and its screen bins at 64 x 48 pixels.
struct TracedView {
    static constexpr int kWidth = 64, kHeight = 48;
    explicit TracedView(const Scene& scene)
        : tracer(scene, TraceOptions{}),
          projection(scene.camera, kWidth, kHeight),
          shells(tracer, projection) {}
    SceneTracer tracer;
    PinholeProjection projection;
    ScreenShells shells;

    /// The camera ray through pixel (x, y) hits at `expected` (world distance, within
    /// `tolerance`), or misses without one, through the BVH and through the screen bins with and
    /// without culling.
    void expectHit(int x, int y, std::optional<float> expected, float tolerance) const {
        const Ray ray = projection.ray(x + 0.5f, y + 0.5f);
        SurfaceHit hit;
        TraceCounters counters;
        ASSERT_EQ(tracer.traceNearest(ray, 0.0f, hit, counters), expected.has_value());
        if (expected) {
            EXPECT_NEAR(hit.distanceWorld, *expected, tolerance);
        }
        for (const bool culling : {true, false}) {
            ShellCounters shellCounters;
            ASSERT_EQ(shells.traceNearest(x, y, ray, culling, hit, counters, shellCounters),
                      expected.has_value());
            if (expected) {
                EXPECT_NEAR(hit.distanceWorld, *expected, tolerance);
            }
        }
    }
};

TEST(SceneTracer, RaysEnterAFlatShellThroughItsSidesOnAnOpenBorder) {
    // A plane of side 2 over a tile whose detail is the plane 4 texels above a solid floor 1
    // world unit deep: the detail is the box [-1, 1]^2 x [-1, -0.75], and a ray's hit is where it
    // meets that box, also when it comes in through a side of the shell (the border of the plane)
    // below the top, where the shell was once entered only through its top and the box's sides
    // were not seen at all; and no hit where the ray leaves by the far side before reaching it.
    // Camera rays through the screen bins (each pixel of a view from the front, with and without
    // culling) and the same rays through the BVH; the plane in 2 triangles and in 2 x 16 x 16.
    for (const int subdivisions : {1, 16}) {
        Scene scene;
        scene.camera = {{0.3f, -3.0f, 0.5f}, {0.0f, 0.0f, -0.6f}, {0.0f, 0.0f, 1.0f}, 50.0f};
        SceneObject plane;
        plane.mesh = makePlane(2.0f, subdivisions);
        plane.material.tile = std::make_shared<const Tile>(flatTile({32, 32, 16}, 4.0f));
        plane.material.uvScale = {1.0f, 1.0f};
        plane.material.depthWorld = 1.0f;
        scene.objects.push_back(std::move(plane));
        const TracedView view(scene);
        int throughSides = 0, leaving = 0;
        for (int y = 0; y < TracedView::kHeight; ++y) {
            for (int x = 0; x < TracedView::kWidth; ++x) {
                SCOPED_TRACE(std::to_string(subdivisions) + " subdivisions, pixel " +
                             std::to_string(x) + ", " + std::to_string(y));
                const Ray ray = view.projection.ray(x + 0.5f, y + 0.5f);
                const std::optional<float> box =
                    boxEntryDistance(ray, {-1.0f, -1.0f, -1.0f}, {1.0f, 1.0f, -0.75f});
                const std::optional<float> shell =
                    boxEntryDistance(ray, {-1.0f, -1.0f, -1.0f}, {1.0f, 1.0f, 0.0f});
                const glm::vec3 atShell = shell ? ray.origin + ray.direction * *shell : glm::vec3();
                const bool side = shell && atShell.z < -1e-3f;
                throughSides += side && box;
                leaving += side && !box;
                // Rays passing within the march's reach of the box's edges (a few hundredths of a
                // texel) may go either way: those that meet a box grown by 0.005 and miss one
                // shrunk by as much, or meet both on different faces.
                constexpr float kNear = 0.005f;
                const std::optional<float> grown =
                    boxEntryDistance(ray, {-1.0f - kNear, -1.0f - kNear, -1.0f - kNear},
                                     {1.0f + kNear, 1.0f + kNear, -0.75f + kNear});
                const std::optional<float> shrunk =
                    boxEntryDistance(ray, {-1.0f + kNear, -1.0f + kNear, -1.0f + kNear},
                                     {1.0f - kNear, 1.0f - kNear, -0.75f - kNear});
                if (grown.has_value() != shrunk.has_value() ||
                    (grown && std::abs(*grown - *shrunk) > 0.1f))
                    continue;
                view.expectHit(x, y, box, 2e-3f);
            }
        }
        // The view must hold both kinds of side entry.
        EXPECT_GT(throughSides, 100);
        EXPECT_GT(leaving, 20);
    }
}

TEST(SceneTracer, RaysEnterACurvedShellThroughItsSidesOnAnOpenBorder) {
    // The upper half of a sphere of radius 1 (its radial normals kept), a shell 0.2 deep whose
    // detail fills it: the rim's sides, from the equator in to radius 0.8, lie in the plane z = 0,
    // and a ray from below that crosses that annulus stops where it does (the march starts a
    // thousandth of the depth further on). It once passed by, into the dome. Rays through the
    // screen bins and through the BVH, each pixel of a view from below; those within 0.01 of the
    // annulus' circles are left out.
    Scene scene;
    scene.camera = {{0.4f, -2.5f, -1.5f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 45.0f};
    SceneObject dome;
    dome.mesh = makeUvSphere(1.0f, 48, 24);
    eraseTrianglesByCentroid(dome.mesh,
                             [](const glm::vec3& centroid) { return centroid.z < 0.0f; });
    dome.material.tile = std::make_shared<const Tile>(flatTile({32, 32, 16}, 16.0f));
    dome.material.uvScale = {4.0f, 2.0f};
    dome.material.depthWorld = 0.2f;
    scene.objects.push_back(std::move(dome));
    const TracedView view(scene);
    int throughSides = 0;
    for (int y = 0; y < TracedView::kHeight; ++y) {
        for (int x = 0; x < TracedView::kWidth; ++x) {
            const Ray ray = view.projection.ray(x + 0.5f, y + 0.5f);
            const float toRim = -ray.origin.z / ray.direction.z;
            const glm::vec3 atRim = ray.origin + ray.direction * toRim;
            const float radius = std::hypot(atRim.x, atRim.y);
            if (!(radius > 0.81f && radius < 0.99f)) continue;
            SCOPED_TRACE("pixel " + std::to_string(x) + ", " + std::to_string(y));
            ++throughSides;
            view.expectHit(x, y, toRim, 5e-4f);
        }
    }
    EXPECT_GT(throughSides, 100);
}

TEST(Renderer, SelfShadowsNearAnOpenBorderComeOnlyFromTheDetailThere) {
    // The walled plane from straight above, lit from +x at 45 degrees. Its floor is in the
    // wall's shadow from x = -1.125 to -0.125, and lit from there to the edge at x = 1: the
    // self-shadow rays of floor points within 0.875 of that edge pass over it before the top,
    // where the march once ran on into the tile's next wall and shaded them as dark as those
    // behind the wall.
    const Scene base = walledPlaneScene(1);
    Scene scene = base;
    scene.camera = {{0.0f, 0.0f, 8.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}, 20.0f};
    scene.lights = {DirectionalLight{{-1.0f, 0.0f, -1.0f}, {1.0f, 1.0f, 1.0f}, 1.0f}};
    RenderOptions options;
    options.width = options.height = 128;
    const RenderResult result = renderScene(scene, options);
    const PinholeProjection projection(scene.camera, options.width, options.height);
    const auto floorLuminance = [&](float x) {
        const glm::dvec2 pixel = projection.toPixels(projection.toView({x, 0.3f, -1.0f}));
        const glm::vec3 color = result.image.at(int(pixel.x), int(pixel.y));
        return (color.r + color.g + color.b) / 3.0f;
    };
    const float shadowed = floorLuminance(-0.4f), lit = floorLuminance(0.4f);
    ASSERT_GT(lit, 2.0f * shadowed);
    for (const float x : {0.6f, 0.8f, 0.9f, 0.95f}) {
        SCOPED_TRACE("x = " + std::to_string(x));
        EXPECT_NEAR(floorLuminance(x), lit, 0.02f * lit);
    }
}

TEST(SceneTracer, AFlatShellBatchGivesEachRayWhatItsRoundsGiveIt) {
    // The sheet's camera rays in runs of 16 x 4 pixels: traceFlatShell (the screen path's batch
    // over the one flat shell of their pixels) must give every ray that meets the plane's first
    // triangle what traceNearest (the rounds of the BVH path) gives it alone, bit for bit, and
    // leave the others unfound.
    const Scene scene = sheetScene();
    const SceneTracer tracer(scene, TraceOptions{});
    constexpr int kWidth = 320, kHeight = 256;
    const PinholeProjection projection(scene.camera, kWidth, kHeight);
    const BaseMesh& mesh = scene.objects[0].mesh;
    const glm::uvec3 first = mesh.triangles[0];
    int entered = 0, missed = 0;
    for (int y0 = 0; y0 < kHeight; y0 += 4) {
        for (int x0 = 0; x0 < kWidth; x0 += 16) {
            std::vector<Ray> rays;
            for (int y = y0; y < y0 + 4; ++y)
                for (int x = x0; x < x0 + 16; ++x)
                    rays.push_back(projection.ray(x + 0.5f, y + 0.5f));
            std::vector<const Ray*> pointers;
            for (const Ray& ray : rays) pointers.push_back(&ray);
            std::vector<SurfaceHit> hits(rays.size());
            bool found[SceneTracer::kMaxBatchRays] = {};
            std::vector<TraceCounters> counters(rays.size());
            if (kSimdLevel < SimdLevel::Avx2) {  // the flat entries need AVX2: the rounds take it
                EXPECT_FALSE(tracer.traceFlatShell(0, pointers, hits, found, counters));
                return;
            }
            ASSERT_TRUE(tracer.traceFlatShell(0, pointers, hits, found, counters));
            for (std::size_t k = 0; k < rays.size(); ++k) {
                double distance = 0.0, b1 = 0.0, b2 = 0.0;
                const bool meetsFirst =
                    intersectTriangle(rays[k], mesh.positions[first[0]], mesh.positions[first[1]],
                                      mesh.positions[first[2]], 0.0, 1e30, distance, b1, b2);
                ASSERT_EQ(found[k], meetsFirst) << x0 << "," << y0 << " ray " << k;
                if (!meetsFirst) {
                    ++missed;
                    continue;
                }
                ++entered;
                SurfaceHit alone;
                TraceCounters aloneCounters;
                ASSERT_TRUE(tracer.traceNearest(rays[k], 0.0f, alone, aloneCounters));
                const SurfaceHit& hit = hits[k];
                const std::string where =
                    std::to_string(x0) + "," + std::to_string(y0) + " ray " + std::to_string(k);
                EXPECT_EQ(hit.object, alone.object) << where;
                EXPECT_EQ(hit.distanceWorld, alone.distanceWorld) << where;
                EXPECT_EQ(hit.position, alone.position) << where;
                EXPECT_EQ(hit.normal, alone.normal) << where;
                EXPECT_EQ(hit.entry.position, alone.entry.position) << where;
                EXPECT_EQ(hit.entry.uv, alone.entry.uv) << where;
                EXPECT_EQ(hit.onDetail, alone.onDetail) << where;
                EXPECT_EQ(hit.march.texelPosition, alone.march.texelPosition) << where;
                EXPECT_EQ(hit.march.iterations, alone.march.iterations) << where;
                EXPECT_EQ(hit.march.converged, alone.march.converged) << where;
                EXPECT_EQ(hit.texelsPerWorldAlongRay, alone.texelsPerWorldAlongRay) << where;
                EXPECT_EQ(counters[k].marchIterations, aloneCounters.marchIterations) << where;
                EXPECT_EQ(counters[k].shellEntries, aloneCounters.shellEntries) << where;
            }
        }
    }
    EXPECT_GT(entered, kWidth * kHeight / 4);
    EXPECT_GT(missed, 1000);  // the rays over the other triangle and the sky

    // Rays that meet the plane from below, and a curved shell: the rounds take them.
    const Ray below{{0.0f, 0.0f, -1.0f}, {0.0f, 0.0f, 1.0f}};
    const Ray* belowRays[1] = {&below};
    SurfaceHit hit;
    bool belowFound[1] = {false};
    TraceCounters belowCounters;
    EXPECT_FALSE(tracer.traceFlatShell(0, belowRays, std::span(&hit, 1), belowFound,
                                       std::span(&belowCounters, 1)));
    Scene torusScene = sheetScene();
    torusScene.objects[0].mesh = makeTorus(1.0f, 0.4f, 32, 16);
    const SceneTracer torusTracer(torusScene, TraceOptions{});
    const Ray down{{1.4f, 0.0f, 2.0f}, {0.0f, 0.0f, -1.0f}};
    const Ray* downRays[1] = {&down};
    for (std::uint32_t shell = 0; shell < torusTracer.shellCount(); ++shell)
        EXPECT_FALSE(torusTracer.traceFlatShell(shell, downRays, std::span(&hit, 1), belowFound,
                                                std::span(&belowCounters, 1)));
}

TEST(Renderer, APreparedSceneRendersAsRenderSceneEveryTime) {
    // The chain-mail sheet and a sphere above it casting a shadow: tiles, self-shadows and a
    // shadow map, whose tiles each render traces anew.
    Scene scene = sheetScene();
    SceneObject sphere;
    sphere.mesh = makeUvSphere(0.3f, 48, 24);
    applyTransform(sphere.mesh, {{0.0f, 0.0f, 0.5f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    scene.objects.push_back(std::move(sphere));
    RenderOptions options;
    options.width = 160;
    options.height = 128;
    options.outputAovs = true;
    const RenderResult once = renderScene(scene, options);
    const PreparedScene prepared(scene, options);
    for (int render = 0; render < 2; ++render) {
        const RenderResult again = prepared.render();
        EXPECT_EQ(again.image.rgbLinear, once.image.rgbLinear) << "render " << render;
        EXPECT_EQ(again.aovs->depth.rgbLinear, once.aovs->depth.rgbLinear);
        EXPECT_EQ(again.stats.marchIterations, once.stats.marchIterations);
        EXPECT_EQ(again.stats.shadowSteps, once.stats.shadowSteps);
        EXPECT_EQ(again.stats.shadowMapSamples, once.stats.shadowMapSamples);
        EXPECT_EQ(again.stats.shadowMapTexels, once.stats.shadowMapTexels);
    }
    EXPECT_GT(once.stats.shadowMapTexels, 0u);
    EXPECT_GT(once.stats.shadowSteps, 0u);
    // Options are checked where the scene is prepared.
    options.march.maxIterations = 0;
    EXPECT_THROW(PreparedScene(scene, options), InputError);
}

/// The sheet rendered at 320 x 256 with `iterations` (other options default, no shadows: shading
/// does not enter the figures checked) against its reference render.
RenderComparison sheetAgainstReference(int iterations) {
    const Scene scene = sheetScene();
    RenderOptions options;
    options.width = 320;
    options.height = 256;
    options.march.maxIterations = iterations;
    options.outputAovs = true;
    options.shadowFilter = ShadowFilter::None;
    options.selfShadows = false;
    const RenderResult tested = renderScene(scene, options);
    options.reference = true;
    const RenderResult truth = renderScene(scene, options);
    // The reference converges on almost every ray within its budget (measured: all).
    EXPECT_GT(double(truth.stats.converged), 0.999 * double(truth.stats.baseHits));
    return compareRenders(
        {tested.image, tested.aovs->depth, tested.aovs->normal, tested.aovs->texelScale},
        {truth.image, truth.aovs->depth, truth.aovs->normal, truth.aovs->texelScale});
}

TEST(ReferenceRender, SheetWithAConvergedBudgetIsWithinAQuarterTexelOfTheAnalyticTruth) {
    // The acceptance figures (mean hit error <= 0.25 texel, coverage mismatch <= 0.5%) on a
    // 320 x 256 image of data/scenes/sheet.json's camera and sheet, trilinear tile, 64 iterations
    // (99.8% of rays converge). Measured: mean 0.112 texel, no coverage mismatch. The residual
    // is the tile's own error (trilinear over a float tile) and silhouette pixels.
    const RenderComparison c = sheetAgainstReference(64);
    EXPECT_GT(c.hitErrorSamples, 0.5 * double(c.pixels));  // the sheet fills most of the image
    EXPECT_LE(c.meanHitErrorTexels, 0.25);
    EXPECT_LE(c.coverageMismatchShare, 0.005);
    // A tile is not its truth: the error is not zero, or this test could not fail.
    EXPECT_GT(c.meanHitErrorTexels, 0.0);
}

// The acceptance for the DEFAULT march (budgeted, 32 samples). Plain sphere tracing (ch. 8) with
// 16 does not meet it: 19% of the rays creep along grazing wires and stop short (measured at
// 1280 x 1024: mean 1.51 texels); the budgeted march reaches a crossing or the floor on every ray
// (measured at 1280 x 1024: mean 0.084 texel, 100% converged; 0.232 with a budget of 16, whose
// forced steps on grazing paths pass wire edges). Here, at 320 x 256: 0.087 texel (0.229 with 16);
// the bound between them keeps the default's budget from falling back.
TEST(ReferenceRender, DefaultSheetRenderIsWithinPoint15TexelOfTheAnalyticTruth) {
    const RenderComparison c = sheetAgainstReference(RenderOptions{}.march.maxIterations);
    EXPECT_LE(c.meanHitErrorTexels, 0.15);
    EXPECT_LE(c.coverageMismatchShare, 0.005);
}

}  // namespace
}  // namespace distile
