// A 2x2 render shows no seam for tiles baked from meshes and height maps. A plane
// carrying 2 x 2 repeats of a tile is rendered from high above with a narrow field of view; every
// pixel's hit is compared with the truth along the same ray (the periodic mesh through CGAL, the
// triangulated height field). A seam is the hits next to the tile borders being worse than the
// others; a tile whose border column is damaged on purpose shows that the check sees one.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <glm/geometric.hpp>
#include <memory>

#include "bake/bake.h"
#include "bake/height_image.h"
#include "detail_meshes.h"
#include "mesh/base_mesh.h"
#include "render/coverage.h"
#include "render/renderer.h"
#include "truth/mesh_truth.h"
#include "vdb/height_field.h"

namespace distile {
namespace {

/// First hit along a ray in texel space, texels travelled from `origin` (on the top, z = D); the
/// floor z = 0 when nothing else is hit.
using TruthAlongRay = std::function<double(const glm::dvec3& origin, const glm::dvec3& direction)>;

struct SeamFigures {
    double nearSeamMean = 0.0;  ///< mean |hit error| where the hit is within 1.5 texels of a border
    double elsewhereMean = 0.0;
    int nearSeam = 0;
    int elsewhere = 0;
};

/// The plane (2 x 2 world units, uv scale 2: one tile per world unit, W texels) seen straight
/// down from 40 units above, 256 x 256 pixels covering it; hit errors in texels along each ray.
SeamFigures seamFigures(std::shared_ptr<const Tile> tile, const TruthAlongRay& truth) {
    const Size3 size = tile->size();
    const float texelsPerWorld = float(size.width);  // one tile per world unit
    Scene scene;
    constexpr float kHeight = 40.0f;
    scene.camera = {{0.0f, 0.0f, kHeight},
                    {0.0f, 0.0f, 0.0f},
                    {0.0f, 1.0f, 0.0f},
                    float(2.0 * std::atan(0.98 / kHeight) * 180.0 / 3.14159265358979)};
    SceneObject plane;
    plane.mesh = makePlane(2.0f, 1);
    plane.material.tile = tile;
    plane.material.uvScale = {2.0f, 2.0f};
    plane.material.depthWorld = float(size.depth) / texelsPerWorld;
    scene.objects.push_back(std::move(plane));
    RenderOptions options;
    options.width = options.height = 256;
    options.outputAovs = true;
    options.shadowFilter = ShadowFilter::None;
    options.selfShadows = false;
    options.march.maxIterations = 64;
    const RenderResult result = renderScene(scene, options);
    const PinholeProjection projection(scene.camera, options.width, options.height);

    SeamFigures figures;
    for (int y = 0; y < options.height; ++y) {
        for (int x = 0; x < options.width; ++x) {
            const float depth = result.aovs->depth.at(x, y).x;
            if (depth <= 0.0f) continue;  // a miss: none here, the plane fills the image
            const Ray ray = projection.ray(float(x) + 0.5f, float(y) + 0.5f);
            // Where the ray enters the shell (world z = 0), and the hit, in texel space of the
            // tile the entry lies in.
            const glm::dvec3 eye(ray.origin);
            const glm::dvec3 direction(ray.direction);
            const double toTop = eye.z / -direction.z;
            const glm::dvec3 top = eye + direction * toTop;
            const double u = (top.x / 2.0 + 0.5) * 2.0, v = (top.y / 2.0 + 0.5) * 2.0;
            const glm::dvec3 entry((u - std::floor(u)) * size.width,
                                   (v - std::floor(v)) * size.height, double(size.depth));
            const double rendered = (double(depth) - toTop) * texelsPerWorld;
            const double error = std::abs(rendered - truth(entry, direction));
            const glm::dvec3 hit = entry + direction * rendered;
            const double toBorderX = std::min(std::abs(hit.x), std::abs(size.width - hit.x));
            const double toBorderY = std::min(std::abs(hit.y), std::abs(size.height - hit.y));
            if (std::min(toBorderX, toBorderY) < 1.5) {
                figures.nearSeamMean += error;
                ++figures.nearSeam;
            } else {
                figures.elsewhereMean += error;
                ++figures.elsewhere;
            }
        }
    }
    figures.nearSeamMean /= std::max(figures.nearSeam, 1);
    figures.elsewhereMean /= std::max(figures.elsewhere, 1);
    return figures;
}

/// The tile with its first column raised by one texel: a border that no longer matches.
std::shared_ptr<const Tile> damagedBorder(const Tile& tile) {
    auto damaged = std::make_shared<Tile>(tile);
    for (int z = 0; z < tile.size().depth; ++z)
        for (int y = 0; y < tile.size().height; ++y) damaged->at(0, y, z) += 1.0f;
    return damaged;
}

void expectSeamless(const char* what, const SeamFigures& good, const SeamFigures& damaged) {
    std::printf(
        "[ figures  ] %s 2x2: mean hit error near the borders %.4f texel (%d px), elsewhere "
        "%.4f (%d px); with a damaged border %.4f near it\n",
        what, good.nearSeamMean, good.nearSeam, good.elsewhereMean, good.elsewhere,
        damaged.nearSeamMean);
    ASSERT_GT(good.nearSeam, 1000);
    ASSERT_GT(good.elsewhere, 10000);
    // Seamless: the border pixels are as good as the rest (0.05 texel of slack for the
    // different content near the borders), and both are small against the detail's size.
    EXPECT_LE(good.nearSeamMean, good.elsewhereMean + 0.05) << what;
    EXPECT_LE(good.elsewhereMean, 0.05) << what;
    // The check sees a seam: one column one texel off raises the border pixels' error.
    EXPECT_GT(damaged.nearSeamMean, good.elsewhereMean + 0.05) << what;
}

TEST(Seams, MeshTileRepeatsWithoutASeam) {
    // A torus lying in the tile, crossing the x = 0 and y = 0 borders: R 9, r 3 texels, centre
    // (3, 2, 4) in 32 x 32 x 8.
    const Size3 size{32, 32, 8};
    const TriangleSoup torus = test::makeTorusSoup(glm::dvec3(3.0, 2.0, 4.0), 9.0, 3.0, 96, 32);
    MeshPlacement placement;
    placement.fit = false;
    BakeOptions options;
    options.size = size;
    const auto tile = std::make_shared<const Tile>(bakeMesh(torus, placement, options).tile);
    const MeshDistance mesh(torus);
    const TruthAlongRay truth = [&](const glm::dvec3& origin, const glm::dvec3& direction) {
        double nearest = origin.z / -direction.z;  // the floor
        for (int m = -1; m <= 1; ++m) {
            for (int n = -1; n <= 1; ++n) {
                double t = 0.0;
                const glm::dvec3 shifted = origin + glm::dvec3(m * size.width, n * size.height, 0);
                if (mesh.rayHit(shifted, direction, t) && t < nearest) nearest = t;
            }
        }
        return nearest;
    };
    ASSERT_NO_FATAL_FAILURE(expectSeamless("mesh tile", seamFigures(tile, truth),
                                           seamFigures(damagedBorder(*tile), truth)));
}

TEST(Seams, HeightMapTileRepeatsWithoutASeam) {
    // A smooth periodic height image: heights 1 + 5 (0.5 + 0.3 sin(2 pi x) cos(4 pi y)) texels.
    const Size3 size{32, 32, 8};
    HeightImage image;
    image.width = image.height = 64;
    for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
            const double u = (x + 0.5) / image.width, v = (y + 0.5) / image.height;
            image.values.push_back(float(0.5 + 0.3 * std::sin(2.0 * 3.14159265358979 * u) *
                                                   std::cos(4.0 * 3.14159265358979 * v)));
        }
    }
    HeightMapOptions heightMap;
    heightMap.heightTexels = 6.0;
    BakeOptions options;
    options.size = size;
    const auto tile = std::make_shared<const Tile>(bakeHeightMap(image, heightMap, options).tile);
    const HeightField field = heightFieldFromImage(image, size, heightMap.heightTexels);
    // The triangulated surface: nodes at texel-column centres, cells split along (i, j)-(i+1, j+1).
    auto surfaceHeight = [&](double x, double y) {
        const double sx = x - 0.5, sy = y - 0.5;
        const int i = int(std::floor(sx)), j = int(std::floor(sy));
        const double fx = sx - i, fy = sy - j;
        const double h00 = field.node(i, j), h11 = field.node(i + 1, j + 1);
        return fx >= fy
                   ? h00 + fx * (field.node(i + 1, j) - h00) + fy * (h11 - field.node(i + 1, j))
                   : h00 + fy * (field.node(i, j + 1) - h00) + fx * (h11 - field.node(i, j + 1));
    };
    const TruthAlongRay truth = [&](const glm::dvec3& origin, const glm::dvec3& direction) {
        // Steps of 0.02 texel along a nearly vertical ray (the surface's slope is below 1), then
        // the linear crossing: within 1e-4 texel of the exact one.
        double previous = 0.0;
        for (double t = 0.0;; t += 0.02) {
            const glm::dvec3 p = origin + direction * t;
            if (p.z <= surfaceHeight(p.x, p.y)) {
                const glm::dvec3 q = origin + direction * previous;
                const double above = q.z - surfaceHeight(q.x, q.y);
                const double below = surfaceHeight(p.x, p.y) - p.z;
                return previous + (t - previous) * above / (above + below);
            }
            previous = t;
        }
    };
    ASSERT_NO_FATAL_FAILURE(expectSeamless("height-map tile", seamFigures(tile, truth),
                                           seamFigures(damagedBorder(*tile), truth)));
}

}  // namespace
}  // namespace distile
