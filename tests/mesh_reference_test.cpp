// Reference renders of mesh detail with exact ray/mesh hits (Material::exactHit,
// truth/mesh_truth.h MeshDistance::firstHit) against the analytic surface the mesh tessellates.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <optional>

#include "bake/bake.h"
#include "detail_meshes.h"
#include "mesh/base_mesh.h"
#include "render/compare.h"
#include "render/renderer.h"
#include "truth/mesh_truth.h"

namespace distile {
namespace {

// A torus lying in a 32 x 32 x 8 tile across the x = 0 and y = 0 borders: R 9, r 3 texels,
// centre (3, 2, 4), so rays meet copies of the neighbouring tiles.
constexpr Size3 kTile{32, 32, 8};
const glm::dvec3 kCentre(3.0, 2.0, 4.0);
constexpr double kMajorRadius = 9.0;
constexpr double kMinorRadius = 3.0;
constexpr int kMajorSegments = 96;
constexpr int kMinorSegments = 32;

/// The analytic torus, periodic in x and y: the nearest of the copies around the wrapped point
/// (the torus spans 24 texels < W, H, so the copies one tile away are the only candidates).
double periodicTorusDistance(const glm::dvec3& texel) {
    const glm::dvec3 wrapped(texel.x - kTile.width * std::floor(texel.x / kTile.width),
                             texel.y - kTile.height * std::floor(texel.y / kTile.height), texel.z);
    double nearest = HUGE_VAL;
    for (int m = -1; m <= 1; ++m) {
        for (int n = -1; n <= 1; ++n) {
            const glm::dvec3 q =
                wrapped - kCentre - glm::dvec3(m * kTile.width, n * kTile.height, 0.0);
            nearest = std::min(nearest,
                               std::hypot(std::hypot(q.x, q.y) - kMajorRadius, q.z) - kMinorRadius);
        }
    }
    return nearest;
}

RenderResult renderReference(const Material& material) {
    Scene scene;
    scene.camera = {{0.3f, -1.5f, 1.1f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    SceneObject plane;
    plane.mesh = makePlane(2.0f, 1);  // 2 x 2 world units, uv [0, 1]
    plane.material = material;
    scene.objects.push_back(std::move(plane));
    RenderOptions options;
    options.width = 160;
    options.height = 120;
    options.outputAovs = true;
    options.reference = true;
    options.shadowFilter = ShadowFilter::None;  // hits and normals are compared, not shading
    options.selfShadows = false;
    return renderScene(scene, options);
}

TEST(MeshReference, ExactMeshHitsAgreeWithTheAnalyticTorusToTheTessellationError) {
    const TriangleSoup torus =
        test::makeTorusSoup(kCentre, kMajorRadius, kMinorRadius, kMajorSegments, kMinorSegments);
    MeshPlacement placement;
    placement.fit = false;  // the soup is in texels already
    BakeOptions bake;
    bake.size = kTile;
    Material material;
    material.tile = std::make_shared<const Tile>(bakeMesh(torus, placement, bake).tile);
    material.uvScale = {2.0f, 2.0f};  // 32 texels per world unit
    material.depthWorld = 8.0f / 32.0f;
    material.analyticDistance = periodicTorusDistance;

    // The truth: the analytic torus, sphere traced in double precision.
    const RenderResult analytic = renderReference(material);
    // Tested: exact hits on the tessellated torus.
    const auto mesh = std::make_shared<const MeshDistance>(torus, MeshDistance::Periodic{kTile});
    material.exactHit = [mesh](const glm::dvec3& origin, const glm::dvec3& direction,
                               double maxTravelTexels) -> std::optional<DetailHit> {
        const auto hit = mesh->firstHit(origin, direction, maxTravelTexels);
        if (!hit) return std::nullopt;
        return DetailHit{hit->distance, hit->normal};
    };
    const RenderResult exact = renderReference(material);
    // Exact hits take one query per shell entry instead of a march: one per hit, and one per ray
    // that left through the plane's edge (and then hit nothing).
    EXPECT_GE(exact.stats.marchIterations, exact.stats.converged);
    EXPECT_LE(exact.stats.marchIterations - exact.stats.converged,
              exact.stats.rays - exact.stats.baseHits);

    const RenderComparison comparison = compareRenders(
        {exact.image, exact.aovs->depth, exact.aovs->normal, exact.aovs->texelScale},
        {analytic.image, analytic.aovs->depth, analytic.aovs->normal, analytic.aovs->texelScale});
    std::printf(
        "exact mesh hits vs analytic torus: hit error mean %.4f p99 %.4f max %.3f texels, "
        "coverage mismatch %.5f, normal error %.3f deg, %llu px compared\n",
        comparison.meanHitErrorTexels, comparison.p99HitErrorTexels, comparison.maxHitErrorTexels,
        comparison.coverageMismatchShare, comparison.meanNormalErrorDeg,
        static_cast<unsigned long long>(comparison.hitErrorSamples));
    // The plane covers about three quarters of the 160 x 120 view; the rest is sky in both.
    ASSERT_GT(comparison.hitErrorSamples, 12000u);
    // The tessellated surface lies within e = 0.021 texel of the analytic one, inside it (chord
    // sagittas, test::torusTessellationError), so a hit moves by up to e / cos(incidence) along
    // the ray, plus the analytic march's epsilon (1e-3 texel). Over the view (incidence mostly
    // below 60 degrees, the floor exact in both) the mean stays below 2e. The p99 includes
    // grazing pixels on the tube's flanks: bounded by e / cos(82 degrees) = 0.15 texel. The mean
    // is not zero: the exact hits are on the facets, not on the analytic surface.
    const double tessellation =
        test::torusTessellationError(kMajorRadius, kMinorRadius, kMajorSegments, kMinorSegments);
    EXPECT_GT(comparison.meanHitErrorTexels, 0.0);
    EXPECT_LT(comparison.meanHitErrorTexels, 2.0 * tessellation);
    EXPECT_LT(comparison.p99HitErrorTexels,
              tessellation / std::cos(82.0 * std::numbers::pi / 180.0));
    // The floor is solid: every pixel on the plane is a hit in both, the sky a miss in both, but
    // for rays that meet the torus where the plane's open edge cuts it: a hit within the
    // tessellation error of the cut can lie inside the edge in one and beyond it (the ray left
    // the shell) in the other. A few pixels along the visible edges, 7 measured: at most 0.1%.
    EXPECT_LE(double(comparison.coverageMismatches), 1e-3 * 160.0 * 120.0);
    // Flat facets against the smooth surface: the facet normal is off by at most half the angle
    // between neighbouring vertex normals, 180 / 32 = 5.6 degrees across the tube, on average
    // half that. The floor (normal exact in both) pulls the mean lower still.
    EXPECT_LT(comparison.meanNormalErrorDeg, 0.5 * 180.0 / kMinorSegments);
}

}  // namespace
}  // namespace distile
