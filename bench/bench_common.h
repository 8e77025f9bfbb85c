/// @file
/// What `distile bench` (bench/bench_command.cpp) and `distile bench --speed`
/// (bench/speed_bench.cpp) share: their arguments, the flat chain-mail sheet scene, the torus on
/// the sheet, the smooth height image, timed renders, timed world references and text output.
/// Internal to the command; the libraries never see it.
#pragma once

#include <chrono>
#include <filesystem>
#include <string>

#include "bake/height_image.h"
#include "render/compare.h"
#include "render/renderer.h"
#include "render/world_reference.h"
#include "sampler/tile.h"
#include "scene/scene_file.h"

namespace distile::cli {

struct BenchArguments {
    std::filesystem::path outputDir = "bench-out";
    bool quick = false;
    bool peers = true;
    /// The stress cases (bench/stress/stress_cases.h) instead of the sweep.
    bool stress = false;
    /// The speed report (bench/speed_bench.h) instead of the sweep.
    bool speed = false;
    int width = 0;  ///< 0: 1280 (640 with --quick)
    int height = 0;
};

/// The view of the sheet: camera eye and lights as JSON values ("eye" array, "lights" array).
/// The defaults are data/scenes/sheet.json's: the camera about 35 degrees above the sheet, one
/// light from above.
struct SheetView {
    std::string eyeJson = "[0.0, -2.1, 1.47]";
    std::string lightsJson =
        R"([{"type": "directional", "direction": [-0.4, 0.3, -1.0], "color": [1, 1, 1], "angle_deg": 2}])";
};

/// The flat chain-mail sheet of data/scenes/sheet.json (a plane of `tilesPerSide` x
/// `tilesPerSide` tiles, 4 there), with the tile size and view given; written beside the results
/// so every row can be reproduced with `distile render`.
std::string sheetJson(const Size3& tile, int tilesPerSide = 4, const SheetView& view = {});

/// The sheet of sheetJson with `tilesPerSide` tiles and the shell depth scaled by 4 / tilesPerSide,
/// so texels stay cubes: the same detail, repeated more, smaller.
std::string repeatedSheetJson(const Size3& tile, int tilesPerSide);

/// The same sheet with `tileJson` (a JSON value: a tile file name or a bake object) as its tile.
std::string sheetJsonWithTile(const std::string& tileJson, int tilesPerSide = 4,
                              double depthWorld = 0.0625, const SheetView& view = {});

/// data/scenes/torus_on_sheet.json as the repository holds it (built into the command): chain mail
/// on a torus (a curved base) lying on the chain-mail sheet (flat), with its own image size.
std::string torusOnSheetJson();

/// Writes `json` to `file` (beside the results, so every row can be reproduced with `distile
/// render`), loads it as a scene file and gives its objects their truth (attachTruth). Throws
/// InputError when the file cannot be written or the scene is invalid.
SceneFile loadBenchScene(const std::filesystem::path& file, const std::string& json,
                         TileCache& tiles);

/// A smooth periodic height image, `side` x `side` pixels: 0.5 + 0.25 sin(u) cos(2v) +
/// 0.2 cos(u + v) with u, v = 2 pi x / side, 2 pi y / side, so every value is in [0.05, 0.95].
HeightImage smoothHeightImage(int side);

/// The bench's render options: `width` x `height`, AOVs on, no self-shadows and no shadow maps
/// (primary visibility and shading only: the peers neither shade nor shadow).
RenderOptions benchRenderOptions(int width, int height);

/// Wall time since `start`, seconds.
double secondsSince(std::chrono::steady_clock::time_point start);

struct TimedRender {
    RenderResult result;
    double seconds = 0.0;  ///< wall time of renderScene: setupSeconds + frameSeconds
    /// Of the set-up that does not depend on the camera (PreparedScene: BVH, tile layout and
    /// empty space, shell map), which a program rendering the scene again does not repeat.
    double setupSeconds = 0.0;
    /// Of the frame alone (PreparedScene::render): what a peer's trace of its built scene is
    /// compared with.
    double frameSeconds = 0.0;
};

TimedRender timedRender(const Scene& scene, const RenderOptions& options);

/// The render with the fastest frame of `runs` renders (at least one) of one configuration, with
/// its set-up. On a shared machine disturbances only add time, so the minimum is the least
/// disturbed measure of the work (renders are deterministic: every run's image is the same).
TimedRender fastestRender(const Scene& scene, const RenderOptions& options, int runs);

/// The fastest of `runs` renders of each of two configurations, run alternately (A, B, A, B, ...)
/// so that a slow spell of the shared machine hits both alike.
struct FastestPair {
    TimedRender a;
    TimedRender b;
};

FastestPair fastestPair(const Scene& sceneA, const RenderOptions& optionsA, const Scene& sceneB,
                        const RenderOptions& optionsB, int runs);

struct TimedWorldReference {
    WorldReferenceResult result;
    double seconds = 0.0;  ///< wall time of renderWorldReference, level sets included
};

/// The world reference of `scene` (render/world_reference.h) at `width` x `height` with its AOVs,
/// every other option at its default: the truth of the curved-shell rows.
TimedWorldReference timedWorldReference(const Scene& scene, int width, int height);

/// The layers of `result` a comparison reads. Precondition: rendered with outputAovs.
RenderLayersView layers(const RenderResult& result);

/// Writes `text` to `file` atomically; throws InputError naming the file when it cannot.
void writeText(const std::filesystem::path& file, const std::string& text);

}  // namespace distile::cli
