// Numerical-stability stress suite (issue 5): grazing rays, far UVs, far base meshes, broken UV
// layouts, a camera inside the shell, sub-texel wires, extreme shell depths and NaN/Inf rays. Each
// case states its expected behaviour, asserts it, and prints its measured error with a
// "[ figures  ]" prefix. Small images and tiles, in-process: the whole file runs in seconds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>
#include <vector>

#include "common/error.h"
#include "render/march.h"
#include "render/renderer.h"
#include "render/tracer.h"
#include "sampler/bake.h"
#include "sampler/filters.h"

namespace distile {
namespace {

constexpr double kPi = 3.14159265358979323846;

/// A tile whose detail is the horizontal plane z = heightTexels (solid below): exact distances,
/// reproduced exactly by trilinear filtering except in the top half texel (clamped there, an
/// underestimate, which only slows the march).
std::shared_ptr<const Tile> flatTile(const Size3& size, float heightTexels) {
    auto tile = std::make_shared<Tile>(size);
    for (int z = 0; z < size.depth; ++z)
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x) tile->at(x, y, z) = (z + 0.5f) - heightTexels;
    return tile;
}

/// A wavy height field (distance bound, not exact): detail with edges and slopes, so image
/// comparisons see shading, silhouettes and self-shadows, not just a flat colour.
std::shared_ptr<const Tile> wavyTile() {
    auto tile = std::make_shared<Tile>(Size3{32, 32, 16});
    for (int z = 0; z < 16; ++z)
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 32; ++x)
                tile->at(x, y, z) =
                    0.5f * ((z + 0.5f) - (8.0f + 4.0f * float(std::sin(2 * kPi * (x + 0.5) / 32) *
                                                              std::cos(2 * kPi * (y + 0.5) / 32))));
    return tile;
}

// The plane scene: a 2 x 2 plane at z = 0 with uv scale 2 and a 32 x 32 x 16 tile, so 32 texels
// per world unit along x and y; depth 0.5 makes the texels cubes (16 texels over 0.5 units).
constexpr float kPlaneSize = 2.0f;
constexpr float kUvScale = 2.0f;
constexpr float kCubeDepth = 0.5f;

Scene planeScene(std::shared_ptr<const Tile> tile, float depthWorld = kCubeDepth) {
    Scene scene;
    scene.camera = {{0.3f, -1.6f, 1.2f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    SceneObject plane;
    plane.mesh = makePlane(kPlaneSize, 1);
    plane.material.tile = std::move(tile);
    plane.material.uvScale = {kUvScale, kUvScale};
    plane.material.depthWorld = depthWorld;
    scene.objects.push_back(std::move(plane));
    return scene;
}

RenderOptions smallOptions() {
    RenderOptions options;
    options.width = 64;
    options.height = 48;
    options.shadowMapResolution = 256;
    options.outputAovs = true;
    return options;
}

bool isFinite(const glm::vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

std::size_t nonFinitePixels(const Image& image) {
    return std::size_t(std::count_if(image.rgbLinear.begin(), image.rgbLinear.end(),
                                     [](const glm::vec3& pixel) { return !isFinite(pixel); }));
}

struct ImageDifference {
    double meanAbs = 0.0;    ///< mean over pixels and channels
    double maxAbs = 0.0;     ///< largest channel difference
    double shareOver = 0.0;  ///< share of pixels with a channel differing by more than 0.05
};

ImageDifference compareImages(const Image& a, const Image& b) {
    ImageDifference difference;
    std::size_t over = 0;
    for (std::size_t i = 0; i < a.rgbLinear.size(); ++i) {
        const glm::vec3 delta = glm::abs(a.rgbLinear[i] - b.rgbLinear[i]);
        const double largest = std::max({delta.x, delta.y, delta.z});
        difference.meanAbs += double(delta.x + delta.y + delta.z) / 3.0;
        difference.maxAbs = std::max(difference.maxAbs, largest);
        if (largest > 0.05) ++over;
    }
    difference.meanAbs /= double(a.rgbLinear.size());
    difference.shareOver = double(over) / double(a.rgbLinear.size());
    return difference;
}

double convergedShare(const RenderStats& stats) {
    return stats.baseHits ? double(stats.converged) / double(stats.baseHits) : 0.0;
}

// ---------------------------------------------------------------------------------------------

TEST(Stress, GrazingRaysStayAboveAFlatDetailPlaneWithABoundedError) {
    // Truth: the detail is the plane z = h in texel space. Sphere tracing towards an exact plane
    // at elevation a leaves the height above it at (D - h) (1 - sin a)^n after n steps (slower in
    // the clamped top half texel, an underestimate), so with the default 16 iterations grazing rays
    // stop short of the plane: never below it, at the predicted height above it, none converged.
    // With a budget large enough (4096) they all converge within epsilon. (Plain sphere tracing;
    // the default budgeted march is the next test.)
    constexpr int kDepth = 8;
    constexpr float kHeight = 4.0f;
    Scene scene = planeScene(flatTile({32, 32, kDepth}, kHeight), kCubeDepth * kDepth / 16.0f);
    const float texelsPerWorldZ = kDepth / scene.objects[0].material.depthWorld;
    const float planeWorldZ = -(kDepth - kHeight) / texelsPerWorldZ;
    for (int budget : {16, 4096}) {
        TraceOptions traceOptions;
        traceOptions.march.method = MarchMethod::SphereTracing;
        traceOptions.march.maxIterations = budget;
        const SceneTracer tracer(scene, traceOptions);
        for (double elevationDeg : {0.1, 0.5, 1.0, 2.0, 5.0}) {
            const double elevation = elevationDeg * kPi / 180.0;
            // The march on the exact plane, in double: the known answer for this budget.
            const double sine = std::sin(elevation);
            double predicted = kDepth;  // texel z after the predicted steps
            bool predictedConverged = false;
            for (int step = 0; step < budget; ++step) {
                const double distance =
                    std::min(predicted, kDepth - 0.5) - kHeight;  // clamped top half texel
                if (distance < traceOptions.march.epsilonTexels) {
                    predictedConverged = true;
                    break;
                }
                predicted -= distance * sine;
            }
            const double predictedError = predicted - kHeight;
            int rays = 0, converged = 0;
            double maxError = 0.0, sumError = 0.0;
            for (double azimuthDeg : {0.0, 37.0, 90.0, 161.0, 250.0, 313.0}) {
                for (float offset : {-0.41f, 0.07f, 0.33f}) {
                    const double azimuth = azimuthDeg * kPi / 180.0;
                    const glm::vec3 direction(float(std::cos(elevation) * std::cos(azimuth)),
                                              float(std::cos(elevation) * std::sin(azimuth)),
                                              float(-std::sin(elevation)));
                    const glm::vec3 target(offset, -0.5f * offset, 0.0f);
                    const Ray ray{target - direction * (0.3f / direction.z * -1.0f),
                                  glm::normalize(direction)};
                    SurfaceHit hit;
                    TraceCounters counters;
                    ASSERT_TRUE(tracer.traceNearest(ray, 0.0f, hit, counters)) << elevationDeg;
                    ASSERT_TRUE(hit.onDetail);
                    ASSERT_TRUE(isFinite(hit.position) && isFinite(hit.normal) &&
                                std::isfinite(hit.distanceWorld));
                    // Two measures of the same error: the march's own texel z, and the world hit
                    // (depth along the ray) mapped back to texels.
                    const double marchError = hit.march.texelPosition.z - kHeight;
                    const double worldError =
                        (double(hit.position.z) - planeWorldZ) * texelsPerWorldZ;
                    EXPECT_GE(marchError, -1e-4) << elevationDeg;  // never below the surface
                    // The world hit agrees with the march within float rounding of a few texels'
                    // travel over a 0.3-unit ray (1e-3 texel).
                    EXPECT_NEAR(worldError, marchError, 1e-3 + 1e-5 * hit.march.travelTexels)
                        << elevationDeg;
                    if (budget == 16) {
                        // Float rounding over 16 steps of at most 4 texels: 1e-3 texel.
                        EXPECT_NEAR(marchError, predictedError, 1e-3) << elevationDeg;
                    } else {
                        EXPECT_TRUE(hit.march.converged) << elevationDeg;
                        EXPECT_LE(marchError, traceOptions.march.epsilonTexels) << elevationDeg;
                        // Thousands of steps accumulate float rounding: 1e-3 texel still bounds it.
                        EXPECT_NEAR(marchError, predictedError, 1e-3) << elevationDeg;
                    }
                    EXPECT_EQ(hit.march.converged, predictedConverged) << elevationDeg;
                    ++rays;
                    converged += hit.march.converged ? 1 : 0;
                    maxError = std::max(maxError, std::abs(marchError));
                    sumError += std::abs(marchError);
                }
            }
            std::printf(
                "[ figures  ] grazing %.1f deg, budget %d: hit error mean %.4f max %.4f texels "
                "(predicted %.4f), converged %d/%d\n",
                elevationDeg, budget, sumError / rays, maxError, predictedError, converged, rays);
        }
    }
}

TEST(Stress, BudgetedMarchReachesAFlatDetailPlaneOnGrazingRaysWithinTheDefaultBudget) {
    // The default march (budgeted) on the grazing rays of the previous test: every step is at
    // least the path left to the floor over the samples left, so the ray crosses the plane
    // z = h within 16 samples, and regula falsi on the plane's linear distance (exact below the
    // clamped top half texel) lands on it: converged, within epsilon, never further below it.
    constexpr int kDepth = 8;
    constexpr float kHeight = 4.0f;
    const Scene scene =
        planeScene(flatTile({32, 32, kDepth}, kHeight), kCubeDepth * kDepth / 16.0f);
    const TraceOptions traceOptions;
    ASSERT_EQ(traceOptions.march.method, MarchMethod::Budgeted);
    ASSERT_EQ(traceOptions.march.maxIterations, 16);
    const SceneTracer tracer(scene, traceOptions);
    for (double elevationDeg : {0.1, 0.5, 1.0, 2.0, 5.0, 30.0}) {
        const double elevation = elevationDeg * kPi / 180.0;
        double maxError = 0.0;
        for (double azimuthDeg : {0.0, 37.0, 90.0, 161.0, 250.0, 313.0}) {
            const double azimuth = azimuthDeg * kPi / 180.0;
            const glm::vec3 direction(float(std::cos(elevation) * std::cos(azimuth)),
                                      float(std::cos(elevation) * std::sin(azimuth)),
                                      float(-std::sin(elevation)));
            const Ray ray{-direction * (0.3f / -direction.z), glm::normalize(direction)};
            SurfaceHit hit;
            TraceCounters counters;
            ASSERT_TRUE(tracer.traceNearest(ray, 0.0f, hit, counters)) << elevationDeg;
            ASSERT_TRUE(hit.onDetail);
            EXPECT_TRUE(hit.march.converged) << elevationDeg;
            EXPECT_FALSE(hit.march.onFloor) << elevationDeg;
            EXPECT_LE(hit.march.iterations, 16);
            const double marchError = hit.march.texelPosition.z - kHeight;
            // Float rounding of a secant over a path of up to 2300 texels (0.1 degree): 1e-3.
            EXPECT_LE(std::abs(marchError), traceOptions.march.epsilonTexels + 1e-3)
                << elevationDeg << " " << azimuthDeg;
            maxError = std::max(maxError, std::abs(marchError));
        }
        std::printf(
            "[ figures  ] budgeted march, grazing %.1f deg, 16 samples: max hit error %.4f "
            "texels\n",
            elevationDeg, maxError);
    }
}

TEST(Stress, UvsFarFromTheOriginRenderLikeSmallOnes) {
    // The same plane with every uv moved by a whole 1e4 (2e4 tile repeats at uv scale 2): the
    // tile is periodic, so the truth is the same image. Float uvs near 1e4 have an ulp of 2^-10
    // (0.06 texel at 64 texels per uv unit): interpolated in float, the entry point moved by up to
    // 0.13 texel; the tracer now interpolates and wraps the uv in double, so the hits agree to
    // float rounding of the wrapped texel position (about 1e-5 texel).
    const std::shared_ptr<const Tile> tile = wavyTile();
    const Scene near = planeScene(tile);
    Scene far = planeScene(tile);
    for (glm::vec2& uv : far.objects[0].mesh.uvs) uv += glm::vec2(1e4f, 1e4f);
    computeTangentFrames(far.objects[0].mesh);

    // Hit positions of the same rays, texel space (wrapped), against the small-uv truth.
    const SceneTracer nearTracer(near, TraceOptions{});
    const SceneTracer farTracer(far, TraceOptions{});
    double maxTexelError = 0.0;
    int compared = 0;
    for (int i = 0; i < 200; ++i) {
        const glm::vec3 target(-0.9f + 1.8f * float(i % 20) / 19.0f,
                               -0.9f + 1.8f * float(i / 20) / 9.0f, 0.0f);
        const glm::vec3 eye(0.3f, -1.6f, 1.2f);
        const Ray ray{eye, glm::normalize(target - eye)};
        SurfaceHit nearHit, farHit;
        TraceCounters counters;
        ASSERT_TRUE(nearTracer.traceNearest(ray, 0.0f, nearHit, counters));
        ASSERT_TRUE(farTracer.traceNearest(ray, 0.0f, farHit, counters));
        ASSERT_TRUE(isFinite(farHit.position) && isFinite(farHit.normal));
        if (!nearHit.onDetail || !farHit.onDetail || nearHit.march.onFloor != farHit.march.onFloor)
            continue;
        maxTexelError =
            std::max(maxTexelError, double(glm::length(farHit.position - nearHit.position)) * 32.0);
        ++compared;
    }
    EXPECT_GT(compared, 150);
    // 1e-3 texel: well above the rounding, well below the 0.13 texel of a float interpolation.
    EXPECT_LT(maxTexelError, 1e-3);

    const RenderOptions options = smallOptions();
    const RenderResult nearImage = renderScene(near, options);
    const RenderResult farImage = renderScene(far, options);
    EXPECT_EQ(nonFinitePixels(farImage.image), 0u);
    const ImageDifference difference = compareImages(nearImage.image, farImage.image);
    std::printf(
        "[ figures  ] far uvs (+1e4): hit error max %.4f texels over %d rays; image mean |diff| "
        "%.5f, "
        "max %.4f, share > 0.05: %.4f\n",
        maxTexelError, compared, difference.meanAbs, difference.maxAbs, difference.shareOver);
    // Hits 1e-5 texel apart shade alike: no pixel may differ visibly.
    EXPECT_LT(difference.meanAbs, 1e-4);
    EXPECT_EQ(difference.shareOver, 0.0);
}

TEST(Stress, BaseMeshFarFromTheWorldOriginRendersLikeNearIt) {
    // The plane and camera moved by 1e5 on every axis: the truth is the same image. Floats at 1e5
    // resolve 2^-7 = 0.0078 world units (0.25 texel here, a third of a pixel at this distance),
    // so the eye, the mesh and thus each ray move by about that: the depth AOV may differ by a
    // few ulps of 1e5 and pixels may change only along the detail's steep edges.
    const std::shared_ptr<const Tile> tile = wavyTile();
    const Scene near = planeScene(tile);
    Scene far = planeScene(tile);
    const glm::vec3 shift(1e5f, 1e5f, 1e5f);
    applyTransform(far.objects[0].mesh, {shift, {0.0f, 0.0f, 0.0f}, 1.0f});
    far.camera.eye += shift;
    far.camera.target += shift;
    const RenderOptions options = smallOptions();
    const RenderResult nearImage = renderScene(near, options);
    const RenderResult farImage = renderScene(far, options);
    EXPECT_EQ(nonFinitePixels(farImage.image), 0u);
    double maxDepthError = 0.0;
    std::size_t bothHit = 0;
    for (std::size_t i = 0; i < nearImage.aovs->depth.rgbLinear.size(); ++i) {
        const float a = nearImage.aovs->depth.rgbLinear[i].x,
                    b = farImage.aovs->depth.rgbLinear[i].x;
        if (a == 0.0f || b == 0.0f) continue;
        ++bothHit;
        maxDepthError = std::max(maxDepthError, double(std::abs(a - b)));
    }
    const ImageDifference difference = compareImages(nearImage.image, farImage.image);
    std::printf(
        "[ figures  ] base mesh at 1e5: depth error max %.4f world (%.2f texels) over %zu pixels; "
        "image mean |diff| %.5f, max %.4f, share > 0.05: %.4f\n",
        maxDepthError, maxDepthError * 32.0, bothHit, difference.meanAbs, difference.maxAbs,
        difference.shareOver);
    EXPECT_GT(bothHit, nearImage.aovs->depth.rgbLinear.size() / 2);
    // A ray moved by ~0.01 units may land on the other side of a detail edge (depth jumps by up to
    // the shell's 0.5 units there); most pixels differ by float rounding only.
    EXPECT_LT(maxDepthError, 0.5);
    EXPECT_LT(difference.meanAbs, 0.02);
    EXPECT_LT(difference.shareOver, 0.1);
}

/// A straight-down ray onto the plane scene at world (x, y): texel z of the hit against the flat
/// detail at `heightTexels` is the hit error (NaN when the ray stopped on no detail).
double downwardHitError(const SceneTracer& tracer, float x, float y, float heightTexels,
                        bool& onDetail) {
    SurfaceHit hit;
    TraceCounters counters;
    onDetail = false;
    if (!tracer.traceNearest({{x, y, 1.0f}, {0.0f, 0.0f, -1.0f}}, 0.0f, hit, counters))
        return std::nan("");
    EXPECT_TRUE(isFinite(hit.position) && isFinite(hit.normal) && std::isfinite(hit.distanceWorld));
    onDetail = hit.onDetail;
    return hit.onDetail ? double(hit.march.texelPosition.z) - heightTexels : std::nan("");
}

TEST(Stress, MirroredAndDegenerateUvTrianglesAndZeroAreaFacesStayFinite) {
    // A 2 x 2 plane split into separate triangles: the first quad's uvs are mirrored in u (w = -1),
    // one triangle has all three uvs equal, one has collinear uvs, and two faces have zero area
    // (a repeated corner, three collinear corners). Expected: computeTangentFrames gives finite
    // unit frames everywhere; the mirrored triangles still carry the detail (straight down onto
    // the flat detail plane z = 4 the hit error is below epsilon); the UV-degenerate ones show the
    // bare base surface (no texel scale to march with); zero-area faces are never hit; the image
    // is finite.
    constexpr float kHeight = 4.0f;
    const BaseMesh grid = makePlane(kPlaneSize, 2);
    BaseMesh mesh;
    for (const glm::uvec3& triangle : grid.triangles) {
        const auto first = std::uint32_t(mesh.positions.size());
        for (int corner = 0; corner < 3; ++corner) {
            mesh.positions.push_back(grid.positions[triangle[corner]]);
            mesh.uvs.push_back(grid.uvs[triangle[corner]]);
        }
        mesh.triangles.push_back({first, first + 1, first + 2});
    }
    ASSERT_EQ(mesh.triangles.size(), 8u);
    // Which triangles lie where: the centroid of each (x, y) decides, not the grid's order.
    std::vector<glm::vec2> centroids;
    for (const glm::uvec3& t : mesh.triangles)
        centroids.push_back(
            glm::vec2(mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]) / 3.0f);
    for (int corner = 0; corner < 3; ++corner) {
        mesh.uvs[mesh.triangles[0][corner]].x =
            1.0f - mesh.uvs[mesh.triangles[0][corner]].x;  // mirrored
        mesh.uvs[mesh.triangles[1][corner]].x = 1.0f - mesh.uvs[mesh.triangles[1][corner]].x;
        mesh.uvs[mesh.triangles[2][corner]] = glm::vec2(0.3f, 0.3f);  // all uvs equal
    }
    mesh.uvs[mesh.triangles[3][1]] = glm::vec2(0.5f, 0.5f);  // collinear uvs
    mesh.uvs[mesh.triangles[3][0]] = glm::vec2(0.0f, 0.0f);
    mesh.uvs[mesh.triangles[3][2]] = glm::vec2(1.0f, 1.0f);
    const auto extra = std::uint32_t(mesh.positions.size());
    for (const glm::vec3& p : {glm::vec3(0.2f, 0.2f, 0.0f), glm::vec3(0.2f, 0.2f, 0.0f),
                               glm::vec3(0.6f, 0.1f, 0.0f), glm::vec3(-0.5f, -0.5f, 0.0f),
                               glm::vec3(0.0f, 0.0f, 0.0f), glm::vec3(0.5f, 0.5f, 0.0f)}) {
        mesh.positions.push_back(p);
        mesh.uvs.push_back(glm::vec2(p) * 0.5f + 0.5f);
    }
    mesh.triangles.push_back({extra, extra + 1, extra + 2});      // repeated corner
    mesh.triangles.push_back({extra + 3, extra + 4, extra + 5});  // collinear corners
    computeTangentFrames(mesh);
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        ASSERT_TRUE(isFinite(mesh.normals[v]) && isFinite(glm::vec3(mesh.tangents[v])))
            << "vertex " << v;
        EXPECT_NEAR(glm::length(mesh.normals[v]), 1.0f, 1e-4f) << "vertex " << v;
        EXPECT_NEAR(glm::length(glm::vec3(mesh.tangents[v])), 1.0f, 1e-4f) << "vertex " << v;
        EXPECT_TRUE(mesh.tangents[v].w == 1.0f || mesh.tangents[v].w == -1.0f) << "vertex " << v;
    }
    EXPECT_EQ(mesh.tangents[mesh.triangles[0][0]].w,
              -1.0f);  // the mirrored triangle is left-handed

    Scene scene = planeScene(flatTile({32, 32, 8}, kHeight), kCubeDepth / 2.0f);
    scene.objects[0].mesh = mesh;
    const SceneTracer tracer(scene, TraceOptions{});
    double maxError = 0.0;
    for (std::size_t t = 0; t < 4; ++t) {
        bool onDetail = false;
        const double error =
            downwardHitError(tracer, centroids[t].x, centroids[t].y, kHeight, onDetail);
        if (t < 2) {
            ASSERT_TRUE(onDetail) << "mirrored triangle " << t;
            // Straight down on an exact plane distance: one exact step, then below epsilon.
            EXPECT_GE(error, -1e-4);
            EXPECT_LE(error, TraceOptions{}.march.epsilonTexels);
            maxError = std::max(maxError, std::abs(error));
        } else {
            EXPECT_FALSE(onDetail) << "UV-degenerate triangle " << t;
        }
    }
    const RenderResult result = renderScene(scene, smallOptions());
    EXPECT_EQ(nonFinitePixels(result.image), 0u);
    EXPECT_EQ(nonFinitePixels(result.aovs->normal), 0u);
    std::printf(
        "[ figures  ] mirrored uvs: hit error max %.5f texels on the flat detail plane; "
        "degenerate uv / zero-area faces: bare surface, 0 non-finite pixels\n",
        maxError);
}

TEST(Stress, CameraInsideTheShellSeesBackFacesAndFinitePixels) {
    // The eye sits inside the detail layer of a plane (a quarter of the depth below its base
    // surface, above the flat detail at half depth), over a bare ground plane 1 unit down.
    // Expected (the tracer enters a shell only through the front of its base surface): a ray
    // straight up stops on the bare back face of the base, one straight down passes the detail
    // it started above and reaches the ground, no shell is marched, no hang, every pixel finite.
    // Known limit, not the truth: the detail plane 0.0625 units below the eye is not seen.
    const float depthWorld = kCubeDepth / 2.0f;
    Scene scene = planeScene(flatTile({32, 32, 8}, 4.0f), depthWorld);
    SceneObject ground;
    ground.mesh = makePlane(20.0f, 1);
    applyTransform(ground.mesh, {{0.0f, 0.0f, -1.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    scene.objects.push_back(std::move(ground));
    const glm::vec3 eye(0.1f, -0.2f, -0.25f * depthWorld);
    scene.camera = {eye, {1.0f, 0.4f, -0.3f}, {0.0f, 0.0f, 1.0f}, 90.0f};

    const SceneTracer tracer(scene, TraceOptions{});
    SurfaceHit up, down;
    TraceCounters counters;
    ASSERT_TRUE(tracer.traceNearest({eye, {0.0f, 0.0f, 1.0f}}, 0.0f, up, counters));
    EXPECT_FALSE(up.entry.frontFacing);
    EXPECT_FALSE(up.onDetail);
    ASSERT_TRUE(tracer.traceNearest({eye, {0.0f, 0.0f, -1.0f}}, 0.0f, down, counters));
    EXPECT_EQ(down.object, 1u);
    // Exact distances 0.0625 and 0.9375 (float rounding of the double-precision hit: 1e-6).
    const double upError = std::abs(double(up.distanceWorld) - 0.25 * depthWorld);
    const double downError = std::abs(double(down.distanceWorld) - (1.0 - 0.25 * depthWorld));
    EXPECT_LT(upError, 1e-6);
    EXPECT_LT(downError, 1e-6);
    EXPECT_EQ(counters.marchIterations, 0u);

    const RenderResult result = renderScene(scene, smallOptions());
    EXPECT_EQ(nonFinitePixels(result.image), 0u);
    EXPECT_GT(result.stats.baseHits,
              result.stats.rays / 2);  // the ground fills the lower half and more
    EXPECT_EQ(result.stats.marchIterations, 0u);
    std::printf(
        "[ figures  ] camera inside the shell: back-face hit error %.2g, ground hit error %.2g "
        "world; "
        "%llu rays, %llu base hits, 0 march steps, 0 non-finite\n",
        upError, downError, (unsigned long long)result.stats.rays,
        (unsigned long long)result.stats.baseHits);
}

TEST(Stress, WiresThinnerThanATexelBakeAndRenderFinite) {
    // Chain mail with a wire radius of 0.08 texel (0.01 ring spacings of 8 texels) on a
    // 32 x 32 x 8 tile. Expected: the bake accepts it (the options only need radii > 0 and rings
    // inside the slab); the conservative tile never overestimates the exact distance by more than
    // rounding (thin wires are where trilinear overestimation would open holes); the render is
    // finite. The converged share is reported: a sub-texel wire is found only near its centreline.
    ChainmailOptions chainmail;
    chainmail.ringsPerRow = 4;
    chainmail.rowsPerTile = 4;
    chainmail.wireRadiusSpacings = 0.01;
    BakeOptions bake;
    bake.size = {32, 32, 8};
    BakeResult baked = [&] {
        try {
            return bakeChainmail(chainmail, bake);
        } catch (const InputError& error) {
            ADD_FAILURE() << "a sub-texel wire was refused: " << error.what();
            throw;
        }
    }();
    const Chainmail truth(chainmail, bake.size);
    double maxOverestimate = -1e9, maxAbsError = 0.0;
    const Size3& size = baked.tile.size();
    for (int z = 0; z < size.depth; ++z)
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x) {
                const double exact = truth.signedDistanceTexels({x + 0.5, y + 0.5, z + 0.5});
                const double stored = baked.tile.at(x, y, z);
                ASSERT_TRUE(std::isfinite(stored));
                maxOverestimate = std::max(maxOverestimate, stored - exact);
                maxAbsError = std::max(maxAbsError, std::abs(stored - exact));
            }
    // The level set is exact to float rounding at these few texels of distance (1e-3 texel).
    EXPECT_LE(maxOverestimate, 1e-3);
    Scene scene =
        planeScene(std::make_shared<const Tile>(std::move(baked.tile)), kCubeDepth / 2.0f);
    const RenderResult result = renderScene(scene, smallOptions());
    EXPECT_EQ(nonFinitePixels(result.image), 0u);
    std::printf(
        "[ figures  ] wires of 0.08 texel: tile max overestimate %.5f, max |error| %.4f texels; "
        "converged %.3f of %llu base hits\n",
        maxOverestimate, maxAbsError, convergedShare(result.stats),
        (unsigned long long)result.stats.baseHits);
}

TEST(Stress, ShellDepthsFrom1e4To1e2WorldUnitsStayFinite) {
    // One plane carrying the flat detail z = 4 of 8 texels, with shell depths from 1e-4 to 1e2
    // world units (texels 1/32 unit wide and from 1/2500 to 400 times as tall as wide).
    // Expected: finite images, no hang; deep shells make the texel-space rays grazing, so fewer
    // converge within 16 steps. Error: straight-down rays (exact steps) land on the detail plane
    // within epsilon at every depth; the converged share of the camera rays is reported.
    constexpr float kHeight = 4.0f;
    for (float depthWorld : {1e-4f, 1e-2f, 1.0f, 1e2f}) {
        const Scene scene = planeScene(flatTile({32, 32, 8}, kHeight), depthWorld);
        const SceneTracer tracer(scene, TraceOptions{});
        bool onDetail = false;
        const double error = downwardHitError(tracer, 0.13f, -0.37f, kHeight, onDetail);
        ASSERT_TRUE(onDetail) << depthWorld;
        EXPECT_GE(error, -1e-4) << depthWorld;
        EXPECT_LE(error, TraceOptions{}.march.epsilonTexels) << depthWorld;
        const RenderResult result = renderScene(scene, smallOptions());
        EXPECT_EQ(nonFinitePixels(result.image), 0u) << depthWorld;
        EXPECT_GT(result.stats.baseHits, 0u);
        std::printf(
            "[ figures  ] shell depth %g world: straight-down hit error %.5f texels; converged "
            "%.3f of "
            "%llu camera base hits, %.2f steps each\n",
            double(depthWorld), error, convergedShare(result.stats),
            (unsigned long long)result.stats.baseHits, result.stats.meanIterations());
    }
}

TEST(Stress, NanAndInfRaysMissOrStayFinite) {
    // Rays with NaN or Inf components, straight into the tracer and the march. Expected: a miss,
    // or a hit whose distance, position and normal (all that shading uses) are finite; the march
    // ends within its budget.
    const Scene scene = planeScene(wavyTile());
    const SceneTracer tracer(scene, TraceOptions{});
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    const glm::vec3 down(0.0f, 0.0f, -1.0f);
    const std::vector<Ray> rays = {
        {{nan, 0.0f, 1.0f}, down},
        {{0.0f, 0.0f, nan}, down},
        {{0.0f, 0.0f, 1.0f}, {nan, 0.0f, -1.0f}},
        {{0.0f, 0.0f, 1.0f}, {0.0f, 0.0f, nan}},
        {{inf, 0.0f, 1.0f}, down},
        {{0.0f, 0.0f, inf}, down},
        {{0.0f, 0.0f, 1.0f}, {inf, 0.0f, -1.0f}},
        {{0.0f, 0.0f, 1.0f}, {0.0f, 0.0f, -inf}},
        {{0.0f, 0.0f, 1.0f}, {-inf, inf, -inf}},
        {{0.0f, 0.0f, 1.0f}, {0.0f, 0.0f, 0.0f}},
    };
    int misses = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        SurfaceHit hit;
        TraceCounters counters;
        if (!tracer.traceNearest(rays[i], 0.0f, hit, counters)) {
            ++misses;
            continue;
        }
        EXPECT_TRUE(std::isfinite(hit.distanceWorld) && isFinite(hit.position) &&
                    isFinite(hit.normal))
            << "ray " << i;
    }
    const Tile& tile = *scene.objects[0].material.tile;
    const TrilinearFilter filter(tile);
    for (const glm::vec3& position :
         {glm::vec3(nan, 3.0f, 16.0f), glm::vec3(3.0f, 3.0f, nan), glm::vec3(inf, 3.0f, 16.0f)}) {
        const MarchResult result =
            march(filter, position, glm::normalize(glm::vec3(0.3f, 0.1f, -1.0f)), Floor::Solid, 16,
                  0.02f);
        EXPECT_LE(result.iterations, 16);
        // Rejected at the door: no hit claimed at a NaN position (it used to converge there).
        EXPECT_FALSE(result.converged);
        EXPECT_EQ(result.iterations, 0);
    }
    for (const glm::vec3& direction :
         {glm::vec3(nan, 0.0f, -1.0f), glm::vec3(0.0f, 0.0f, nan), glm::vec3(inf, 0.0f, -inf)}) {
        const MarchResult result =
            march(filter, glm::vec3(3.0f, 3.0f, 16.0f), direction, Floor::Solid, 16, 0.02f);
        EXPECT_LE(result.iterations, 16);
        EXPECT_FALSE(result.converged);
        EXPECT_EQ(result.iterations, 0);
    }
    std::printf("[ figures  ] NaN/Inf rays: %d of %zu missed, the rest finite\n", misses,
                rays.size());
}

}  // namespace
}  // namespace distile
