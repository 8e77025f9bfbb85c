// Tests of the shell map (common/shell_map.h) and of the march that follows it through curved
// shells (render/shell_march.h, SceneTracer with ShellMapping::Curved). The known answers: a
// layer of constant depth h in the shell is, by the map's definition, the mesh of the base
// triangles moved by -h N_i at their corners (flat triangles at every h), so a ray's hit on it is
// a ray/triangle intersection computed here in double precision, independently of the march.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <utility>

#include "common/shell_map.h"
#include "mesh/base_mesh.h"
#include "render/bvh.h"
#include "render/renderer.h"
#include "render/shading.h"
#include "render/shell_march.h"
#include "render/tracer.h"
#include "tests/on_threads.h"

namespace distile {
namespace {

/// A tile whose detail is the horizontal plane z = heightTexels (solid below): trilinear
/// reconstruction reproduces its distance exactly.
Tile layerTile(const Size3& size, float heightTexels) {
    Tile tile(size);
    for (int z = 0; z < size.depth; ++z)
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x) tile.at(x, y, z) = (z + 0.5f) - heightTexels;
    return tile;
}

constexpr float kLayerTexels = 6.0f;  ///< the layer's height in the 16-deep tile
constexpr float kDepthWorld = 0.04f;

Scene layerScene(BaseMesh mesh, float depthWorld = kDepthWorld) {
    Scene scene;
    SceneObject object;
    object.mesh = std::move(mesh);
    object.material.tile = std::make_shared<const Tile>(layerTile({32, 32, 16}, kLayerTexels));
    object.material.uvScale = {8.0f, 4.0f};
    object.material.depthWorld = depthWorld;
    scene.objects.push_back(std::move(object));
    return scene;
}

/// The nearest front-facing hit of `ray` on the base mesh moved to depth `depthWorld` along its
/// vertex normals (the shell's layer at that depth), in double precision; nothing for a miss.
std::optional<double> layerHit(const BaseMesh& mesh, const Ray& ray, double depthWorld) {
    std::optional<double> nearest;
    for (const glm::uvec3& triangle : mesh.triangles) {
        glm::dvec3 corners[3];
        for (int corner = 0; corner < 3; ++corner) {
            corners[corner] = glm::dvec3(mesh.positions[triangle[corner]]) -
                              depthWorld * glm::dvec3(mesh.normals[triangle[corner]]);
        }
        const glm::dvec3 edge1 = corners[1] - corners[0], edge2 = corners[2] - corners[0];
        const glm::dvec3 direction(ray.direction);
        if (glm::dot(glm::cross(edge1, edge2), direction) >= 0.0) continue;  // a back face
        const glm::dvec3 pvec = glm::cross(direction, edge2);
        const double determinant = glm::dot(edge1, pvec);
        const glm::dvec3 tvec = glm::dvec3(ray.origin) - corners[0];
        const double b1 = glm::dot(tvec, pvec) / determinant;
        const glm::dvec3 qvec = glm::cross(tvec, edge1);
        const double b2 = glm::dot(direction, qvec) / determinant;
        const double distance = glm::dot(edge2, qvec) / determinant;
        if (b1 < 0.0 || b2 < 0.0 || b1 + b2 > 1.0 || distance <= 0.0) continue;
        if (!nearest || distance < *nearest) nearest = distance;
    }
    return nearest;
}

double layerDepthWorld(float depthWorld) {
    return depthWorld * (1.0 - kLayerTexels / 16.0);
}

/// A march that converges far below the default threshold, so a hit is where the map puts it.
TraceOptions preciseOptions(ShellMapping mapping) {
    TraceOptions options;
    options.march.maxIterations = 512;
    options.march.epsilonTexels = 1e-4f;
    options.shellMapping = mapping;
    return options;
}

ShellPrism curvedPrism() {
    // A triangle on a sphere of radius 2 with the sphere's normals, and a skewed uv triangle.
    const glm::vec3 corners[3] = {glm::normalize(glm::vec3(1.0f, 0.1f, 0.2f)) * 2.0f,
                                  glm::normalize(glm::vec3(0.9f, 0.5f, 0.1f)) * 2.0f,
                                  glm::normalize(glm::vec3(0.95f, 0.2f, 0.6f)) * 2.0f};
    const glm::vec3 normals[3] = {corners[0] / 2.0f, corners[1] / 2.0f, corners[2] / 2.0f};
    const glm::vec2 uvs[3] = {{0.1f, 0.2f}, {0.35f, 0.22f}, {0.18f, 0.5f}};
    return ShellPrism::make(corners, normals, uvs, {3.0f, 2.0f}, 64, 64, 16, 0.3);
}

TEST(ShellMap, InvertsTheForwardMapInsideThePrism) {
    const ShellPrism prism = curvedPrism();
    std::mt19937 random(7);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int sample = 0; sample < 200; ++sample) {
        double b1 = unit(random), b2 = unit(random);
        if (b1 + b2 > 1.0) b1 = 1.0 - b1, b2 = 1.0 - b2;
        const PrismPoint point{b1, b2, prism.depthWorld * unit(random)};
        PrismPoint found{1.0 / 3.0, 1.0 / 3.0, 0.0};  // from the centre of the top
        ShellPrism::Jacobian jacobian;
        ASSERT_TRUE(prism.invert(prism.offsetAt(point), found, jacobian));
        // The map is nearly affine: after the step that moved less than 1e-3 the error left is
        // of the order of its square.
        EXPECT_NEAR(found.b1, point.b1, 1e-6);
        EXPECT_NEAR(found.b2, point.b2, 1e-6);
        EXPECT_NEAR(found.depthWorld, point.depthWorld, 1e-6 * prism.depthWorld);
        // texel and back
        const PrismPoint again = prism.pointAtTexel(prism.texelAt(point));
        EXPECT_NEAR(again.b1, point.b1, 1e-12);
        EXPECT_NEAR(again.b2, point.b2, 1e-12);
        EXPECT_NEAR(again.depthWorld, point.depthWorld, 1e-12);
    }
}

/// A shell of one prism (no neighbours: every side is an open border).
struct LoneShell {
    std::array<std::uint32_t, 3> neighbours = {ShellPrisms::kNoNeighbour, ShellPrisms::kNoNeighbour,
                                               ShellPrisms::kNoNeighbour};
    std::array<std::uint8_t, 3> corners = {0, 0, 0};
    /// The shell of `prism`, which must outlive it.
    ShellPrisms of(const ShellPrism& prism) const {
        return {std::span(&prism, 1), std::span(&neighbours, 1), std::span(&corners, 1)};
    }
};

/// The largest distance (world units) of the samples of curved marches through `prism` alone
/// (rays entering its top, tilted from its normal, marching to the layer 3 texels above its
/// floor) from their world rays: each sample's texel position mapped back to world space.
double farthestSampleFromTheRay(const ShellPrism& prism, int& samples) {
    const LoneShell lone;
    const ShellPrisms shell = lone.of(prism);
    std::mt19937 random(5);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    double farthestWorld = 0.0;
    samples = 0;
    for (int index = 0; index < 200; ++index) {
        const double b1 = 0.1 + 0.4 * unit(random), b2 = 0.1 + 0.4 * unit(random);
        const glm::dvec3 inward = -glm::normalize(prism.normalAt(b1, b2));
        const glm::dvec3 tilt(unit(random) - 0.5, unit(random) - 0.5, unit(random) - 0.5);
        const glm::dvec3 top = prism.worldAt({b1, b2, 0.0});
        const Ray ray{glm::vec3(top - glm::normalize(inward + tilt)),
                      glm::vec3(glm::normalize(inward + tilt))};
        const glm::dvec3 origin(ray.origin), direction(ray.direction);
        MarchSettings settings;
        settings.maxIterations = 64;
        CurvedMarchRay march;
        march.start(shell, ray, 0, b1, b2, glm::dot(top - origin, direction), Floor::Solid,
                    settings);
        while (march.needsSample()) {
            const glm::vec3 texel = march.samplePosition();
            const glm::dvec3 offset = prism.worldAt(prism.pointAtTexel(glm::dvec3(texel))) - origin;
            farthestWorld = std::max(farthestWorld,
                                     glm::length(offset - glm::dot(offset, direction) * direction));
            ++samples;
            march.advance(float(double(texel.z) - 3.0));
        }
    }
    return farthestWorld;
}

TEST(CurvedShell, EverySampleOfACurvedMarchLiesOnItsWorldRay) {
    // Between Newton steps a curved march takes its samples by chord steps (the Jacobian of an
    // earlier step kept): each sample's point is still put back on the world ray, to within
    // what the Jacobian's change over the few texels since that step leaves. On a triangle of a
    // sphere of radius 2 (texels of about 0.01 world units across) with a shell 0.05 deep, that
    // is the float rounding of a texel position (1e-7 world units); with a shell 0.3 deep, whose
    // stretch changes by a tenth over those texels, about 1e-3 texel. A point left where the
    // ray's prism-space velocity predicts it strays 8 and 50 times as far.
    for (const auto& [depthWorld, toleranceWorld] : {std::pair(0.05, 2e-7), std::pair(0.3, 5e-5)}) {
        ShellPrism prism = curvedPrism();
        prism.depthWorld = depthWorld;
        prism.texelsPerDepthWorld = prism.depthTexels / depthWorld;
        int samples = 0;
        EXPECT_LT(farthestSampleFromTheRay(prism, samples), toleranceWorld) << depthWorld;
        EXPECT_GT(samples, 500) << depthWorld;  // 3 to 4.5 per ray
    }
}

TEST(CurvedShell, SelfShadowPathsComeBackToTheirWorldRayAtEverySettle) {
    // A self-shadow path moves along its tangent in the prism between corrections; every
    // kStepsPerSettle steps its point is put back on the world ray, by a chord step near the
    // last Newton step: as close as the camera rays' samples (above).
    for (const auto& [depthWorld, toleranceWorld] : {std::pair(0.05, 2e-7), std::pair(0.3, 5e-5)}) {
        ShellPrism prism = curvedPrism();
        prism.depthWorld = depthWorld;
        prism.texelsPerDepthWorld = prism.depthTexels / depthWorld;
        const LoneShell lone;
        const ShellPrisms shell = lone.of(prism);
        std::mt19937 random(9);
        std::uniform_real_distribution<double> unit(0.0, 1.0);
        double farthestWorld = 0.0;
        int settled = 0;
        for (int index = 0; index < 200; ++index) {
            const PrismPoint from{0.2 + 0.3 * unit(random), 0.2 + 0.3 * unit(random),
                                  (0.7 + 0.2 * unit(random)) * depthWorld};
            const glm::dvec3 outward = glm::normalize(prism.normalAt(from.b1, from.b2));
            const glm::dvec3 tilt(unit(random) - 0.5, unit(random) - 0.5, unit(random) - 0.5);
            const glm::dvec3 origin = prism.worldAt(from);
            const glm::dvec3 direction = glm::normalize(outward + 0.8 * tilt);
            ShellRayPath path;
            ASSERT_TRUE(path.start(shell, origin, direction, 0, from));
            for (int step = 1; path.advance(0.75); ++step) {
                if (step % ShellRayPath::kStepsPerSettle != 0) continue;
                const glm::dvec3 offset =
                    prism.worldAt(prism.pointAtTexel(glm::dvec3(path.texelPosition()))) - origin;
                farthestWorld = std::max(
                    farthestWorld, glm::length(offset - glm::dot(offset, direction) * direction));
                ++settled;
            }
        }
        EXPECT_LT(farthestWorld, toleranceWorld) << depthWorld;
        EXPECT_GT(settled, 200) << depthWorld;
    }
}

TEST(ShellMap, JacobianIsTheMapsDerivative) {
    const ShellPrism prism = curvedPrism();
    const PrismPoint point{0.3, 0.25, 0.1};
    const ShellPrism::Jacobian jacobian = prism.jacobianAt(point);
    const double step = 1e-6;
    for (int axis = 0; axis < 3; ++axis) {
        PrismPoint up = point, down = point;
        double* upValue = axis == 0 ? &up.b1 : axis == 1 ? &up.b2 : &up.depthWorld;
        double* downValue = axis == 0 ? &down.b1 : axis == 1 ? &down.b2 : &down.depthWorld;
        *upValue += step;
        *downValue -= step;
        const glm::dvec3 difference = (prism.worldAt(up) - prism.worldAt(down)) / (2.0 * step);
        EXPECT_NEAR(glm::length(difference - jacobian.column[axis]), 0.0, 1e-8) << axis;
    }
    // solve and solveTransposed invert J and its transpose.
    const glm::dvec3 v(0.3, -1.2, 0.7);
    const glm::dvec3 x = jacobian.solve(v);
    const glm::dvec3 back =
        x.x * jacobian.column[0] + x.y * jacobian.column[1] + x.z * jacobian.column[2];
    EXPECT_NEAR(glm::length(back - v), 0.0, 1e-12);
    const glm::dvec3 y = jacobian.solveTransposed(v);
    EXPECT_NEAR(glm::dot(y, jacobian.column[0]), v.x, 1e-12);
    EXPECT_NEAR(glm::dot(y, jacobian.column[1]), v.y, 1e-12);
    EXPECT_NEAR(glm::dot(y, jacobian.column[2]), v.z, 1e-12);
}

TEST(ShellMap, DeterminantIsTheJacobiansToTheBit) {
    // foldDepthWorld reads determinantAt: the same number as the whole Jacobian's, so the folds
    // it reports are the ones the march's Jacobians have.
    const ShellPrism prism = curvedPrism();
    for (double depth : {-0.3, 0.0, 0.1, 2.0, 5.0})
        for (const auto& [b1, b2] : {std::pair{0.0, 0.0}, {0.3, 0.25}, {1.0, 0.0}, {-0.5, 1.5}}) {
            const PrismPoint point{b1, b2, depth};
            EXPECT_EQ(prism.determinantAt(point), prism.jacobianAt(point).determinant)
                << b1 << " " << b2 << " " << depth;
        }
}

TEST(ShellMesh, JoinsTrianglesWhoseSharedCornersDifferByRoundingNoise) {
    // The unit square as triangles 0 1 2 and 4 3 5, whose corners 4 and 5 are 1 and 2 written with
    // rounding noise (as sin(2 pi) = -2.4e-16 puts a cylinder's seam column): one edge, joined.
    BaseMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0},         {0, 1, 0},
                      {1, 1, 0}, {1, -2.4e-16f, 0}, {1e-7f * 0.5f, 1, 0}};
    mesh.uvs = {{0, 0}, {1, 0}, {0, 1}, {1, 1}, {1, 0}, {0, 1}};
    mesh.triangles = {{0, 1, 2}, {4, 3, 5}};
    computeTangentFrames(mesh);
    const ShellMesh shell = buildShellMesh(mesh, {1.0f, 1.0f}, {32, 32, 16}, 0.05);
    EXPECT_EQ(shell.neighbours[0][0], 1u);  // edge 1-2 is edge 5-4
    EXPECT_EQ(shell.neighbourCorners[0][0], 1);
    EXPECT_EQ(shell.neighbours[1][1], 0u);
    EXPECT_EQ(shell.neighbourCorners[1][1], 0);
    EXPECT_EQ(mesh.normals[4], mesh.normals[1]);
}

TEST(ShellMesh, JoinsTrianglesAcrossEdgesUsedOnceEachWayOnly) {
    // The square 0 1 2 3 as triangles 0 1 2 and 0 2 4, vertex 4 a uv seam's copy of 3; a sliver
    // 1 5 2 with 5 a copy of 1 (its side 1-5 has both ends at one position, and edge 1-2 is then
    // used three times); a triangle 6 0 1 that runs along edge 0-1 the same way as triangle 0.
    BaseMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0},    {0, 1, 0},
                      {0, 1, 0}, {1, 0, 0}, {0.5f, -1, 0}};
    mesh.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5f, 1}, {0.5f, 0}, {0.5f, 0.5f}};
    mesh.triangles = {{0, 1, 2}, {0, 2, 4}, {1, 5, 2}, {6, 0, 1}};
    computeTangentFrames(mesh);
    const ShellMesh shell = buildShellMesh(mesh, {1.0f, 1.0f}, {32, 32, 16}, 0.05);
    const std::uint32_t none = ShellPrisms::kNoNeighbour;
    // Edge 0-2, used once each way: triangle 0's side opposite its corner 1 is triangle 1's
    // opposite its corner 2, through the seam.
    EXPECT_EQ(shell.neighbours[0][1], 1u);
    EXPECT_EQ(shell.neighbourCorners[0][1], 2);
    EXPECT_EQ(shell.neighbours[1][2], 0u);
    EXPECT_EQ(shell.neighbourCorners[1][2], 1);
    EXPECT_EQ(shell.neighbours[0][0], none);  // edge 1-2: three sides
    EXPECT_EQ(shell.neighbours[2][0], none);
    EXPECT_EQ(shell.neighbours[2][1], none);
    EXPECT_EQ(shell.neighbours[0][2], none);  // edge 0-1: twice the same way
    EXPECT_EQ(shell.neighbours[3][0], none);
    EXPECT_EQ(shell.neighbours[2][2], none);  // the sliver's side of no length
    EXPECT_EQ(shell.neighbours[1][0], none);  // open borders
    EXPECT_EQ(shell.neighbours[1][1], none);

    // Written into a scene's arrays after 3 other shells: the same prisms, the neighbours
    // numbered from 3, the open sides still open.
    constexpr std::uint32_t kFirst = 3;
    std::vector<ShellPrism> prisms(kFirst + 4);
    std::vector<std::array<std::uint32_t, 3>> neighbours(kFirst + 4);
    std::vector<std::array<std::uint8_t, 3>> corners(kFirst + 4);
    buildShellMeshInto(mesh, {1.0f, 1.0f}, {32, 32, 16}, 0.05, kFirst,
                       std::span(prisms).subspan(kFirst), std::span(neighbours).subspan(kFirst),
                       std::span(corners).subspan(kFirst));
    for (std::size_t t = 0; t < 4; ++t) {
        EXPECT_EQ(prisms[kFirst + t].corner0, shell.prisms[t].corner0);
        EXPECT_EQ(prisms[kFirst + t].normalDelta2, shell.prisms[t].normalDelta2);
        for (int side = 0; side < 3; ++side) {
            const std::uint32_t expected =
                shell.neighbours[t][side] == none ? none : kFirst + shell.neighbours[t][side];
            EXPECT_EQ(neighbours[kFirst + t][side], expected) << t << " " << side;
            if (expected != none) {
                EXPECT_EQ(corners[kFirst + t][side], shell.neighbourCorners[t][side]);
            }
        }
    }
}

TEST(ShellMap, FoldsAtTheSphereCentreAndNeverWhenFlat) {
    // Corners on a sphere of radius 2 with radial normals: every P_i - h N_i reaches the centre
    // at h = 2, where the prism collapses to a point.
    EXPECT_NEAR(curvedPrism().foldDepthWorld(), 2.0, 1e-6);  // float corners
    const glm::vec3 corners[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    const glm::vec3 normals[3] = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
    const glm::vec2 uvs[3] = {{0, 0}, {1, 0}, {0, 1}};
    const ShellPrism flat = ShellPrism::make(corners, normals, uvs, {1, 1}, 16, 16, 8, 0.1);
    EXPECT_TRUE(flat.straight());
    EXPECT_EQ(flat.foldDepthWorld(), std::numeric_limits<double>::infinity());
}

/// Rays from `eye` to points of the mesh's visible side (vertices, edge midpoints, and random
/// points inside triangles), with their expected layer hits.
struct AimedRay {
    Ray ray;
    std::optional<double> expected;
    std::string what;
};

std::vector<AimedRay> raysAt(const BaseMesh& mesh, const glm::vec3& eye, double layerDepth,
                             bool edgesAndVertices) {
    std::vector<AimedRay> rays;
    std::mt19937 random(11);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (std::size_t t = 0; t < mesh.triangles.size(); t += 7) {
        const glm::uvec3 triangle = mesh.triangles[t];
        const glm::vec3 p0 = mesh.positions[triangle[0]], p1 = mesh.positions[triangle[1]],
                        p2 = mesh.positions[triangle[2]];
        if (glm::dot(glm::cross(p1 - p0, p2 - p0), (p0 + p1 + p2) / 3.0f - eye) >= 0.0f)
            continue;  // faces away from the eye
        std::vector<std::pair<glm::vec3, std::string>> targets;
        if (edgesAndVertices) {
            targets = {{p0, "vertex"}, {0.5f * (p0 + p1), "edge"}, {0.5f * (p1 + p2), "edge"}};
        } else {
            float b1 = unit(random), b2 = unit(random);
            if (b1 + b2 > 1.0f) b1 = 1.0f - b1, b2 = 1.0f - b2;
            targets = {{p0 + b1 * (p1 - p0) + b2 * (p2 - p0), "inside"}};
        }
        for (const auto& [target, what] : targets) {
            const Ray ray{eye, glm::normalize(target - eye)};
            // Leave out rays that graze the base (their layer hit is ill-conditioned) or that
            // the base mesh's own other side hides.
            if (std::abs(glm::dot(ray.direction, mesh.normals[triangle[0]])) < 0.5f) continue;
            rays.push_back(
                {ray, layerHit(mesh, ray, layerDepth), what + " of triangle " + std::to_string(t)});
        }
    }
    return rays;
}

/// The largest error (texels along the ray) of the tracer's hits on the layer, over `rays`;
/// every ray with an expected hit must hit the detail.
double largestLayerError(const Scene& scene, const TraceOptions& options,
                         const std::vector<AimedRay>& rays, int& hits) {
    const SceneTracer tracer(scene, options);
    double largest = 0.0;
    hits = 0;
    for (const AimedRay& aimed : rays) {
        SurfaceHit hit;
        TraceCounters counters;
        const bool found = tracer.traceNearest(aimed.ray, 0.0f, hit, counters);
        if (!aimed.expected) continue;
        EXPECT_TRUE(found && hit.onDetail) << aimed.what;
        if (!found || !hit.onDetail) continue;
        ++hits;
        const double errorTexels =
            std::abs(double(hit.distanceWorld) - *aimed.expected) * hit.texelsPerWorldAlongRay;
        largest = std::max(largest, errorTexels);
    }
    return largest;
}

TEST(CurvedShell, HitsTheLayerOfTheShellMapOnASphereAndATorus) {
    // The layer z = 6 of a 16-deep tile lies at depth 0.625 x 0.04 below the base: the
    // offset mesh. The curved march lands on it to within its threshold (1e-4 texel, with float
    // rounding of a ray a few world units long: 2e-3 texels); the planar march, which maps the
    // ray once with the entry's frame, misses it by more on the same rays.
    for (const bool torus : {false, true}) {
        const BaseMesh mesh = torus ? makeTorus(0.8f, 0.3f, 64, 32) : makeUvSphere(0.6f, 48, 24);
        const Scene scene = layerScene(mesh);
        const std::vector<AimedRay> rays =
            raysAt(mesh, {0.4f, -2.5f, 1.7f}, layerDepthWorld(kDepthWorld), false);
        int hits = 0;
        const double curved =
            largestLayerError(scene, preciseOptions(ShellMapping::Curved), rays, hits);
        EXPECT_GT(hits, 50);
        EXPECT_LT(curved, 2e-3) << (torus ? "torus" : "sphere");
        const double planar =
            largestLayerError(scene, preciseOptions(ShellMapping::Planar), rays, hits);
        EXPECT_GT(planar, 0.05) << (torus ? "torus" : "sphere");
    }
}

TEST(CurvedShell, TheMirroredUvVaseCarriesTheLayerOnBothHalves) {
    // data/meshes/vase.obj: a uv seam, and u running backwards over half the vase (mirrored
    // charts, tangent handedness -1). The layer lies at the same depth on both halves, and the
    // march reaches it from either side of the mirror line.
    const BaseMesh mesh = loadBaseMesh(std::string(DISTILE_SOURCE_DIR) + "/data/meshes/vase.obj");
    const Scene scene = layerScene(mesh);
    int mirrored = 0, unmirrored = 0;
    for (const glm::vec3 eye : {glm::vec3(2.2f, -2.6f, 1.9f), glm::vec3(-2.2f, 2.6f, 1.9f)}) {
        const std::vector<AimedRay> rays = raysAt(mesh, eye, layerDepthWorld(kDepthWorld), false);
        int hits = 0;
        EXPECT_LT(largestLayerError(scene, preciseOptions(ShellMapping::Curved), rays, hits), 2e-3);
        EXPECT_GT(hits, 20);
        (eye.y < 0.0f ? mirrored : unmirrored) += hits;  // u runs backwards where y < 0
    }
    EXPECT_GT(mirrored, 20);
    EXPECT_GT(unmirrored, 20);
}

TEST(CurvedShell, DefaultMarchIsWithinItsThresholdOfTheLayer) {
    // The default budget and threshold (0.02 texel): within twice the threshold along rays that
    // meet the base at 60 degrees or steeper (in texel space, steeper still: z is stretched).
    const BaseMesh mesh = makeTorus(0.8f, 0.3f, 64, 32);
    const Scene scene = layerScene(mesh);
    const std::vector<AimedRay> rays =
        raysAt(mesh, {0.4f, -2.5f, 1.7f}, layerDepthWorld(kDepthWorld), false);
    TraceOptions options;
    int hits = 0;
    EXPECT_LT(largestLayerError(scene, options, rays, hits), 0.05);
    EXPECT_GT(hits, 50);
}

TEST(CurvedShell, SecantStepsReachTheLayerInAFewSamples) {
    // The layer is flat in texel space, so along a ray its distance falls nearly linearly and the
    // curved march's secant steps (render/march_wide.h) land on it in a few samples, where sphere
    // steps approach it geometrically. To the precise threshold of 1e-4 texel, measured: 3.78
    // samples per ray, at most 6; with sphere steps alone, 5.07 and at most 7 (these rays are
    // steep in texel space, whose z the shell's depth stretches).
    const BaseMesh mesh = makeTorus(0.8f, 0.3f, 64, 32);
    const Scene scene = layerScene(mesh);
    const SceneTracer tracer(scene, preciseOptions(ShellMapping::Curved));
    int hits = 0;
    std::uint64_t samples = 0, most = 0;
    for (const AimedRay& aimed :
         raysAt(mesh, {0.4f, -2.5f, 1.7f}, layerDepthWorld(kDepthWorld), false)) {
        if (!aimed.expected) continue;
        SurfaceHit hit;
        TraceCounters counters;
        ASSERT_TRUE(tracer.traceNearest(aimed.ray, 0.0f, hit, counters)) << aimed.what;
        ASSERT_TRUE(hit.onDetail) << aimed.what;
        EXPECT_LT(
            std::abs(double(hit.distanceWorld) - *aimed.expected) * hit.texelsPerWorldAlongRay,
            2e-3)
            << aimed.what;
        ++hits;
        samples += counters.marchIterations;
        most = std::max(most, counters.marchIterations);
    }
    ASSERT_GT(hits, 50);
    EXPECT_LT(double(samples) / hits, 4.5);
    EXPECT_LE(most, 6u);
}

TEST(CurvedShell, RaysAtVerticesAndEdgesNeitherLeakNorMissTheLayer) {
    // Rays aimed exactly at base vertices and edge midpoints enter where several prisms meet and
    // must land on the layer like any other ray (a leak would miss it, a double hit would not
    // change the nearest one).
    const BaseMesh mesh = makeUvSphere(0.6f, 48, 24);
    const Scene scene = layerScene(mesh);
    const std::vector<AimedRay> rays =
        raysAt(mesh, {0.3f, -2.2f, 0.9f}, layerDepthWorld(kDepthWorld), true);
    int hits = 0;
    EXPECT_LT(largestLayerError(scene, preciseOptions(ShellMapping::Curved), rays, hits), 2e-3);
    EXPECT_GT(hits, 100);
}

TEST(CurvedShell, RaysThatDoNotReachTheLayerLeaveThroughTheTop) {
    // Rays passing the sphere's centre at a distance between the layer's radius and the base's:
    // they enter the shell and leave it again without reaching the detail. The planar march
    // continues straight under the base and wrongly hits.
    const float radius = 0.6f;
    const BaseMesh mesh = makeUvSphere(radius, 96, 48);
    const Scene scene = layerScene(mesh);
    const double layerRadius = radius - layerDepthWorld(kDepthWorld);
    const double sag = radius * (1.0 - std::cos(3.14159265 / 48.0));  // chord below the sphere
    const double pass = 0.5 * (layerRadius + radius - sag);
    int curvedMisses = 0, planarHits = 0, entered = 0;
    const SceneTracer curved(scene, TraceOptions{});
    TraceOptions planarOptions;
    planarOptions.shellMapping = ShellMapping::Planar;
    const SceneTracer planar(scene, planarOptions);
    for (int k = 0; k < 40; ++k) {
        const double angle = 2.0 * 3.14159265 * (k + 0.5) / 40.0;
        const glm::dvec3 side(std::cos(angle), 0.0, std::sin(angle));
        const Ray ray{glm::vec3(side * pass + glm::dvec3(0.0, -3.0, 0.0)), {0.0f, 1.0f, 0.0f}};
        if (!layerHit(mesh, ray, 0.0)) continue;  // misses the base mesh itself
        ++entered;
        EXPECT_FALSE(layerHit(mesh, ray, layerDepthWorld(kDepthWorld)));
        SurfaceHit hit;
        TraceCounters counters;
        if (!curved.traceNearest(ray, 0.0f, hit, counters) || !hit.onDetail) ++curvedMisses;
        if (planar.traceNearest(ray, 0.0f, hit, counters) && hit.onDetail) ++planarHits;
    }
    EXPECT_GT(entered, 30);
    EXPECT_EQ(curvedMisses, entered);
    EXPECT_GT(planarHits, entered / 2);
}

TEST(CurvedShell, MirroredUvsMirrorTheDetailAndItsNormals) {
    // A gently bent strip whose right half has its u running backwards (mirrored), under a ramp
    // tile (detail z = 4 + x). On both halves the hit lies on the ramp as the shell map
    // places it, and the normal J^T grad d is the ramp's world normal, mirrored on the right.
    BaseMesh mesh;
    const int columns = 8;
    for (int column = 0; column <= columns; ++column) {
        const float x = -1.0f + 2.0f * float(column) / columns;
        const float u =
            column <= columns / 2 ? float(column) / columns : float(columns - column) / columns;
        for (int row = 0; row < 2; ++row) {
            mesh.positions.push_back({x, row == 0 ? -0.5f : 0.5f, -0.1f * x * x});
            mesh.uvs.push_back({u, float(row)});
        }
    }
    for (int column = 0; column < columns; ++column) {
        const unsigned a = 2 * column, b = a + 2;
        mesh.triangles.push_back({a, b, b + 1});
        mesh.triangles.push_back({a, b + 1, a + 1});
    }
    computeTangentFrames(mesh);
    Tile ramp({32, 32, 16});
    const double slope = 1.0;
    const double norm = std::sqrt(1.0 + slope * slope);
    for (int z = 0; z < 16; ++z)
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 32; ++x)
                ramp.at(x, y, z) = float(((z + 0.5) - 4.0 - slope * (x + 0.5)) / norm);
    Scene scene;
    SceneObject object;
    object.mesh = mesh;
    object.material.tile = std::make_shared<const Tile>(std::move(ramp));
    object.material.uvScale = {1.0f, 1.0f};
    object.material.depthWorld = 0.05f;
    scene.objects.push_back(std::move(object));
    const SceneTracer tracer(scene, preciseOptions(ShellMapping::Curved));
    const ShellMesh prisms = buildShellMesh(mesh, {1.0f, 1.0f}, {32, 32, 16}, 0.05);
    int checked = 0;
    for (const float x : {-0.6f, -0.35f, 0.35f, 0.6f}) {  // u in [0.2, 0.33]: inside one tile
        const Ray ray{{x, 0.05f, 2.0f}, {0.0f, 0.0f, -1.0f}};
        SurfaceHit hit;
        TraceCounters counters;
        ASSERT_TRUE(tracer.traceNearest(ray, 0.0f, hit, counters)) << x;
        ASSERT_TRUE(hit.onDetail) << x;
        // Where the hit is in its prism, through the map: on the ramp.
        std::uint32_t shell = 0;
        for (; shell < mesh.triangles.size(); ++shell) {
            glm::vec3 top[3], bottom[3];
            tracer.shellCorners(shell, top, bottom);
            if (top[0].x <= x && x <= top[1].x && (top[0].x < top[1].x)) break;
        }
        ASSERT_LT(shell, mesh.triangles.size());
        const ShellPrism& prism = prisms.prisms[shell];
        PrismPoint point{1.0 / 3.0, 1.0 / 3.0, 0.0};
        ShellPrism::Jacobian jacobian;
        ASSERT_TRUE(prism.invert(glm::dvec3(hit.position) - prism.corner0, point, jacobian));
        ASSERT_TRUE(prism.invert(glm::dvec3(hit.position) - prism.corner0, point, jacobian));
        const glm::dvec3 texel = prism.texelAt(point);
        EXPECT_NEAR(texel.z, 4.0 + slope * texel.x, 2e-3) << x;
        // The ramp's world normal: the map's Jacobian there, applied to the texel-space normal.
        const glm::dvec3 gradient(-slope, 0.0, 1.0);
        const glm::dvec3 expected = glm::normalize(
            prism.jacobianAt(point).solveTransposed(prism.texelGradientToPrism(gradient)));
        EXPECT_GT(glm::dot(glm::dvec3(hit.normal), expected), std::cos(0.5 * 3.14159265 / 180))
            << x;
        // Mirrored: the ramp rises toward +u, which is +x on the left and -x on the right, so
        // the normal leans against it, away from the base's normal.
        const float lean = hit.normal.x - hit.entry.normal.x;
        EXPECT_LT(lean * (x < 0.0f ? 1.0f : -1.0f), -0.02f) << x;
        ++checked;
    }
    EXPECT_EQ(checked, 4);
}

TEST(CurvedShell, AFoldingShellIsReportedOnceAndRendersFinitePixels) {
    // A torus tube of radius 0.1 under a shell 0.15 deep: the shell folds at the tube's
    // centre line (depth 0.1, a little less on the tessellated tube).
    Scene scene = layerScene(makeTorus(0.5f, 0.1f, 48, 24), 0.15f);
    scene.camera = {{0.0f, -1.6f, 1.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 45.0f};
    {
        const SceneTracer tracer(scene, TraceOptions{});
        ASSERT_EQ(tracer.warnings().size(), 1u);
        const std::string& warning = tracer.warnings()[0];
        EXPECT_NE(warning.find("objects[0]"), std::string::npos) << warning;
        const std::size_t at = warning.find("does not fold is ");
        ASSERT_NE(at, std::string::npos) << warning;
        const double safe = std::stod(warning.substr(at + 17));
        EXPECT_NEAR(safe, 0.1, 0.005) << warning;
    }
    RenderOptions options;
    options.width = 64;
    options.height = 48;
    const RenderResult result = renderScene(scene, options);
    EXPECT_EQ(result.warnings.size(), 1u);
    for (const glm::vec3& pixel : result.image.rgbLinear)
        ASSERT_TRUE(std::isfinite(pixel.x) && std::isfinite(pixel.y) && std::isfinite(pixel.z));
    // A shell shallower than the tube's radius does not fold.
    const Scene shallow = layerScene(makeTorus(0.5f, 0.1f, 48, 24), 0.05f);
    EXPECT_TRUE(SceneTracer(shallow, TraceOptions{}).warnings().empty());
}

TEST(CurvedShell, AMeshWoundClockwiseIsReported) {
    // The same sphere twice: wound as files should be (counter-clockwise seen from outside), no
    // warning; flipped, every camera ray that reaches it meets a back face, and the render says
    // so, naming the object.
    RenderOptions options;
    options.width = 48;
    options.height = 36;
    Scene scene = layerScene(makeUvSphere(0.6f, 32, 16));
    scene.camera = {{0.0f, -2.5f, 0.8f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    EXPECT_TRUE(renderScene(scene, options).warnings.empty());

    for (glm::uvec3& triangle : scene.objects[0].mesh.triangles)
        std::swap(triangle[1], triangle[2]);
    computeTangentFrames(scene.objects[0].mesh);
    const RenderResult flipped = renderScene(scene, options);
    ASSERT_EQ(flipped.warnings.size(), 1u);
    EXPECT_NE(flipped.warnings[0].find("objects[0]: 100% of the camera rays"), std::string::npos)
        << flipped.warnings[0];
    EXPECT_NE(flipped.warnings[0].find("clockwise"), std::string::npos);
}

TEST(CurvedShell, AnOpenFloorSeenThroughIsNoSignOfAMeshWoundClockwise) {
    // A sphere with an open floor and sparse detail (a post of radius 2 texels in each 32 x 32
    // tile): most camera rays pass between the posts and stop on the inside of the far side, a
    // back face met after the front of the same sphere. That is no sign of a mesh wound inside
    // out: no warning. Flipped, the rays meet back faces first, and it is reported.
    Tile posts({32, 32, 16});
    for (int z = 0; z < 16; ++z)
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 32; ++x)
                posts.at(x, y, z) = std::hypot(x + 0.5f - 16.0f, y + 0.5f - 16.0f) - 2.0f;
    Scene scene = layerScene(makeUvSphere(0.6f, 32, 16));
    scene.objects[0].material.tile = std::make_shared<const Tile>(std::move(posts));
    scene.objects[0].material.floor = Floor::Open;
    scene.camera = {{0.0f, -2.5f, 0.8f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    RenderOptions options;
    options.width = 48;
    options.height = 36;
    options.shadowFilter = ShadowFilter::None;
    const RenderResult open = renderScene(scene, options);
    EXPECT_TRUE(open.warnings.empty()) << open.warnings.front();
    // The rays did stop on the inside: the back faces are there to be miscounted.
    std::size_t insideStops = 0;
    for (const glm::vec3& pixel : open.image.rgbLinear)
        insideStops += pixel == backFaceColor(scene.objects[0].material.color);
    EXPECT_GT(insideStops, open.image.rgbLinear.size() / 8);

    for (glm::uvec3& triangle : scene.objects[0].mesh.triangles)
        std::swap(triangle[1], triangle[2]);
    computeTangentFrames(scene.objects[0].mesh);
    const RenderResult flipped = renderScene(scene, options);
    ASSERT_EQ(flipped.warnings.size(), 1u);
    EXPECT_NE(flipped.warnings[0].find("objects[0]:"), std::string::npos) << flipped.warnings[0];
    EXPECT_NE(flipped.warnings[0].find("clockwise"), std::string::npos);
}

TEST(CurvedShell, TheMeshWoundClockwiseIsNamedAmongOthers) {
    // Two spheres side by side, the right one flipped: about half the camera rays that reach
    // a sphere reach each, so the counts of the two objects alternate along every row. Only the
    // flipped one is named, with all its rays on back faces.
    RenderOptions options;
    options.width = 64;
    options.height = 32;
    Scene scene = layerScene(makeUvSphere(0.5f, 32, 16));
    scene.objects.push_back(scene.objects[0]);
    for (int object = 0; object < 2; ++object) {
        BaseMesh& mesh = scene.objects[std::size_t(object)].mesh;
        for (glm::vec3& position : mesh.positions) position.x += object == 0 ? -0.6f : 0.6f;
        if (object == 1) {
            for (glm::uvec3& triangle : mesh.triangles) std::swap(triangle[1], triangle[2]);
        }
        computeTangentFrames(mesh);
    }
    scene.camera = {{0.0f, -3.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 45.0f};
    const RenderResult render = renderScene(scene, options);
    ASSERT_EQ(render.warnings.size(), 1u);
    EXPECT_NE(render.warnings[0].find("objects[1]: 100% of the camera rays"), std::string::npos)
        << render.warnings[0];
}

TEST(CurvedShell, RenderIsTheSameForOneAndTwoThreadsAndBatched) {
    Scene scene = layerScene(makeTorus(0.5f, 0.2f, 48, 24));
    scene.camera = {{0.0f, -1.5f, 1.1f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 45.0f};
    RenderOptions options;
    options.width = 80;
    options.height = 60;
    options.outputAovs = true;
    const RenderResult one = onThreads(1, [&] { return renderScene(scene, options); });
    const RenderResult two = onThreads(2, [&] { return renderScene(scene, options); });
    EXPECT_EQ(one.image.rgbLinear, two.image.rgbLinear);
    EXPECT_EQ(one.aovs->depth.rgbLinear, two.aovs->depth.rgbLinear);
    EXPECT_GT(one.stats.baseHits, 1000u);
    // Shadow-map rays (traceNearestBatch) give each ray what it gives alone.
    const SceneTracer tracer(scene, TraceOptions{});
    std::vector<Ray> rays;
    for (int k = 0; k < 64; ++k)
        rays.push_back(
            {{-0.7f + 0.022f * k, -1.0f, 0.5f}, glm::normalize(glm::vec3(0.1f, 1.0f, -0.6f))});
    std::vector<SurfaceHit> hits(rays.size());
    bool found[SceneTracer::kMaxBatchRays] = {};
    TraceCounters counters;
    tracer.traceNearestBatch(rays, 0.0f, hits, std::span<bool>(found, rays.size()), counters);
    int onDetail = 0;
    for (std::size_t k = 0; k < rays.size(); ++k) {
        SurfaceHit hit;
        TraceCounters single;
        ASSERT_EQ(tracer.traceNearest(rays[k], 0.0f, hit, single), found[k]) << k;
        if (!found[k]) continue;
        EXPECT_EQ(hit.distanceWorld, hits[k].distanceWorld) << k;
        EXPECT_EQ(hit.normal, hits[k].normal) << k;
        onDetail += hit.onDetail;
    }
    EXPECT_GT(onDetail, 10);
}

TEST(CurvedShell, FlatBasesRenderAsWithThePlanarMarch) {
    // Flat faces take the planar march whatever the mapping: the same image.
    Scene scene = layerScene(makePlane(2.0f, 4));
    scene.camera = {{0.3f, -1.6f, 1.2f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    RenderOptions options;
    options.width = 64;
    options.height = 48;
    const RenderResult curved = renderScene(scene, options);
    options.shellMapping = ShellMapping::Planar;
    const RenderResult planar = renderScene(scene, options);
    EXPECT_EQ(curved.image.rgbLinear, planar.image.rgbLinear);
}

}  // namespace
}  // namespace distile
