#include "bench/bench_common.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include "common/atomic_file.h"
#include "common/error.h"

namespace distile::cli {

namespace fs = std::filesystem;

std::string sheetJson(const Size3& tile, int tilesPerSide, const SheetView& view) {
    std::ostringstream bake;
    bake << R"({"bake": "chainmail", "size": ")" << tile.width << "x" << tile.height << "x"
         << tile.depth << R"("})";
    return sheetJsonWithTile(bake.str(), tilesPerSide, 0.0625, view);
}

std::string repeatedSheetJson(const Size3& tile, int tilesPerSide) {
    std::ostringstream bake;
    bake << R"({"bake": "chainmail", "size": ")" << tile.width << "x" << tile.height << "x"
         << tile.depth << R"("})";
    return sheetJsonWithTile(bake.str(), tilesPerSide, 0.0625 * 4.0 / tilesPerSide);
}

std::string sheetJsonWithTile(const std::string& tileJson, int tilesPerSide, double depthWorld,
                              const SheetView& view) {
    std::ostringstream json;
    json << R"({
  "camera": {"eye": )"
         << view.eyeJson << R"(, "target": [0.0, 0.0, 0.0], "up": [0, 0, 1], "fov_deg": 40},
  "image": {"width": 1280, "height": 1024, "spp": 1},
  "lights": )"
         << view.lightsJson << R"(,
  "objects": [
    {"mesh": "plane",
     "transform": {"scale": 2.0},
     "material": {"tile": )"
         << tileJson << R"(, "uv_scale": [)" << tilesPerSide << ", " << tilesPerSide
         << R"(], "depth": )" << depthWorld << R"(,
                  "floor": "solid", "color": [0.8, 0.8, 0.85]}}
  ]
}
)";
    return json.str();
}

SceneFile loadBenchScene(const fs::path& file, const std::string& json, TileCache& tiles) {
    writeText(file, json);
    SceneFile scene = loadSceneFile(file, tiles);
    attachTruth(scene);
    return scene;
}

HeightImage smoothHeightImage(int side) {
    HeightImage heights;
    heights.width = heights.height = side;
    heights.values.resize(std::size_t(side) * std::size_t(side));
    constexpr double kTwoPi = 6.283185307179586;
    for (int y = 0; y < side; ++y) {
        for (int x = 0; x < side; ++x) {
            const double u = kTwoPi * x / side;
            const double v = kTwoPi * y / side;
            heights.values[std::size_t(y) * std::size_t(side) + std::size_t(x)] =
                float(0.5 + 0.25 * std::sin(u) * std::cos(2.0 * v) + 0.2 * std::cos(u + v));
        }
    }
    return heights;
}

RenderOptions benchRenderOptions(int width, int height) {
    RenderOptions options;
    options.width = width;
    options.height = height;
    options.outputAovs = true;
    // Primary visibility and shading only: the peers neither shade nor shadow.
    options.selfShadows = false;
    options.shadowFilter = ShadowFilter::None;
    return options;
}

double secondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

TimedRender timedRender(const Scene& scene, const RenderOptions& options) {
    const auto start = std::chrono::steady_clock::now();
    const PreparedScene prepared(scene, options);
    const double setupSeconds = secondsSince(start);
    const auto frameStart = std::chrono::steady_clock::now();
    TimedRender timed{prepared.render()};
    timed.frameSeconds = secondsSince(frameStart);
    timed.setupSeconds = setupSeconds;
    timed.seconds = setupSeconds + timed.frameSeconds;
    return timed;
}

TimedRender fastestRender(const Scene& scene, const RenderOptions& options, int runs) {
    TimedRender fastest = timedRender(scene, options);
    for (int run = 1; run < runs; ++run) {
        TimedRender timed = timedRender(scene, options);
        if (timed.frameSeconds < fastest.frameSeconds) fastest = std::move(timed);
    }
    return fastest;
}

FastestPair fastestPair(const Scene& sceneA, const RenderOptions& optionsA, const Scene& sceneB,
                        const RenderOptions& optionsB, int runs) {
    FastestPair fastest{timedRender(sceneA, optionsA), timedRender(sceneB, optionsB)};
    for (int run = 1; run < runs; ++run) {
        TimedRender a = timedRender(sceneA, optionsA);
        if (a.seconds < fastest.a.seconds) fastest.a = std::move(a);
        TimedRender b = timedRender(sceneB, optionsB);
        if (b.seconds < fastest.b.seconds) fastest.b = std::move(b);
    }
    return fastest;
}

TimedWorldReference timedWorldReference(const Scene& scene, int width, int height) {
    WorldReferenceOptions options;
    options.width = width;
    options.height = height;
    options.outputAovs = true;
    const auto start = std::chrono::steady_clock::now();
    TimedWorldReference timed{renderWorldReference(scene, options), 0.0};
    timed.seconds = secondsSince(start);
    return timed;
}

RenderLayersView layers(const RenderResult& result) {
    return {result.image, result.aovs->depth, result.aovs->normal, result.aovs->texelScale};
}

void writeText(const fs::path& file, const std::string& text) {
    writeAtomically(file, [&](const fs::path& temporary) {
        std::ofstream out(temporary);
        out << text;
        if (!out.flush()) throw InputError(file.string() + ": could not be written");
    });
}

}  // namespace distile::cli
