#include "bench/stress/stress_cases.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <exception>
#include <functional>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>

#include "bake/bake.h"
#include "common/error.h"
#include "mesh/base_mesh.h"
#include "render/march.h"
#include "render/renderer.h"
#include "render/tracer.h"
#include "sampler/filters.h"
#include "sampler/tile_columns.h"
#include "vdb/chainmail.h"

namespace distile {
namespace {

constexpr double kPi = 3.14159265358979323846;

/// printf into a std::string (the report lines).
__attribute__((format(printf, 1, 2))) std::string formatLine(const char* pattern, ...) {
    char line[512];
    va_list arguments;
    va_start(arguments, pattern);
    std::vsnprintf(line, sizeof line, pattern, arguments);
    va_end(arguments);
    return line;
}

/// Collects a case's checks and decides `passed`.
class CaseRecord {
  public:
    CaseRecord(std::string name, std::string expected) {
        case_.name = std::move(name);
        case_.expected = std::move(expected);
    }
    StressCase& result() { return case_; }
    void check(bool held, std::string what) { case_.checks.push_back({std::move(what), held}); }
    StressCase finish() {
        case_.passed = std::isfinite(case_.errorTexels) &&
                       case_.errorTexels <= case_.toleranceTexels && case_.nonFinitePixels == 0 &&
                       std::all_of(case_.checks.begin(), case_.checks.end(),
                                   [](const StressCheck& c) { return c.held; });
        return std::move(case_);
    }

  private:
    StressCase case_;
};

/// A tile whose detail is the horizontal plane z = heightTexels (solid below): exact distances,
/// reproduced exactly by trilinear filtering over the whole slab (the edge cells extend linearly
/// to z = 0 and z = D).
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
constexpr double kTexelsPerWorldXY = 32.0;
/// A plane wide enough that the grazing rays and the deep shells' rays reach the detail before
/// its edge, where a ray leaves the shell: at 0.1 degree a ray crosses 4 texels of height over
/// 2300 texels (72 world units), and a shell 100 units deep sends the camera's rays about 150
/// units sideways.
constexpr float kWidePlaneSize = 512.0f;

/// The plane scene with a plane of side `sizeWorld`, the texel density kept (32 per world unit).
Scene planeScene(std::shared_ptr<const Tile> tile, float depthWorld = kCubeDepth,
                 float sizeWorld = kPlaneSize) {
    Scene scene;
    scene.camera = {{0.3f, -1.6f, 1.2f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    SceneObject plane;
    plane.mesh = makePlane(sizeWorld, 1);
    plane.material.tile = std::move(tile);
    const float uvScale = kUvScale * sizeWorld / kPlaneSize;
    plane.material.uvScale = {uvScale, uvScale};
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

bool isFiniteHit(const SurfaceHit& hit) {
    return isFinite(hit.position) && isFinite(hit.normal) && std::isfinite(hit.distanceWorld);
}

std::uint64_t nonFinitePixels(const Image& image) {
    return std::uint64_t(std::count_if(image.rgbLinear.begin(), image.rgbLinear.end(),
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

/// A ray of elevation `elevationDeg` below the horizon and azimuth `azimuthDeg` that crosses the
/// plane z = 0 at `target` after starting 0.3 world units above it.
Ray grazingRay(double elevationDeg, double azimuthDeg, const glm::vec3& target) {
    const double elevation = elevationDeg * kPi / 180.0;
    const double azimuth = azimuthDeg * kPi / 180.0;
    const glm::vec3 direction(float(std::cos(elevation) * std::cos(azimuth)),
                              float(std::cos(elevation) * std::sin(azimuth)),
                              float(-std::sin(elevation)));
    return {target - direction * (0.3f / -direction.z), glm::normalize(direction)};
}

// The flat detail plane of the grazing and depth cases: z = 4 in a tile 8 texels deep.
constexpr int kFlatDepth = 8;
constexpr float kFlatHeight = 4.0f;

void grazingSphereTracingCases(std::vector<StressCase>& cases) {
    // Truth: the detail is the plane z = h in texel space. Sphere tracing towards an exact plane
    // at elevation a leaves the height above it at (D - h) (1 - sin a)^n after n steps (the
    // filter extends the top cell linearly, so the field is exact up to z = D), so with 16
    // iterations grazing rays stop short of the plane: never below it, at the predicted height
    // above it. With a budget large enough (4096) they all converge within epsilon.
    const Scene scene = planeScene(flatTile({32, 32, kFlatDepth}, kFlatHeight),
                                   kCubeDepth * kFlatDepth / 16.0f, kWidePlaneSize);
    const double texelsPerWorldZ = kFlatDepth / scene.objects[0].material.depthWorld;
    const double planeWorldZ = -(kFlatDepth - kFlatHeight) / texelsPerWorldZ;
    for (int budget : {16, 4096}) {
        TraceOptions traceOptions;
        traceOptions.march.method = MarchMethod::SphereTracing;
        traceOptions.march.maxIterations = budget;
        // Ch. 8's march from the top face, as predicted: no empty-space skipping, which would
        // start the rays just above the plane.
        traceOptions.skips.emptySpace = false;
        const double epsilon = traceOptions.march.epsilonTexels;
        const SceneTracer tracer(scene, traceOptions);
        for (double elevationDeg : {0.1, 0.5, 1.0, 2.0, 5.0}) {
            // The march on the exact plane, in double: the known answer for this budget.
            const double sine = std::sin(elevationDeg * kPi / 180.0);
            double predicted = kFlatDepth;  // texel z after the predicted steps
            bool predictedConverged = false;
            for (int step = 0; step < budget; ++step) {
                const double distance = predicted - kFlatHeight;
                if (distance < epsilon) {
                    predictedConverged = true;
                    break;
                }
                predicted -= distance * sine;
            }
            const double predictedError = predicted - kFlatHeight;
            CaseRecord record(
                formatLine("grazing rays %.1f deg, sphere tracing %d steps", elevationDeg, budget),
                budget == 16
                    ? "Stops short of the flat detail plane, never below it, at the height "
                      "above it that sphere tracing an exact plane predicts."
                    : "Converges on the flat detail plane within epsilon, never below "
                      "it, as sphere tracing an exact plane predicts.");
            int rays = 0, hits = 0, converged = 0, convergedAsPredicted = 0;
            double minError = std::numeric_limits<double>::infinity();
            double maxError = 0.0, sumError = 0.0, maxPredictionGap = 0.0, maxWorldGapExcess = -1.0;
            for (double azimuthDeg : {0.0, 37.0, 90.0, 161.0, 250.0, 313.0}) {
                for (float offset : {-0.41f, 0.07f, 0.33f}) {
                    ++rays;
                    SurfaceHit hit;
                    TraceCounters counters;
                    const Ray ray =
                        grazingRay(elevationDeg, azimuthDeg, {offset, -0.5f * offset, 0.0f});
                    if (!tracer.traceNearest(ray, 0.0f, hit, counters) || !hit.onDetail) continue;
                    if (!isFiniteHit(hit)) {
                        ++record.result().nonFinitePixels;
                        continue;
                    }
                    ++hits;
                    // Two measures of the same error: the march's own texel z, and the world hit
                    // (depth along the ray) mapped back to texels. They agree within float
                    // rounding of a few texels' travel over a 0.3-unit ray (1e-3 texel).
                    const double marchError = hit.march.texelPosition.z - kFlatHeight;
                    const double worldError =
                        (double(hit.position.z) - planeWorldZ) * texelsPerWorldZ;
                    maxWorldGapExcess =
                        std::max(maxWorldGapExcess, std::abs(worldError - marchError) -
                                                        (1e-3 + 1e-5 * hit.march.travelTexels));
                    maxPredictionGap =
                        std::max(maxPredictionGap, std::abs(marchError - predictedError));
                    converged += hit.march.converged ? 1 : 0;
                    convergedAsPredicted += hit.march.converged == predictedConverged ? 1 : 0;
                    minError = std::min(minError, marchError);
                    maxError = std::max(maxError, std::abs(marchError));
                    sumError += std::abs(marchError);
                }
            }
            StressCase& result = record.result();
            // Float rounding over 16 steps of at most 4 texels, or thousands of small ones: 1e-3.
            result.errorTexels = maxPredictionGap;
            result.toleranceTexels = 1e-3;
            result.measured = formatLine(
                "hit error mean %.4f max %.4f texels (predicted %.4f), converged %d/%d, "
                "max gap to the prediction %.2g texel",
                hits ? sumError / hits : 0.0, maxError, predictedError, converged, rays,
                maxPredictionGap);
            record.check(hits == rays,
                         formatLine("every ray hit the detail: %d of %d", hits, rays));
            record.check(hits == 0 || minError >= -1e-4,
                         formatLine("never below the plane: min hit error %.2g >= -1e-4 texel",
                                    hits ? minError : 0.0));
            record.check(maxWorldGapExcess <= 0.0,
                         formatLine("world hit agrees with the march within 1e-3 + 1e-5 x travel "
                                    "texels (excess %.2g)",
                                    maxWorldGapExcess));
            record.check(convergedAsPredicted == hits,
                         formatLine("converged as predicted (%s): %d of %d",
                                    predictedConverged ? "yes" : "no", convergedAsPredicted, hits));
            if (budget != 16) {
                record.check(converged == rays,
                             formatLine("every ray converged: %d of %d", converged, rays));
                // The renderer samples the tile's 16-bit columns, rounded down by up to one
                // code step (sampler/tile_columns.h): a hit may stop that much further above.
                const double step = TileColumns(*scene.objects[0].material.tile).texelsPerCode();
                record.check(maxError <= epsilon + step,
                             formatLine("hit error %.3g <= epsilon %.2g + code step %.2g texel",
                                        maxError, epsilon, step));
            }
            cases.push_back(record.finish());
        }
    }
}

void grazingBudgetedCases(std::vector<StressCase>& cases) {
    // The default march (budgeted) on the grazing rays: every step is at least the path left to
    // the floor over the samples left, so the ray crosses the plane z = h within the default
    // budget, and regula falsi on the plane's linear distance (exact up to z = D) lands on it:
    // converged, within epsilon, never further below it.
    const Scene scene = planeScene(flatTile({32, 32, kFlatDepth}, kFlatHeight),
                                   kCubeDepth * kFlatDepth / 16.0f, kWidePlaneSize);
    const TraceOptions traceOptions;
    const SceneTracer tracer(scene, traceOptions);
    const double epsilon = traceOptions.march.epsilonTexels;
    const int budget = traceOptions.march.maxIterations;
    for (double elevationDeg : {0.1, 0.5, 1.0, 2.0, 5.0, 30.0}) {
        CaseRecord record(
            formatLine("grazing rays %.1f deg, budgeted march %d samples", elevationDeg, budget),
            formatLine("The default march converges on the flat detail plane within epsilon in %d "
                       "samples, never on the floor.",
                       budget));
        int rays = 0, hits = 0, converged = 0, onFloor = 0, maxIterations = 0;
        double maxError = 0.0;
        for (double azimuthDeg : {0.0, 37.0, 90.0, 161.0, 250.0, 313.0}) {
            ++rays;
            SurfaceHit hit;
            TraceCounters counters;
            const Ray ray = grazingRay(elevationDeg, azimuthDeg, glm::vec3(0.0f));
            if (!tracer.traceNearest(ray, 0.0f, hit, counters) || !hit.onDetail) continue;
            if (!isFiniteHit(hit)) {
                ++record.result().nonFinitePixels;
                continue;
            }
            ++hits;
            converged += hit.march.converged ? 1 : 0;
            onFloor += hit.march.onFloor ? 1 : 0;
            maxIterations = std::max(maxIterations, hit.march.iterations);
            maxError =
                std::max(maxError, std::abs(double(hit.march.texelPosition.z) - kFlatHeight));
        }
        StressCase& result = record.result();
        result.errorTexels = maxError;
        // Float rounding of a secant over a path of up to 2300 texels (0.1 degree): 1e-3.
        result.toleranceTexels = epsilon + 1e-3;
        result.measured =
            formatLine("max hit error %.2g texels, converged %d/%d, at most %d samples", maxError,
                       converged, rays, maxIterations);
        record.check(traceOptions.march.method == MarchMethod::Budgeted,
                     "the default march is budgeted");
        record.check(hits == rays, formatLine("every ray hit the detail: %d of %d", hits, rays));
        record.check(converged == rays,
                     formatLine("every ray converged: %d of %d", converged, rays));
        record.check(onFloor == 0, formatLine("no ray ended on the floor: %d did", onFloor));
        record.check(maxIterations <= budget,
                     formatLine("at most %d samples: %d", budget, maxIterations));
        cases.push_back(record.finish());
    }
}

/// Traces 200 rays from the plane scene's eye at both scenes and renders both: `far` is `near`
/// with its uvs placed so that the tile's repeats fall on the same world points, so the truth is
/// the same image. The error is the largest distance between the two hits of a ray, texels.
void expectSameAsNearPlane(CaseRecord& record, const Scene& near, const Scene& far) {
    const SceneTracer nearTracer(near, TraceOptions{});
    const SceneTracer farTracer(far, TraceOptions{});
    double maxTexelError = 0.0;
    int rays = 0, alike = 0, compared = 0;
    for (int i = 0; i < 200; ++i) {
        const glm::vec3 target(-0.9f + 1.8f * float(i % 20) / 19.0f,
                               -0.9f + 1.8f * float(i / 20) / 9.0f, 0.0f);
        const glm::vec3 eye(0.3f, -1.6f, 1.2f);
        const Ray ray{eye, glm::normalize(target - eye)};
        SurfaceHit nearHit, farHit;
        TraceCounters counters;
        ++rays;
        // A ray that reaches the plane's edge before the detail leaves both shells there.
        const bool nearFound = nearTracer.traceNearest(ray, 0.0f, nearHit, counters);
        const bool farFound = farTracer.traceNearest(ray, 0.0f, farHit, counters);
        alike += nearFound == farFound ? 1 : 0;
        if (!nearFound || !farFound) continue;
        if (!isFiniteHit(farHit)) {
            ++record.result().nonFinitePixels;
            continue;
        }
        if (!nearHit.onDetail || !farHit.onDetail || nearHit.march.onFloor != farHit.march.onFloor)
            continue;
        maxTexelError =
            std::max(maxTexelError,
                     double(glm::length(farHit.position - nearHit.position)) * kTexelsPerWorldXY);
        ++compared;
    }
    const RenderOptions options = smallOptions();
    const RenderResult nearImage = renderScene(near, options);
    const RenderResult farImage = renderScene(far, options);
    const ImageDifference difference = compareImages(nearImage.image, farImage.image);
    StressCase& result = record.result();
    result.nonFinitePixels += nonFinitePixels(farImage.image);
    result.errorTexels = maxTexelError;
    // 1e-3 texel: well above the rounding of the wrapped texel position (about 1e-5), well below
    // the 0.13 texel of a float interpolation at 1e4.
    result.toleranceTexels = 1e-3;
    result.measured = formatLine(
        "hit error max %.2g texels over %d rays; image mean |diff| %.5f, max %.4f, share > 0.05: "
        "%.4f",
        maxTexelError, compared, difference.meanAbs, difference.maxAbs, difference.shareOver);
    record.check(alike == rays,
                 formatLine("every ray hit both planes or left both: %d of %d", alike, rays));
    record.check(compared > 120, formatLine("more than 120 detail hits compared: %d", compared));
    // Hits 1e-5 texel apart shade alike: no pixel may differ visibly.
    record.check(difference.meanAbs < 1e-4,
                 formatLine("image mean |diff| %.2g < 1e-4", difference.meanAbs));
    record.check(
        difference.shareOver == 0.0,
        formatLine("no pixel differs by more than 0.05: share %.4f", difference.shareOver));
}

void farUvCase(std::vector<StressCase>& cases) {
    // The same plane with every uv moved by a whole 1e4 (2e4 tile repeats at uv scale 2): the
    // tile is periodic, so the truth is the same image. Float uvs near 1e4 have an ulp of 2^-10
    // (0.06 texel at 64 texels per uv unit): interpolated in float, the entry point moved by up to
    // 0.13 texel; the tracer interpolates and wraps the uv in double, so the hits agree to float
    // rounding of the wrapped texel position (about 1e-5 texel).
    CaseRecord record("uvs far from the origin (+1e4)",
                      "Renders like the same uvs near the origin (the tile is periodic): the same "
                      "hits to float rounding, no visible pixel change.");
    const std::shared_ptr<const Tile> tile = wavyTile();
    Scene far = planeScene(tile);
    for (glm::vec2& uv : far.objects[0].mesh.uvs) uv += glm::vec2(1e4f, 1e4f);
    computeTangentFrames(far.objects[0].mesh);
    expectSameAsNearPlane(record, planeScene(tile), far);
    cases.push_back(record.finish());
}

void wideTriangleCase(std::vector<StressCase>& cases) {
    // A plane of two triangles 2^20 world units wide against one 16 units wide (wider than the
    // view, so no ray reaches either's edge), at the same texel density (one 32-texel repeat per
    // world unit): each large triangle spans 2^20 repeats (3.4e7 texels), and as both planes'
    // half sides are whole numbers of repeats, the repeats fall on the same world points. A float
    // barycentric weight (ulp 6e-8 near 0.5) times 3.4e7 texels moved the entry by up to 2
    // texels; the tracer keeps the weights in double.
    CaseRecord record("uvs far from the origin across one triangle (2^20 repeats)",
                      "Renders like the small plane: the same hits to float rounding, no visible "
                      "pixel change.");
    const std::shared_ptr<const Tile> tile = wavyTile();
    expectSameAsNearPlane(record, planeScene(tile, kCubeDepth, 16.0f),
                          planeScene(tile, kCubeDepth, float(1 << 20)));
    cases.push_back(record.finish());
}

void farBaseMeshCase(std::vector<StressCase>& cases) {
    // The plane and camera moved by 1e5 on every axis: the truth is the same image. Floats at 1e5
    // resolve 2^-7 = 0.0078 world units (0.25 texel here, a third of a pixel at this distance),
    // so the eye, the mesh and thus each ray move by about that: the depth AOV may differ by a
    // few ulps of 1e5 and pixels may change only along the detail's steep edges.
    CaseRecord record("base mesh far from the world origin (1e5)",
                      "Renders like the same scene at the origin up to float rounding of 1e5 "
                      "(2^-7 world): depth jumps only along steep detail edges.");
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
    const std::size_t pixels = nearImage.aovs->depth.rgbLinear.size();
    StressCase& result = record.result();
    result.nonFinitePixels = nonFinitePixels(farImage.image);
    result.errorTexels = maxDepthError * kTexelsPerWorldXY;
    // A ray moved by ~0.01 units may land on the other side of a detail edge (depth jumps by up to
    // the shell's 0.5 units, 16 texels, there).
    result.toleranceTexels = 0.5 * kTexelsPerWorldXY;
    result.measured = formatLine(
        "depth error max %.4f world (%.2f texels) over %zu pixels; image mean |diff| %.5f, max "
        "%.4f, share > 0.05: %.4f",
        maxDepthError, result.errorTexels, bothHit, difference.meanAbs, difference.maxAbs,
        difference.shareOver);
    record.check(
        bothHit > pixels / 2,
        formatLine("both renders hit more than half the pixels: %zu of %zu", bothHit, pixels));
    // Most pixels differ by float rounding only.
    record.check(difference.meanAbs < 0.02,
                 formatLine("image mean |diff| %.4f < 0.02", difference.meanAbs));
    record.check(difference.shareOver < 0.1,
                 formatLine("share of pixels differing by more than 0.05: %.4f < 0.1",
                            difference.shareOver));
    cases.push_back(record.finish());
}

/// A straight-down ray from (x, y, 1) onto the plane scene.
struct DownwardHit {
    bool traced = false;
    bool finite = false;
    bool onDetail = false;
    double detailErrorTexels = 0.0;  ///< texel z of the hit against the flat detail (onDetail)
    double distanceWorld = 0.0;
};

DownwardHit traceDownward(const SceneTracer& tracer, float x, float y, float heightTexels) {
    SurfaceHit hit;
    TraceCounters counters;
    DownwardHit result;
    result.traced = tracer.traceNearest({{x, y, 1.0f}, {0.0f, 0.0f, -1.0f}}, 0.0f, hit, counters);
    if (!result.traced) return result;
    result.finite = isFiniteHit(hit);
    result.onDetail = hit.onDetail;
    result.distanceWorld = hit.distanceWorld;
    if (hit.onDetail) result.detailErrorTexels = double(hit.march.texelPosition.z) - heightTexels;
    return result;
}

void brokenUvCases(std::vector<StressCase>& cases) {
    // A 2 x 2 plane split into separate triangles: the first quad's uvs are mirrored in u (w = -1),
    // one triangle has all three uvs equal, one has collinear uvs, and two faces have zero area
    // (a repeated corner, three collinear corners).
    CaseRecord mirrored("mirrored uv triangles",
                        "Left-handed tangent frames (w = -1) that still carry the detail: a "
                        "straight-down ray lands on the flat detail plane within epsilon.");
    CaseRecord degenerate(
        "degenerate uv triangles and zero-area faces",
        "Finite unit tangent frames; UV-degenerate triangles show the bare base surface (no texel "
        "scale to march with), hit exactly; the image is finite.");
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
    // Which triangles lie where: the centroid of each (x, y) decides, not the grid's order.
    std::vector<glm::vec2> centroids;
    for (const glm::uvec3& t : mesh.triangles)
        centroids.push_back(
            glm::vec2(mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]) / 3.0f);
    for (int corner = 0; corner < 3; ++corner) {
        glm::vec2& first = mesh.uvs[mesh.triangles[0][corner]];
        glm::vec2& second = mesh.uvs[mesh.triangles[1][corner]];
        first.x = 1.0f - first.x;  // mirrored
        second.x = 1.0f - second.x;
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
    std::size_t badFrames = 0, badHandedness = 0;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        const glm::vec3 tangent(mesh.tangents[v]);
        const bool finite = isFinite(mesh.normals[v]) && isFinite(tangent);
        if (!finite || std::abs(glm::length(mesh.normals[v]) - 1.0f) > 1e-4f ||
            std::abs(glm::length(tangent) - 1.0f) > 1e-4f)
            ++badFrames;
        if (mesh.tangents[v].w != 1.0f && mesh.tangents[v].w != -1.0f) ++badHandedness;
    }
    const float mirroredHandedness = mesh.tangents[mesh.triangles[0][0]].w;

    Scene scene = planeScene(flatTile({32, 32, kFlatDepth}, kFlatHeight), kCubeDepth / 2.0f);
    scene.objects[0].mesh = mesh;
    const SceneTracer tracer(scene, TraceOptions{});
    const double epsilon = TraceOptions{}.march.epsilonTexels;
    int mirroredOnDetail = 0, degenerateBare = 0, nonFiniteHits = 0;
    double mirroredMaxError = 0.0, mirroredMinError = std::numeric_limits<double>::infinity();
    double bareMaxError = 0.0;  // texels: the bare surface is 1 world unit below the ray origin
    for (std::size_t t = 0; t < 4; ++t) {
        const DownwardHit hit = traceDownward(tracer, centroids[t].x, centroids[t].y, kFlatHeight);
        if (hit.traced && !hit.finite) ++nonFiniteHits;
        if (!hit.traced || !hit.finite) continue;
        if (t < 2 && hit.onDetail) {
            ++mirroredOnDetail;
            mirroredMaxError = std::max(mirroredMaxError, std::abs(hit.detailErrorTexels));
            mirroredMinError = std::min(mirroredMinError, hit.detailErrorTexels);
        } else if (t >= 2 && !hit.onDetail) {
            ++degenerateBare;
            bareMaxError =
                std::max(bareMaxError, std::abs(hit.distanceWorld - 1.0) * kTexelsPerWorldXY);
        }
    }
    const RenderResult render = renderScene(scene, smallOptions());
    const std::uint64_t nonFinite =
        nonFinitePixels(render.image) + nonFinitePixels(render.aovs->normal) + nonFiniteHits;
    const std::string frames = formatLine(
        "tangent frames finite and unit at all %zu vertices: %zu bad, %zu with w not +-1",
        mesh.positions.size(), badFrames, badHandedness);

    StressCase& m = mirrored.result();
    m.nonFinitePixels = nonFinite;
    m.errorTexels = mirroredMaxError;
    // Straight down on an exact plane distance: one exact step, then below epsilon.
    m.toleranceTexels = epsilon;
    m.measured = formatLine("hit error max %.2g texels on the flat detail plane, handedness w = %g",
                            mirroredMaxError, double(mirroredHandedness));
    mirrored.check(
        mirroredOnDetail == 2,
        formatLine("both mirrored triangles carry the detail: %d of 2", mirroredOnDetail));
    mirrored.check(mirroredOnDetail == 0 || mirroredMinError >= -1e-4,
                   formatLine("never below the plane: min hit error %.2g >= -1e-4 texel",
                              mirroredOnDetail ? mirroredMinError : 0.0));
    mirrored.check(
        mirroredHandedness == -1.0f,
        formatLine("the mirrored triangle is left-handed: w = %g", double(mirroredHandedness)));
    cases.push_back(mirrored.finish());

    StressCase& d = degenerate.result();
    d.nonFinitePixels = nonFinite;
    d.errorTexels = bareMaxError;
    // The bare surface's hit in double, stored as a float distance near 1: ulp 1.2e-7 world.
    d.toleranceTexels = 1e-4;
    d.measured = formatLine(
        "bare-surface hit error max %.2g texels; %zu vertices, %zu bad frames; %llu non-finite "
        "pixels",
        bareMaxError, mesh.positions.size(), badFrames, (unsigned long long)nonFinite);
    degenerate.check(badFrames == 0 && badHandedness == 0, frames);
    degenerate.check(
        degenerateBare == 2,
        formatLine("both UV-degenerate triangles show the bare surface: %d of 2", degenerateBare));
    cases.push_back(degenerate.finish());
}

void cameraInsideShellCase(std::vector<StressCase>& cases) {
    // The eye sits inside the detail layer of a plane (a quarter of the depth below its base
    // surface, above the flat detail at half depth), over a bare ground plane 1 unit down. The
    // tracer enters a shell only through the front of its base surface. Known limit, not the
    // truth: the detail plane 0.0625 units below the eye is not seen.
    CaseRecord record("camera inside the shell",
                      "A ray up stops on the bare back face of the base, one down passes the "
                      "detail it started above and reaches the ground; no shell is marched, no "
                      "hang, every pixel finite.");
    const float depthWorld = kCubeDepth / 2.0f;
    Scene scene = planeScene(flatTile({32, 32, kFlatDepth}, kFlatHeight), depthWorld);
    SceneObject ground;
    ground.mesh = makePlane(20.0f, 1);
    applyTransform(ground.mesh, {{0.0f, 0.0f, -1.0f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    scene.objects.push_back(std::move(ground));
    const glm::vec3 eye(0.1f, -0.2f, -0.25f * depthWorld);
    scene.camera = {eye, {1.0f, 0.4f, -0.3f}, {0.0f, 0.0f, 1.0f}, 90.0f};

    const SceneTracer tracer(scene, TraceOptions{});
    SurfaceHit up, down;
    TraceCounters counters;
    const bool upTraced = tracer.traceNearest({eye, {0.0f, 0.0f, 1.0f}}, 0.0f, up, counters);
    const bool downTraced = tracer.traceNearest({eye, {0.0f, 0.0f, -1.0f}}, 0.0f, down, counters);
    // Exact distances 0.0625 and 0.9375.
    const double upError = std::abs(double(up.distanceWorld) - 0.25 * depthWorld);
    const double downError = std::abs(double(down.distanceWorld) - (1.0 - 0.25 * depthWorld));
    const RenderResult render = renderScene(scene, smallOptions());
    StressCase& result = record.result();
    result.nonFinitePixels = nonFinitePixels(render.image);
    result.errorTexels = std::max(upError, downError) * kTexelsPerWorldXY;
    // Float rounding of the double-precision hits: 1e-6 world.
    result.toleranceTexels = 1e-6 * kTexelsPerWorldXY;
    result.measured = formatLine(
        "back-face hit error %.2g, ground hit error %.2g world; %llu rays, %llu base hits, %llu "
        "march steps",
        upError, downError, (unsigned long long)render.stats.rays,
        (unsigned long long)render.stats.baseHits,
        (unsigned long long)render.stats.marchIterations);
    record.check(upTraced && !up.entry.frontFacing && !up.onDetail,
                 "the ray up stops on the bare back face of the base");
    record.check(downTraced && down.object == 1u, "the ray down reaches the ground (object 1)");
    record.check(counters.marchIterations == 0,
                 formatLine("the two rays marched no shell: %llu steps",
                            (unsigned long long)counters.marchIterations));
    // The ground fills the lower half of the image and more.
    record.check(render.stats.baseHits > render.stats.rays / 2,
                 "the render hits a base surface on more than half its rays");
    record.check(render.stats.marchIterations == 0,
                 formatLine("the render marched no shell: %llu steps",
                            (unsigned long long)render.stats.marchIterations));
    cases.push_back(record.finish());
}

void subTexelWireCase(std::vector<StressCase>& cases) {
    // Chain mail with a wire radius of 0.08 texel (0.01 ring spacings of 8 texels) on a
    // 32 x 32 x 8 tile. The bake options only need radii > 0 and rings inside the slab; thin
    // wires are where trilinear overestimation would open holes. The converged share is reported:
    // a sub-texel wire is found only near its centreline.
    CaseRecord record("wires thinner than a texel (0.08 texel)",
                      "The bake accepts them, the conservative tile never overestimates the "
                      "analytic distance beyond rounding, and the render is finite.");
    ChainmailOptions chainmail;
    chainmail.ringsPerRow = 4;
    chainmail.rowsPerTile = 4;
    chainmail.wireRadiusSpacings = 0.01;
    BakeOptions bake;
    bake.size = {32, 32, 8};
    std::unique_ptr<BakeResult> baked;
    try {
        baked = std::make_unique<BakeResult>(bakeChainmail(chainmail, bake));
    } catch (const InputError& error) {
        record.check(false, std::string("the bake accepts the wire: refused: ") + error.what());
        record.result().measured = "not baked";
        cases.push_back(record.finish());
        return;
    }
    const Chainmail truth(chainmail, bake.size);
    double maxOverestimate = -std::numeric_limits<double>::infinity(), maxAbsError = 0.0;
    std::uint64_t nonFiniteTexels = 0;
    const Size3& size = baked->tile.size();
    for (int z = 0; z < size.depth; ++z)
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x) {
                const double exact = truth.signedDistanceTexels({x + 0.5, y + 0.5, z + 0.5});
                const double stored = baked->tile.at(x, y, z);
                if (!std::isfinite(stored)) {
                    ++nonFiniteTexels;
                    continue;
                }
                maxOverestimate = std::max(maxOverestimate, stored - exact);
                maxAbsError = std::max(maxAbsError, std::abs(stored - exact));
            }
    const Scene scene =
        planeScene(std::make_shared<const Tile>(std::move(baked->tile)), kCubeDepth / 2.0f);
    const RenderResult render = renderScene(scene, smallOptions());
    StressCase& result = record.result();
    result.nonFinitePixels = nonFinitePixels(render.image) + nonFiniteTexels;
    // The overestimate (stored - exact, positive when the tile claims more room than there is);
    // the level set is exact to float rounding at these few texels of distance (1e-3 texel).
    result.errorTexels = std::max(0.0, maxOverestimate);
    result.toleranceTexels = 1e-3;
    result.measured = formatLine(
        "tile max overestimate %.2g, max |error| %.4f texels; converged %.3f of %llu hits on the "
        "tile",
        maxOverestimate, maxAbsError, render.stats.convergedShare(),
        (unsigned long long)render.stats.detailHits);
    record.check(true, "the bake accepts the wire");
    cases.push_back(record.finish());
}

void shellDepthCases(std::vector<StressCase>& cases) {
    // One plane carrying the flat detail z = 4 of 8 texels, with shell depths from 1e-4 to 1e2
    // world units (texels 1/32 unit wide and from 1/2500 to 400 times as tall as wide). Deep
    // shells make the texel-space rays grazing, so fewer converge within the budget (reported).
    const double epsilon = TraceOptions{}.march.epsilonTexels;
    for (float depthWorld : {1e-4f, 1e-2f, 1.0f, 1e2f}) {
        CaseRecord record(formatLine("shell depth %g world units", double(depthWorld)),
                          "Straight-down rays (exact steps) land on the flat detail plane within "
                          "epsilon; the image is finite, no hang.");
        const Scene scene =
            planeScene(flatTile({32, 32, kFlatDepth}, kFlatHeight), depthWorld, kWidePlaneSize);
        const SceneTracer tracer(scene, TraceOptions{});
        const DownwardHit hit = traceDownward(tracer, 0.13f, -0.37f, kFlatHeight);
        const RenderResult render = renderScene(scene, smallOptions());
        StressCase& result = record.result();
        result.nonFinitePixels = nonFinitePixels(render.image) + (hit.traced && !hit.finite);
        result.errorTexels = std::abs(hit.detailErrorTexels);
        result.toleranceTexels = epsilon;
        result.measured = formatLine(
            "straight-down hit error %.2g texels; converged %.3f of %llu camera hits on the tile, "
            "%.2f steps each",
            hit.detailErrorTexels, render.stats.convergedShare(),
            (unsigned long long)render.stats.detailHits, render.stats.meanIterations());
        record.check(hit.traced && hit.finite && hit.onDetail,
                     "the straight-down ray hits the detail");
        record.check(hit.detailErrorTexels >= -1e-4,
                     formatLine("never below the plane: hit error %.2g >= -1e-4 texel",
                                hit.detailErrorTexels));
        record.check(render.stats.baseHits > 0, "the camera sees the plane");
        cases.push_back(record.finish());
    }
}

void nanInfRayCase(std::vector<StressCase>& cases) {
    // Rays with NaN or Inf components, straight into the tracer and the march.
    CaseRecord record("NaN and Inf rays",
                      "A miss, or a hit whose distance, position and normal are finite; the "
                      "march rejects NaN/Inf starts and directions at once (no hit claimed).");
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
    for (const Ray& ray : rays) {
        SurfaceHit hit;
        TraceCounters counters;
        if (!tracer.traceNearest(ray, 0.0f, hit, counters))
            ++misses;
        else if (!isFiniteHit(hit))
            ++record.result().nonFinitePixels;
    }
    const TrilinearFilter filter(*scene.objects[0].material.tile);
    const glm::vec3 direction = glm::normalize(glm::vec3(0.3f, 0.1f, -1.0f));
    std::vector<MarchResult> marches;
    for (const glm::vec3& position :
         {glm::vec3(nan, 3.0f, 16.0f), glm::vec3(3.0f, 3.0f, nan), glm::vec3(inf, 3.0f, 16.0f)})
        marches.push_back(march(filter, position, direction, Floor::Solid, 16, 0.02f));
    for (const glm::vec3& badDirection :
         {glm::vec3(nan, 0.0f, -1.0f), glm::vec3(0.0f, 0.0f, nan), glm::vec3(inf, 0.0f, -inf)})
        marches.push_back(
            march(filter, glm::vec3(3.0f, 3.0f, 16.0f), badDirection, Floor::Solid, 16, 0.02f));
    // Rejected at the door: no hit claimed at a NaN position (it used to converge there).
    const auto rejected = std::count_if(marches.begin(), marches.end(), [](const MarchResult& m) {
        return !m.converged && m.iterations == 0;
    });
    StressCase& result = record.result();
    // No valid ray, so no geometric truth: the error figure is 0 by definition; what counts is
    // finiteness (nonFinitePixels counts hits with NaN/Inf values) and the rejections.
    result.errorTexels = 0.0;
    result.toleranceTexels = 0.0;
    result.measured = formatLine(
        "%d of %zu rays missed, %zu hit with finite values; %lld of %zu "
        "marches rejected at once",
        misses, rays.size(),
        rays.size() - std::size_t(misses) - std::size_t(result.nonFinitePixels),
        (long long)rejected, marches.size());
    record.check(rejected == std::ptrdiff_t(marches.size()),
                 formatLine("every NaN/Inf march ends at once, not converged: %lld of %zu",
                            (long long)rejected, marches.size()));
    cases.push_back(record.finish());
}

}  // namespace

std::vector<StressCase> runStressCases() {
    const std::vector<std::pair<const char*, std::function<void(std::vector<StressCase>&)>>>
        families = {{"grazing rays, sphere tracing", grazingSphereTracingCases},
                    {"grazing rays, budgeted march", grazingBudgetedCases},
                    {"uvs far from the origin", farUvCase},
                    {"uvs far from the origin across one triangle", wideTriangleCase},
                    {"base mesh far from the world origin", farBaseMeshCase},
                    {"mirrored and degenerate uvs", brokenUvCases},
                    {"camera inside the shell", cameraInsideShellCase},
                    {"wires thinner than a texel", subTexelWireCase},
                    {"shell depths", shellDepthCases},
                    {"NaN and Inf rays", nanInfRayCase}};
    std::vector<StressCase> cases;
    for (const auto& [family, run] : families) {
        try {
            run(cases);
        } catch (const std::exception& error) {
            StressCase failed;
            failed.name = family;
            failed.expected = "Runs to the end.";
            failed.measured = std::string("threw: ") + error.what();
            failed.checks.push_back({failed.measured, false});
            cases.push_back(std::move(failed));
        }
    }
    return cases;
}

}  // namespace distile
