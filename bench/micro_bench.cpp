// Micro-benchmarks: filter samples and whole sphere-traced marches on the default chain-mail
// tile, and the bake itself. Run: build/bin/micro_bench [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <ctime>
#include <glm/geometric.hpp>
#include <limits>
#include <random>
#include <vector>

#include "bake/bake.h"
#include "render/bvh.h"
#include "render/coverage.h"
#include "render/demo_scene.h"
#include "render/image.h"
#include "render/march.h"
#include "render/renderer.h"
#include "sampler/filters.h"
#include "sampler/tile_columns.h"
#include "sampler/tile_io.h"

namespace distile {
namespace {

const Tile& chainmailTile() {
    static const Tile tile = bakeChainmail(ChainmailOptions{}, BakeOptions{}).tile;
    return tile;
}

/// The trace options a render with `options` uses (march and filter; the rest defaulted).
TraceOptions traceOptionsOf(const RenderOptions& options) {
    TraceOptions trace;
    trace.march = options.march;
    trace.filter = options.filter;
    return trace;
}

const TileColumns& chainmailColumns() {
    static const TileColumns columns(chainmailTile());
    return columns;
}

std::vector<glm::vec3> randomPoints(std::size_t count) {
    std::mt19937 random(11);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<glm::vec3> points(count);
    for (auto& p : points) p = {unit(random) * 256.0f, unit(random) * 256.0f, unit(random) * 16.0f};
    return points;
}

template <class Filter>
void sampleDistance(benchmark::State& state) {
    const Filter filter(chainmailTile());
    const auto points = randomPoints(1 << 16);
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(filter.distanceTexels(points[i++ & 0xffff]));
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(sampleDistance<NearestFilter>);
BENCHMARK(sampleDistance<TrilinearFilter>);

void trilinearGradient(benchmark::State& state) {
    const TrilinearFilter filter(chainmailTile());
    const auto points = randomPoints(1 << 16);
    std::size_t i = 0;
    for (auto _ : state) benchmark::DoNotOptimize(filter.gradient(points[i++ & 0xffff]));
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(trilinearGradient);

/// One march per item from a random entry point at 35 degrees above the tile, the budget given.
void marchChainmail(benchmark::State& state) {
    const TrilinearFilter filter(chainmailTile());
    auto entries = randomPoints(1 << 12);
    for (auto& p : entries) p.z = 16.0f;
    const glm::vec3 direction = glm::normalize(glm::vec3(0.6f, 0.55f, -0.58f));
    const int budget = int(state.range(0));
    std::size_t i = 0;
    std::int64_t iterations = 0;
    for (auto _ : state) {
        const MarchResult result =
            march(filter, entries[i++ & 0xfff], direction, Floor::Solid, budget, 0.02f);
        iterations += result.iterations;
        benchmark::DoNotOptimize(result);
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["iterations/ray"] =
        benchmark::Counter(double(iterations) / double(state.iterations()));
}
BENCHMARK(marchChainmail)->Arg(8)->Arg(16)->Arg(64);

/// The same marches (budgeted, the renderer's default) in batches of 16 rays, one at a time
/// (range 1 = 0) or interleaved (marchInterleaved, range 1 = 1): identical results, the time per
/// ray is what interleaving saves.
void marchChainmailBatch(benchmark::State& state) {
    const BasicTrilinearFilter<ColumnTexels> filter(chainmailColumns());
    auto entries = randomPoints(1 << 12);
    for (auto& p : entries) p.z = 16.0f;
    const glm::vec3 direction = glm::normalize(glm::vec3(0.6f, 0.55f, -0.58f));
    MarchSettings settings;
    settings.maxIterations = int(state.range(0));
    const bool interleaved = state.range(1) != 0;
    constexpr std::size_t kBatch = 16;
    std::size_t i = 0;
    std::int64_t iterations = 0;
    for (auto _ : state) {
        if (interleaved) {
            detail::SphereTraceRay rays[kBatch];
            detail::SphereTraceRay* pointers[kBatch];
            for (std::size_t k = 0; k < kBatch; ++k) {
                rays[k].start(entries[(i + k) & 0xfff], direction, Floor::Solid, settings);
                pointers[k] = &rays[k];
            }
            marchInterleaved(filter, std::span<detail::SphereTraceRay* const>(pointers));
            for (const auto& ray : rays) iterations += ray.result().iterations;
        } else {
            for (std::size_t k = 0; k < kBatch; ++k) {
                const MarchResult result =
                    march(filter, entries[(i + k) & 0xfff], direction, Floor::Solid, settings);
                iterations += result.iterations;
                benchmark::DoNotOptimize(result);
            }
        }
        i += kBatch;
    }
    state.SetItemsProcessed(state.iterations() * kBatch);
    state.counters["iterations/ray"] =
        benchmark::Counter(double(iterations) / double(state.iterations() * kBatch));
}
BENCHMARK(marchChainmailBatch)->Args({16, 0})->Args({16, 1});

void bakeDefaultChainmail(benchmark::State& state) {
    for (auto _ : state)
        benchmark::DoNotOptimize(bakeChainmail(ChainmailOptions{}, BakeOptions{}).tile.size());
}
BENCHMARK(bakeDefaultChainmail)->Unit(benchmark::kMillisecond)->Iterations(2);

/// The hash every tile read checks (distile:hash), over the default 256x256x16 tile (4 MiB).
void tileHashChainmail(benchmark::State& state) {
    const Tile& tile = chainmailTile();
    for (auto _ : state) benchmark::DoNotOptimize(tileHash(tile));
    state.SetBytesProcessed(std::int64_t(state.iterations()) *
                            std::int64_t(tile.distancesTexels().size_bytes()));
}
BENCHMARK(tileHashChainmail)->Unit(benchmark::kMillisecond);

/// CPU seconds used by all threads of this process: steadier than wall time on a shared machine.
double processCpuSeconds() {
    timespec now{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
    return double(now.tv_sec) + 1e-9 * double(now.tv_nsec);
}

/// Ch. 17 acceptance on the demo scene at 640 x 512: one full-filter and one adaptive render per
/// iteration (shadow maps at the default resolution, traced in each render where its lookups
/// reach). Counters: shadow-map samples of each, their ratio, the CPU-time ratio full / adaptive
/// (whole renders, map tiles and camera rays included), the same ratio of the shadow-map
/// filtering alone (each render minus a render without maps, minus its share of a whole map
/// build), and the share of pixels whose 8-bit sRGB values differ by <= 2.
void demoShadowFilters(benchmark::State& state) {
    static const Scene scene = demoScene(std::make_shared<const Tile>(chainmailTile()));
    RenderOptions options;
    options.width = 640;
    options.height = 512;
    double fullSeconds = 0.0, adaptiveSeconds = 0.0, noMapSeconds = 0.0, buildSeconds = 0.0,
           closeShare = 0.0;
    std::uint64_t fullSamples = 0, adaptiveSamples = 0;
    for (auto _ : state) {
        options.shadowFilter = ShadowFilter::Full;
        double start = processCpuSeconds();
        const RenderResult full = renderScene(scene, options);
        fullSeconds += processCpuSeconds() - start;
        options.shadowFilter = ShadowFilter::Adaptive;
        start = processCpuSeconds();
        const RenderResult adaptive = renderScene(scene, options);
        adaptiveSeconds += processCpuSeconds() - start;
        options.shadowFilter = ShadowFilter::None;  // self-shadow rays stay on
        start = processCpuSeconds();
        benchmark::DoNotOptimize(renderScene(scene, options).stats.rays);
        noMapSeconds += processCpuSeconds() - start;
        start = processCpuSeconds();
        const SceneTracer tracer(scene, traceOptionsOf(options));
        const LightShadowMaps maps(tracer, scene.lights[0]);
        const ShadowMap& map = maps[0];  // the demo's objects form one group
        for (int y = 0; y < map.height(); y += ShadowMap::kTileTexels)  // every finest tile
            for (int x = 0; x < map.width(); x += ShadowMap::kTileTexels)
                benchmark::DoNotOptimize(map.depthAt(x, y));
        // A render traces only the tiles its lookups reach, of every level: that many texels at
        // the finest level's cost per texel.
        buildSeconds += (processCpuSeconds() - start) * double(adaptive.stats.shadowMapTexels) /
                        double(std::max<std::uint64_t>(map.tracedTexels(), 1));
        fullSamples = full.stats.shadowMapSamples;
        adaptiveSamples = adaptive.stats.shadowMapSamples;
        std::size_t close = 0;
        for (std::size_t i = 0; i < full.image.rgbLinear.size(); ++i) {
            int difference = 0;
            for (int c = 0; c < 3; ++c) {
                difference =
                    std::max(difference, std::abs(int(srgbCode8(full.image.rgbLinear[i][c])) -
                                                  int(srgbCode8(adaptive.image.rgbLinear[i][c]))));
            }
            close += difference <= 2 ? 1 : 0;
        }
        closeShare = double(close) / double(full.image.rgbLinear.size());
    }
    state.counters["full samples"] = double(fullSamples);
    state.counters["adaptive samples"] = double(adaptiveSamples);
    state.counters["adaptive/full samples"] =
        double(adaptiveSamples) / double(std::max<std::uint64_t>(fullSamples, 1));
    state.counters["full/adaptive time"] = fullSeconds / adaptiveSeconds;
    state.counters["full/adaptive filter time"] = (fullSeconds - noMapSeconds - buildSeconds) /
                                                  (adaptiveSeconds - noMapSeconds - buildSeconds);
    state.counters["map build s"] = buildSeconds / double(state.iterations());
    state.counters["full s"] = fullSeconds / double(state.iterations());
    state.counters["adaptive s"] = adaptiveSeconds / double(state.iterations());
    state.counters["no map s"] = noMapSeconds / double(state.iterations());
    state.counters["pixels within 2/255"] = closeShare;
}
BENCHMARK(demoShadowFilters)->Unit(benchmark::kSecond)->Iterations(1);

/// The filter alone: shadow-map lookups on the demo's floor (a 128 x 128 grid over the 3 x 3
/// world units around the torus, shadow and penumbra included), argument 0 Full, 1 Adaptive.
/// Compare the two time/lookup figures of one run; samples/lookup is the work ratio.
void demoShadowLookups(benchmark::State& state) {
    static const Scene scene = demoScene(std::make_shared<const Tile>(chainmailTile()));
    static const SceneTracer tracer(scene, TraceOptions{});
    static const LightShadowMaps map(tracer, scene.lights[0]);
    const ShadowFilter filter = state.range(0) == 0 ? ShadowFilter::Full : ShadowFilter::Adaptive;
    std::vector<ShadowReceiver> receivers;
    for (int y = 0; y < 128; ++y) {
        for (int x = 0; x < 128; ++x) {
            receivers.push_back(
                {{-1.5f + 3.0f * (x + 0.5f) / 128.0f, -1.3f + 3.0f * (y + 0.5f) / 128.0f, 0.0f},
                 {0.0f, 0.0f, 1.0f}});
        }
    }
    std::uint64_t samples = 0;
    std::uint32_t index = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(map.visibility(receivers[index & 0x3fff], filter, index, samples));
        ++index;
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["samples/lookup"] = double(samples) / double(state.iterations());
}
BENCHMARK(demoShadowLookups)->Arg(0)->Arg(1);

// Ch. 20: third-order filters on the same random points as sampleDistance. Compare
// sampleDistance<TricubicBSplineFilter> (8 trilinear fetches) with tricubic64Tap (the plain sum),
// and the gradients with trilinearGradient and trilinearCentralDifferences (6 trilinear samples,
// the shading-normal competitor of the tricubic gradient).
BENCHMARK(sampleDistance<TricubicBSplineFilter>);
BENCHMARK(sampleDistance<CatmullRomFilter>);

void tricubic64Tap(benchmark::State& state) {
    const TricubicBSplineFilter filter(chainmailTile());
    const auto points = randomPoints(1 << 16);
    std::size_t i = 0;
    for (auto _ : state) benchmark::DoNotOptimize(filter.distanceTexels64Tap(points[i++ & 0xffff]));
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(tricubic64Tap);

template <class Filter>
void sampleGradient(benchmark::State& state) {
    const Filter filter(chainmailTile());
    const auto points = randomPoints(1 << 16);
    std::size_t i = 0;
    for (auto _ : state) benchmark::DoNotOptimize(filter.gradient(points[i++ & 0xffff]));
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(sampleGradient<TricubicBSplineFilter>);
BENCHMARK(sampleGradient<CatmullRomFilter>);

void trilinearCentralDifferences(benchmark::State& state) {
    const TrilinearFilter filter(chainmailTile());
    const auto points = randomPoints(1 << 16);
    std::size_t i = 0;
    for (auto _ : state) {
        const glm::vec3 p = points[i++ & 0xffff];
        benchmark::DoNotOptimize(glm::vec3(filter.distanceTexels(p + glm::vec3(1, 0, 0)) -
                                               filter.distanceTexels(p - glm::vec3(1, 0, 0)),
                                           filter.distanceTexels(p + glm::vec3(0, 1, 0)) -
                                               filter.distanceTexels(p - glm::vec3(0, 1, 0)),
                                           filter.distanceTexels(p + glm::vec3(0, 0, 1)) -
                                               filter.distanceTexels(p - glm::vec3(0, 0, 1))) *
                                 0.5f);
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(trilinearCentralDifferences);

void tricubicHessian(benchmark::State& state) {
    const TricubicBSplineFilter filter(chainmailTile());
    const auto points = randomPoints(1 << 16);
    std::size_t i = 0;
    for (auto _ : state) benchmark::DoNotOptimize(filter.hessian(points[i++ & 0xffff]));
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(tricubicHessian);

/// Ch. 42 shell culling on the demo scene at 640 x 512 (the torus overlaps the floor's shells
/// and its own back half): renders with and without culling (no shadows, so camera rays
/// dominate), plus the same camera rays through the BVH path (SceneTracer::traceNearest) for
/// reference. Counters: shells traced and march iterations of each, CPU seconds of each, and
/// whether the two images are identical (1) as they must be.
void demoShellCulling(benchmark::State& state) {
    static const Scene scene = demoScene(std::make_shared<const Tile>(chainmailTile()));
    RenderOptions options;
    options.width = 640;
    options.height = 512;
    options.shadowFilter = ShadowFilter::None;
    options.selfShadows = false;
    double culledSeconds = 0.0, unculledSeconds = 0.0, bvhSeconds = 0.0;
    RenderStats culled, unculled;
    bool identical = true;
    for (auto _ : state) {
        options.skips.shellCulling = true;
        double start = processCpuSeconds();
        const RenderResult withCulling = renderScene(scene, options);
        culledSeconds += processCpuSeconds() - start;
        options.skips.shellCulling = false;
        start = processCpuSeconds();
        const RenderResult withoutCulling = renderScene(scene, options);
        unculledSeconds += processCpuSeconds() - start;
        start = processCpuSeconds();
        const SceneTracer tracer(scene, traceOptionsOf(options));
        const PinholeProjection projection(scene.camera, options.width, options.height);
        TraceCounters counters;
        for (int y = 0; y < options.height; ++y) {
            for (int x = 0; x < options.width; ++x) {
                SurfaceHit hit;
                benchmark::DoNotOptimize(
                    tracer.traceNearest(projection.ray(x + 0.5f, y + 0.5f), 0.0f, hit, counters));
            }
        }
        bvhSeconds += processCpuSeconds() - start;
        culled = withCulling.stats;
        unculled = withoutCulling.stats;
        identical = identical && withCulling.image.rgbLinear == withoutCulling.image.rgbLinear;
    }
    const double iterations = double(state.iterations());
    state.counters["culled shells traced"] = double(culled.shellsTraced);
    state.counters["unculled shells traced"] = double(unculled.shellsTraced);
    state.counters["culled march steps"] = double(culled.marchIterations);
    state.counters["unculled march steps"] = double(unculled.marchIterations);
    state.counters["culled s"] = culledSeconds / iterations;
    state.counters["unculled s"] = unculledSeconds / iterations;
    state.counters["bvh camera rays s"] = bvhSeconds / iterations;
    state.counters["identical"] = identical ? 1.0 : 0.0;
}
BENCHMARK(demoShellCulling)->Unit(benchmark::kSecond)->Iterations(1);

/// The base-triangle BVH (TriangleBvh) on the rays a shadow map of the demo traces: parallel
/// rays along its light, one per texel of a 512 x 512 grid over the torus and the floor around
/// it (texels of 0.005 world units, about a shadow map's finest), each asked for its nearest
/// base triangle as the shadow map's light rays are. Counter: the share of rays that hit.
void demoLightRaysBvh(benchmark::State& state) {
    static const DemoMeshes meshes = demoMeshes();
    static const TriangleBvh bvh = [] {
        std::vector<glm::vec3> corners;
        for (const BaseMesh* mesh : {&meshes.torus, &meshes.floor})
            for (const glm::uvec3& triangle : mesh->triangles)
                for (int corner = 0; corner < 3; ++corner)
                    corners.push_back(mesh->positions[triangle[corner]]);
        return TriangleBvh(std::move(corners));
    }();
    const glm::vec3 direction = glm::normalize(glm::vec3(-0.45f, 0.35f, -1.0f));
    // A plane across the light above the scene, its axes as a shadow map's.
    const glm::vec3 axisX = glm::normalize(glm::cross(direction, glm::vec3(0.0f, 1.0f, 0.0f)));
    const glm::vec3 axisY = glm::cross(axisX, direction);
    const glm::vec3 centre = glm::vec3(0.0f, 0.2f, 0.3f) - 4.0f * direction;
    constexpr int kTexels = 512;
    constexpr float kTexelWorld = 2.56f / float(kTexels);
    std::vector<Ray> rays;
    for (int y = 0; y < kTexels; ++y)
        for (int x = 0; x < kTexels; ++x)
            rays.push_back({centre + axisX * ((float(x) + 0.5f - 0.5f * kTexels) * kTexelWorld) +
                                axisY * ((float(y) + 0.5f - 0.5f * kTexels) * kTexelWorld),
                            direction});
    std::size_t hits = 0;
    const bool packets = state.range(0) == 1;
    std::vector<Ray> packet(16);
    const std::vector<float> from(16, 0.0f);
    TriangleHit packetHits[16];
    bool found[16];
    for (auto _ : state) {
        hits = 0;
        if (!packets) {
            for (const Ray& ray : rays) {
                TriangleHit hit;
                hits += bvh.intersect(ray, 0.0f, std::numeric_limits<float>::max(), hit) ? 1 : 0;
                benchmark::DoNotOptimize(hit);
            }
            continue;
        }
        for (int y = 0; y < kTexels; y += 4)
            for (int x = 0; x < kTexels; x += 4) {
                for (int k = 0; k < 16; ++k)
                    packet[std::size_t(k)] = rays[std::size_t((y + k / 4) * kTexels + x + k % 4)];
                bvh.intersectParallel(packet, from, std::numeric_limits<float>::max(), packetHits,
                                      found);
                for (int k = 0; k < 16; ++k) hits += found[k] ? 1 : 0;
                benchmark::DoNotOptimize(packetHits);
            }
    }
    state.counters["hit share"] = double(hits) / double(rays.size());
    state.SetItemsProcessed(std::int64_t(state.iterations()) * std::int64_t(rays.size()));
}
BENCHMARK(demoLightRaysBvh)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

/// The flat chain-mail sheet of data/scenes/sheet.json (a plane of 4 x 4 default tiles, camera
/// about 35 degrees above it) as `distile bench --speed` times it against the peers: 1280 x 1024,
/// no shadows, no AOVs, frames of the prepared scene (PreparedScene::render) on all threads.
/// Argument 1 turns the camera around: every pixel is sky, what remains is the per-pixel cost
/// of a frame before any shell is traced (ray set-up, screen bins, shading, the image). Argument
/// 2 is the same sheet over a plane of 2 x 100 x 100 triangles, as a modeller exports one: the
/// same picture (the uvs run on across the triangles), traced shell by shell, with the border
/// walk near the edges. Counter: mean march samples per camera ray.
void sheetFrame(benchmark::State& state) {
    static const Scene sheet = [] {
        Scene scene;
        scene.camera = {{0.0f, -2.1f, 1.47f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
        scene.lights = {DirectionalLight{{-0.4f, 0.3f, -1.0f}, {1.0f, 1.0f, 1.0f}, 2.0f}};
        SceneObject plane;
        plane.mesh = makePlane(2.0f, 1);  // the scene file's built-in plane, scaled by 2
        applyTransform(plane.mesh, {{0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 2.0f});
        plane.material.tile = std::make_shared<const Tile>(chainmailTile());
        plane.material.uvScale = {4.0f, 4.0f};
        plane.material.depthWorld = 0.0625f;
        plane.material.color = {0.8f, 0.8f, 0.85f};
        scene.objects.push_back(std::move(plane));
        return scene;
    }();
    static const Scene sky = [] {
        Scene scene = sheet;
        scene.camera.target = 2.0f * scene.camera.eye - scene.camera.target;  // looking away
        return scene;
    }();
    static const Scene fine = [] {
        Scene scene = sheet;
        BaseMesh& mesh = scene.objects[0].mesh;
        mesh = makePlane(2.0f, 100);
        applyTransform(mesh, {{0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 2.0f});
        return scene;
    }();
    RenderOptions options;
    options.width = 1280;
    options.height = 1024;
    options.selfShadows = false;
    options.shadowFilter = ShadowFilter::None;
    const Scene* const scenes[] = {&sheet, &sky, &fine};
    const PreparedScene prepared(*scenes[state.range(0)], options);
    double iterations = 0.0;
    for (auto _ : state) {
        const RenderResult result = prepared.render();
        iterations = double(result.stats.marchIterations) / double(result.stats.rays);
    }
    state.counters["samples/ray"] = iterations;
}
BENCHMARK(sheetFrame)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace distile

BENCHMARK_MAIN();
