// distile bench --speed: the acceptance measurements of the renderer's speed (see
// bench/speed_bench.h).
#include "bench/speed_bench.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "bake/bake.h"
#include "bake/bake_cache.h"
#include "bench/main_job_bench.h"
#include "bench/peers/peers.h"
#include "common/error.h"
#include "render/compare.h"
#include "render/image.h"
#include "sampler/tile_io.h"
#include "scene/scene_file.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

/// A scene of the report, with the label its tables show it under (the report defines them).
struct SpeedScene {
    std::string id;
    std::string name;
    Scene scene;
};

/// A scene of the curved-shell section (E.), at its own image size.
struct CurvedShellScene {
    std::string id;
    std::string name;
    Scene scene;
    ImageSettings image;  ///< the scene's own size (its file's "image")
};

/// The section of the curved-shell rows in speed.csv.
constexpr const char* kCurvedSection = "curved shells";

/// Acceptance of the curved march: its time against the planar march's in the same run, and its
/// error against the world reference (interior pixels: render/compare.h).
constexpr double kMaxCurvedOverPlanar = 1.5;
constexpr double kMaxCurvedInteriorMeanTexels = 0.3;
constexpr double kMaxCurvedInteriorP99Texels = 2.0;
constexpr double kMaxCurvedCoverageMismatch = 0.005;
constexpr double kMaxCurvedInteriorNormalDeg = 3.0;

/// uv_scale of the chain-mail sheet and of the repeated sheet: 16x the repeats per side.
constexpr int kSheetTilesPerSide = 4;
constexpr int kRepeatedTilesPerSide = 64;

/// A skip "saves time" on a scene when it is faster there by more than this share and lowers one of
/// the renderer's work counters: on a shared machine the fastest of a few runs still moves by a
/// few percent between identical renders, so a time alone does not tell a skip from noise.
constexpr double kSavingThreshold = 0.02;
/// A skip passes when it changes the image by more than one 8-bit code in at most this
/// share of the pixels.
constexpr double kMaxDifferingShare = 0.001;

/// The default render's name among those the skips are measured in (runSpeedBench, C.): its
/// rows are named after the skip alone.
constexpr const char* kShadowedRender = "shadows";

/// One line of speed.csv; fields that do not apply stay NaN (written empty).
struct SpeedRow {
    SpeedRow(std::string sectionName, std::string sceneId, std::string measured)
        : section(std::move(sectionName)), scene(std::move(sceneId)), what(std::move(measured)) {}

    std::string section;  ///< peers, error, repetition, memory, skip, cache, threads
    std::string scene;    ///< the scene's label in the report
    std::string what;
    double seconds = std::nan("");          ///< distile; the skip on; warm cache; 1 thread
    double comparedSeconds = std::nan("");  ///< the peer; the skip off; no cache; all threads
    double differingShare = std::nan("");   ///< pixels with a channel more than 1 code apart
    double maxDifferenceCodes = std::nan("");
    double bytes = std::nan("");
    bool estimated = false;  ///< bytes extrapolated, not measured
    double meanHitErrorTexels = std::nan("");
    double coverageMismatchShare = std::nan("");
    double p99HitErrorTexels = std::nan("");
    double interiorMeanHitErrorTexels = std::nan("");  ///< render/compare.h's interior class
    double interiorP99HitErrorTexels = std::nan("");
    double meanNormalErrorDeg = std::nan("");
    double interiorMeanNormalErrorDeg = std::nan("");
    int width = 0;  ///< the image size where it is not the run's (curved shells); 0: the run's
    int height = 0;
    /// Skips: the RenderStats work counter the skip lowers most, and by which share of its value
    /// with the skip off (deterministic, unlike the times); "none" when it lowers none.
    std::string workCounter;
    double workSavedShare = std::nan("");
    std::string note;
};

/// Fills the error fields of `row` from a comparison against a reference.
void setError(SpeedRow& row, const RenderComparison& comparison) {
    row.meanHitErrorTexels = comparison.meanHitErrorTexels;
    row.coverageMismatchShare = comparison.coverageMismatchShare;
    row.p99HitErrorTexels = comparison.p99HitErrorTexels;
    row.interiorMeanHitErrorTexels = comparison.interior.meanHitErrorTexels;
    row.interiorP99HitErrorTexels = comparison.interior.p99HitErrorTexels;
    row.meanNormalErrorDeg = comparison.meanNormalErrorDeg;
    row.interiorMeanNormalErrorDeg = comparison.interior.meanNormalErrorDeg;
}

/// The `what` of a skip's row: the switch, and the render unless it is the default one.
std::string skipRowName(const RenderSkipSwitch& skip, const char* renderName) {
    return renderName == std::string(kShadowedRender) ? std::string(skip.name)
                                                      : std::string(skip.name) + ", " + renderName;
}

/// RenderStats counters of work a skip may save.
struct WorkCounter {
    const char* name;
    std::uint64_t RenderStats::*count;
};

constexpr std::array kWorkCounters{
    WorkCounter{"march iterations", &RenderStats::marchIterations},
    WorkCounter{"self-shadow steps", &RenderStats::shadowSteps},
    WorkCounter{"shadow-map samples", &RenderStats::shadowMapSamples},
    WorkCounter{"shadow-map texels traced", &RenderStats::shadowMapTexels},
    WorkCounter{"shells traced", &RenderStats::shellsTraced},
};

/// The counter that `on` lowers most against `off`, relative to its value in `off`.
std::pair<std::string, double> largestWorkSaving(const RenderStats& on, const RenderStats& off) {
    std::pair<std::string, double> largest{"none", 0.0};
    for (const WorkCounter& counter : kWorkCounters) {
        const double without = double(off.*counter.count);
        const double with = double(on.*counter.count);
        if (without > 0.0 && with < without && 1.0 - with / without > largest.second)
            largest = {counter.name, 1.0 - with / without};
    }
    return largest;
}

/// Sets an environment variable for the lifetime of the object, then restores it.
class ScopedEnvironment {
  public:
    ScopedEnvironment(const char* name, const char* value) : name_(name) {
        if (const char* previous = std::getenv(name)) previous_ = previous;
        setenv(name, value, 1);
    }
    ~ScopedEnvironment() {
        if (previous_)
            setenv(name_, previous_->c_str(), 1);
        else
            unsetenv(name_);
    }
    ScopedEnvironment(const ScopedEnvironment&) = delete;
    ScopedEnvironment& operator=(const ScopedEnvironment&) = delete;

  private:
    const char* name_;
    std::optional<std::string> previous_;
};

std::string csvNumber(double value) {
    if (std::isnan(value)) return "";
    std::ostringstream text;
    text.precision(6);
    text << value;
    return text.str();
}

std::string csvOf(const std::vector<SpeedRow>& rows, int threads, int width, int height) {
    std::ostringstream csv;
    csv << "section,scene,what,seconds,compared_seconds,ratio,differing_share,max_difference_codes,"
           "bytes,bytes_estimated,hit_error_mean_texels,coverage_mismatch_share,"
           "hit_error_p99_texels,interior_hit_error_mean_texels,interior_hit_error_p99_texels,"
           "normal_error_mean_deg,interior_normal_error_mean_deg,work_counter,work_saved_share,"
           "note,threads,width,height\n";
    for (const SpeedRow& r : rows) {
        csv << r.section << "," << r.scene << ",\"" << r.what << "\"," << csvNumber(r.seconds)
            << "," << csvNumber(r.comparedSeconds) << ","
            << csvNumber(r.seconds / r.comparedSeconds) << "," << csvNumber(r.differingShare) << ","
            << csvNumber(r.maxDifferenceCodes) << "," << csvNumber(r.bytes) << ","
            << (std::isnan(r.bytes) ? ""
                : r.estimated       ? "1"
                                    : "0")
            << "," << csvNumber(r.meanHitErrorTexels) << "," << csvNumber(r.coverageMismatchShare)
            << "," << csvNumber(r.p99HitErrorTexels) << ","
            << csvNumber(r.interiorMeanHitErrorTexels) << ","
            << csvNumber(r.interiorP99HitErrorTexels) << "," << csvNumber(r.meanNormalErrorDeg)
            << "," << csvNumber(r.interiorMeanNormalErrorDeg) << ",\"" << r.workCounter << "\","
            << csvNumber(r.workSavedShare) << ",\"" << r.note << "\"," << threads << ","
            << (r.width > 0 ? r.width : width) << "," << (r.height > 0 ? r.height : height) << "\n";
    }
    return csv.str();
}

std::string verdict(bool passed) {
    return passed ? "**pass**" : "**FAIL**";
}

std::string mib(double bytes) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f MiB", bytes / (1024.0 * 1024.0));
    return text;
}

std::string fixed(double value, int digits) {
    if (std::isnan(value)) return "-";
    char text[32];
    std::snprintf(text, sizeof text, "%.*f", digits, value);
    return text;
}

const SpeedRow* findRow(const std::vector<SpeedRow>& rows, const std::string& section,
                        const std::string& scene, const std::string& what) {
    for (const SpeedRow& r : rows)
        if (r.section == section && r.scene == scene && r.what == what) return &r;
    return nullptr;
}

}  // namespace

void runSpeedBench(const BenchArguments& arguments) {
    const int width = arguments.width > 0 ? arguments.width : (arguments.quick ? 640 : 1280);
    const int height = arguments.height > 0 ? arguments.height : (arguments.quick ? 512 : 1024);
    const int runs = arguments.quick ? 2 : 3;
    const int threads =
        int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    const fs::path sceneDir = arguments.outputDir / "scenes";
    std::error_code error;
    fs::create_directories(sceneDir, error);
    if (error)
        throw InputError("-o: cannot create the folder '" + sceneDir.string() +
                         "': " + error.message());
    auto say = [](const std::string& line) {
        std::printf("%s\n", line.c_str());
        std::fflush(stdout);
    };
    char line[320];
    say("bench --speed: " + std::to_string(width) + "x" + std::to_string(height) + ", " +
        std::to_string(threads) + " threads, each time the minimum of " + std::to_string(runs) +
        " runs");

    // Scenes.
    TileCache tiles;
    const Size3 sheetTile{256, 256, 16};
    auto loadJson = [&](const std::string& fileName, const std::string& json, TileCache& cache) {
        return loadBenchScene(sceneDir / fileName, json, cache).scene;
    };
    say("bench --speed: loading the scenes (bakes come from the cache when it has them)");
    std::vector<SpeedScene> scenes;
    scenes.push_back(
        {"S1", "sheet", loadJson("sheet.json", sheetJson(sheetTile, kSheetTilesPerSide), tiles)});
    scenes.push_back(
        {"S2", "sheet x16",
         loadJson("sheet_x16.json", repeatedSheetJson(sheetTile, kRepeatedTilesPerSide), tiles)});
    SceneFile demo = demoScene(tiles);
    attachTruth(demo);  // the world reference's detail: analytic, not the tile
    scenes.push_back({"S3", "demo", demo.scene});
    {
        // Heights fill the lowest quarter of the slab: a large empty space above the detail.
        HeightMapOptions heightMap;
        heightMap.heightTexels = sheetTile.depth / 4.0;
        BakeOptions bake;
        bake.size = sheetTile;
        const std::string recipe =
            "speed bench low height field: smoothHeightImage(" + std::to_string(sheetTile.width) +
            "), height " + numberText(heightMap.heightTexels) + " texels, size " +
            std::to_string(sheetTile.width) + "x" + std::to_string(sheetTile.height) + "x" +
            std::to_string(sheetTile.depth);
        const std::shared_ptr<const Tile> tile = cachedBake(recipe, [&] {
            return bakeHeightMap(smoothHeightImage(sheetTile.width), heightMap, bake).tile;
        });
        writeTileExr(*tile, sceneDir / "low_height_field.exr");
        scenes.push_back(
            {"S4", "low height field",
             loadJson("low_height_field.json",
                      sheetJsonWithTile("\"low_height_field.exr\"", kSheetTilesPerSide), tiles)});
        // The same seen from about 12 degrees above the sheet, as terrain is: rays cross long
        // empty paths above the detail before they reach it.
        SheetView grazing;
        grazing.eyeJson = "[0.0, -2.1, 0.45]";
        scenes.push_back({"S5", "low height field, grazing view",
                          loadJson("low_height_field_grazing.json",
                                   sheetJsonWithTile("\"low_height_field.exr\"", kSheetTilesPerSide,
                                                     0.0625, grazing),
                                   tiles)});
    }
    {
        // Three low lights around the sheet (key, fill and rim of a studio set-up): much of the
        // detail faces away from one or two of them, where the unlit-shadow skip does its work.
        SheetView threeLights;
        threeLights.lightsJson =
            R"([{"type": "directional", "direction": [-1.0, 0.3, -0.5], "color": [0.6, 0.6, 0.6], "angle_deg": 2},
            {"type": "directional", "direction": [1.0, 0.3, -0.5], "color": [0.5, 0.5, 0.6], "angle_deg": 2},
            {"type": "directional", "direction": [0.0, -1.0, -0.6], "color": [0.5, 0.5, 0.5], "angle_deg": 2}])";
        scenes.push_back({"S6", "sheet, three lights",
                          loadJson("sheet_three_lights.json",
                                   sheetJson(sheetTile, kSheetTilesPerSide, threeLights), tiles)});
    }
    const Scene& sheet = scenes[0].scene;
    const Scene& repeated = scenes[1].scene;
    // The curved-shell section's scenes: the demo and the torus on the sheet.
    const std::vector<CurvedShellScene> curvedScenes{
        {"S3", "demo", demo.scene, demo.image}, [&] {
            const SceneFile torus =
                loadBenchScene(sceneDir / "torus_on_sheet.json", torusOnSheetJson(), tiles);
            return CurvedShellScene{"S7", "torus on sheet", torus.scene, torus.image};
        }()};

    std::vector<SpeedRow> rows;
    std::vector<std::string> notes;
    // The peers' render: primary visibility and a normal (no shadows, no AOVs).
    RenderOptions unshadowed = benchRenderOptions(width, height);
    unshadowed.outputAovs = false;
    // The default render, shadows included.
    RenderOptions shadowed;
    shadowed.width = width;
    shadowed.height = height;

    // A. Peers and error, on the chain-mail sheet.
    say("bench --speed: A. distile against the peers on S1, and its error");
    // A first render, untimed: the process's first pays for starting the thread pool and for
    // fresh pages (the peers' times exclude their start too: set-up, reading the level set).
    timedRender(sheet, unshadowed);
    // Frames of the prepared scene, as the peers' traces are of their built scenes.
    TimedRender sheetUnshadowed = fastestRender(sheet, unshadowed, runs);
    // Said once distile's runs are over (with the peers, after theirs).
    auto sayDistileTime = [&] {
        std::snprintf(line, sizeof line,
                      "  S1 distile, no shadows, no AOVs       %8.4f s frame (setup %.4f s)",
                      sheetUnshadowed.frameSeconds, sheetUnshadowed.setupSeconds);
        say(line);
    };
    {
        RenderOptions referenceOptions = benchRenderOptions(width, height);
        referenceOptions.reference = true;
        const TimedRender reference = timedRender(sheet, referenceOptions);
        const TimedRender measured = timedRender(sheet, benchRenderOptions(width, height));
        const RenderComparison comparison =
            compareRenders(layers(measured.result), layers(reference.result));
        SpeedRow row{"error", "S1", "distile against the analytic reference"};
        setError(row, comparison);
        rows.push_back(row);
        std::snprintf(line, sizeof line,
                      "  S1 error: mean hit %.4f texel, coverage mismatch %.4f%%",
                      comparison.meanHitErrorTexels, 100.0 * comparison.coverageMismatchShare);
        say(line);
    }
    const double tileBytes =
        double(sheet.objects[0].material.tile->distancesTexels().size()) * sizeof(float);
    std::optional<double> embreeBytes, levelSetBytes;
    if (arguments.peers) {
        auto peerRow = [&](const std::string& name, std::optional<PeerRender> fastest) {
            if (!fastest) return;
            if (!fastest->available) {
                notes.push_back(name + ": " + fastest->unavailableReason);
                say("  " + name + ": " + fastest->unavailableReason);
                return;
            }
            SpeedRow row{"peers", "S1", "distile (no shadows) against " + name + "'s trace"};
            row.seconds = sheetUnshadowed.frameSeconds;
            row.comparedSeconds = fastest->traceSeconds;
            row.bytes = double(fastest->memoryBytes);
            rows.push_back(row);
            std::snprintf(line, sizeof line,
                          "  S1 %-34s %8.4f s trace (setup %.1f s, %s); distile/%s %.3f, "
                          "%s/distile %.2f",
                          name.c_str(), fastest->traceSeconds, fastest->setupSeconds,
                          mib(double(fastest->memoryBytes)).c_str(), name.c_str(),
                          sheetUnshadowed.frameSeconds / fastest->traceSeconds, name.c_str(),
                          fastest->traceSeconds / sheetUnshadowed.frameSeconds);
            say(line);
        };
        // distile renders again before each peer run, so that a slow spell of the shared
        // machine hits both alike; its time is the fastest of all its runs.
        int distileRuns = runs;
        auto renderSheetAgain = [&] {
            TimedRender timed = timedRender(sheet, unshadowed);
            if (timed.frameSeconds < sheetUnshadowed.frameSeconds)
                sheetUnshadowed = std::move(timed);
            ++distileRuns;
        };
        // The fastest trace of `runs` runs of a peer (each with its own set-up), each run after
        // one of distile's.
        auto fastestPeer = [&](const auto& renderPeer) {
            std::optional<PeerRender> fastest;
            for (int run = 0; run < runs; ++run) {
                renderSheetAgain();
                PeerRender peer = renderPeer();
                if (!fastest || !peer.available || peer.traceSeconds < fastest->traceSeconds)
                    fastest = std::move(peer);
                if (!fastest->available) break;
            }
            return fastest;
        };
        const std::optional<PeerRender> embree =
            fastestPeer([&] { return renderSheetWithEmbree(sheet, width, height, threads); });
        const fs::path work = arguments.outputDir / "vdb_render";
        fs::create_directories(work);
        const std::optional<PeerRender> vdbRender = fastestPeer(
            [&] { return renderSheetWithVdbRender(sheet, width, height, threads, work); });
        sayDistileTime();
        peerRow("embree", embree);
        peerRow("vdb_render", vdbRender);
        std::string note = "distile and each peer: the fastest of their runs, distile's ";
        note += "alternating with the peer's (" + std::to_string(runs) + " runs of each peer, ";
        note += "each with its own set-up; distile's fastest of all its ";
        note += std::to_string(distileRuns) + " runs after one untimed warm-up render).";
        notes.push_back(note);
        if (embree && embree->available) embreeBytes = double(embree->memoryBytes);
        if (vdbRender && vdbRender->available) levelSetBytes = double(vdbRender->memoryBytes);
    } else {
        sayDistileTime();
        notes.push_back("peers: not run (--no-peers)");
    }

    // B. Repetition and memory.
    say("bench --speed: B. repetition (S2: uv scale x16) and memory");
    {
        for (const bool shadows : {false, true}) {
            const RenderOptions& options = shadows ? shadowed : unshadowed;
            const FastestPair pair = fastestPair(repeated, options, sheet, options, runs);
            SpeedRow row{"repetition", "S2", shadows ? "S2 / S1, shadows" : "S2 / S1, no shadows"};
            row.seconds = pair.a.seconds;
            row.comparedSeconds = pair.b.seconds;
            rows.push_back(row);
            std::snprintf(line, sizeof line, "  %-22s S1 %8.4f s, S2 %8.4f s: S2/S1 %.3f",
                          shadows ? "shadows" : "no shadows, no AOVs", pair.b.seconds,
                          pair.a.seconds, pair.a.seconds / pair.b.seconds);
            say(line);
        }
        const double repeatedTileBytes =
            double(repeated.objects[0].material.tile->distancesTexels().size()) * sizeof(float);
        const double repeatFactor = double(kRepeatedTilesPerSide * kRepeatedTilesPerSide) /
                                    double(kSheetTilesPerSide * kSheetTilesPerSide);
        auto memoryRow = [&](const std::string& scene, const std::string& what,
                             std::optional<double> bytes, bool estimated, const std::string& note) {
            SpeedRow memory{"memory", scene, what};
            if (bytes) memory.bytes = *bytes;
            memory.estimated = estimated;
            memory.note = bytes ? note : "not measured (peers not run)";
            rows.push_back(memory);
        };
        memoryRow("S1", "distile tile", tileBytes, false, "");
        memoryRow("S2", "distile tile", repeatedTileBytes, false, "one tile, repeated by uv");
        memoryRow("S1", "embree scene", embreeBytes, false, "rtcDevice memory monitor");
        memoryRow("S2", "embree scene",
                  embreeBytes ? std::optional<double>(*embreeBytes * repeatFactor) : std::nullopt,
                  true, "estimate: S1 x 256 (not built: every repeat is its own geometry)");
        memoryRow("S1", "repeated level set", levelSetBytes, false, "OpenVDB memUsage");
        memoryRow(
            "S2", "repeated level set",
            levelSetBytes ? std::optional<double>(*levelSetBytes * repeatFactor) : std::nullopt,
            true, "estimate: S1 x 256");
    }

    // C. Skips, in three renders: the default (shadows on), the peers' (primary visibility and a
    // normal), and that with the tricubic B-spline as the march's filter (64 taps a sample). The
    // march's skips weigh most where the march is most of the work, the shadows' only with
    // shadows.
    say("bench --speed: C. every skip off, one at a time, with shadows, without, and with the "
        "tricubic march");
    RenderOptions tricubicMarch = unshadowed;
    tricubicMarch.filter = FilterKind::TricubicBSpline;
    const std::array<std::pair<const char*, const RenderOptions*>, 3> skipRenders{
        std::pair{kShadowedRender, &shadowed}, std::pair{"no shadows", &unshadowed},
        std::pair{"tricubic march", &tricubicMarch}};
    for (const RenderSkipSwitch& skip : kRenderSkipSwitches) {
        for (const auto& [renderName, render] : skipRenders) {
            for (std::size_t index = 0; index < scenes.size(); ++index) {
                RenderOptions without = *render;
                without.skips.*skip.enabled = false;
                const Scene& scene = scenes[index].scene;
                const FastestPair pair = fastestPair(scene, *render, scene, without, runs);
                const CodeDifference difference =
                    codeDifference(pair.a.result.image, pair.b.result.image);
                SpeedRow row{"skip", scenes[index].id, skipRowName(skip, renderName)};
                row.seconds = pair.a.seconds;
                row.comparedSeconds = pair.b.seconds;
                std::tie(row.workCounter, row.workSavedShare) =
                    largestWorkSaving(pair.a.result.stats, pair.b.result.stats);
                row.differingShare = difference.differingShare;
                row.maxDifferenceCodes = difference.maxCodes;
                rows.push_back(row);
                std::snprintf(
                    line, sizeof line,
                    "  %-20s %-10s %s on %8.4f s off %8.4f s saving %6.1f%%, %.4f%% pixels "
                    "> 1 code, max %d; work: %s -%.1f%%",
                    skip.name, renderName, scenes[index].id.c_str(), row.seconds,
                    row.comparedSeconds, 100.0 * (1.0 - row.seconds / row.comparedSeconds),
                    100.0 * row.differingShare, difference.maxCodes, row.workCounter.c_str(),
                    100.0 * row.workSavedShare);
                say(line);
            }
        }
    }

    // The bake cache: the chain-mail sheet loaded from a warm cache against a bake with caching
    // off.
    say("bench --speed: bake cache (S1 loaded warm against caching off)");
    if (bakeCacheFolder()) {
        const std::string json = sheetJson(sheetTile, kSheetTilesPerSide);
        double warmSeconds = std::numeric_limits<double>::infinity();
        Scene warm;
        for (int run = 0; run < runs; ++run) {
            TileCache fresh;
            const auto start = std::chrono::steady_clock::now();
            warm = loadJson("sheet.json", json, fresh);
            warmSeconds = std::min(warmSeconds, secondsSince(start));
        }
        Scene baked;
        double bakedSeconds = 0.0;
        {
            // One run: the bake takes seconds, far above the machine's noise.
            const ScopedEnvironment noCache("DISTILE_CACHE", "off");
            TileCache fresh;
            const auto start = std::chrono::steady_clock::now();
            baked = loadJson("sheet.json", json, fresh);
            bakedSeconds = secondsSince(start);
        }
        const CodeDifference difference =
            codeDifference(renderScene(warm, shadowed).image, renderScene(baked, shadowed).image);
        SpeedRow row{"cache", "S1", "bake cache"};
        row.seconds = warmSeconds;
        row.comparedSeconds = bakedSeconds;
        row.differingShare = difference.differingShare;
        row.maxDifferenceCodes = difference.maxCodes;
        row.note = difference.bitIdentical ? "image bit-identical" : "image differs";
        rows.push_back(row);
        std::snprintf(line, sizeof line, "  warm cache %8.4f s, caching off %8.4f s; image %s",
                      warmSeconds, bakedSeconds,
                      difference.bitIdentical ? "bit-identical" : "DIFFERS");
        say(line);
    } else {
        notes.push_back("bake cache: disabled in this environment (DISTILE_CACHE=off or no home)");
        say("  bake cache disabled here: not measured");
    }

    // D. Threads.
    say("bench --speed: D. S1 on 1 thread against " + std::to_string(threads) + " threads");
    {
        RenderResult single;
        {
            const tbb::global_control oneThread(tbb::global_control::max_allowed_parallelism, 1);
            single = renderScene(sheet, shadowed);
        }
        const RenderResult all = renderScene(sheet, shadowed);
        const CodeDifference difference = codeDifference(single.image, all.image);
        float maxLinear = 0.0f;
        for (std::size_t i = 0; i < single.image.rgbLinear.size(); ++i)
            for (int channel = 0; channel < 3; ++channel)
                maxLinear = std::max(maxLinear, std::abs(single.image.rgbLinear[i][channel] -
                                                         all.image.rgbLinear[i][channel]));
        SpeedRow row{"threads", "S1", "1 thread against " + std::to_string(threads)};
        row.differingShare = difference.differingShare;
        row.maxDifferenceCodes = difference.maxCodes;
        row.note = difference.bitIdentical
                       ? "bit-identical"
                       : "differs: max linear difference " + std::to_string(maxLinear);
        rows.push_back(row);
        say(std::string("  bit-identical: ") + (difference.bitIdentical ? "yes" : "no") +
            " (max linear difference " + std::to_string(maxLinear) + ")");
    }

    // E. Curved shells: the curved march against the planar one in the same run, alternated as
    // in B, and each against the world reference of the same scene at the same size.
    say("bench --speed: E. curved shells: the curved march against the planar one, each against "
        "the world reference");
    // The scene's own size; a quarter of it per side with --quick; the run's when given.
    const bool sizeGiven = arguments.width > 0 || arguments.height > 0;
    auto curvedSize = [&](const ImageSettings& image) {
        if (sizeGiven) return std::pair{width, height};
        if (arguments.quick)
            return std::pair{std::max(16, image.width / 4), std::max(16, image.height / 4)};
        return std::pair{image.width, image.height};
    };
    for (const CurvedShellScene& s : curvedScenes) {
        const auto [curvedWidth, curvedHeight] = curvedSize(s.image);
        // The errors from a render as the peers' in A (no shadows), with the AOVs they compare.
        RenderOptions curvedAovs = benchRenderOptions(curvedWidth, curvedHeight);
        curvedAovs.shellMapping = ShellMapping::Curved;
        RenderOptions planarAovs = curvedAovs;
        planarAovs.shellMapping = ShellMapping::Planar;
        timedRender(s.scene, curvedAovs);  // untimed warm-up: fresh pages for this scene and size
        const TimedRender curvedErrors = timedRender(s.scene, curvedAovs);
        const TimedRender planarErrors = timedRender(s.scene, planarAovs);
        // The times without the AOVs, whose filling costs both shell maps alike and would hide
        // the march's own cost; then the render a user gets (shadow maps and self-shadows on),
        // and each of its two kinds of shadow work alone: where a curved shell costs more.
        const auto timedPair = [&](bool shadowMaps, bool selfShadows) {
            RenderOptions curvedTimed;
            curvedTimed.width = curvedWidth;
            curvedTimed.height = curvedHeight;
            curvedTimed.shellMapping = ShellMapping::Curved;
            if (!shadowMaps) curvedTimed.shadowFilter = ShadowFilter::None;
            curvedTimed.selfShadows = selfShadows;
            RenderOptions planarTimed = curvedTimed;
            planarTimed.shellMapping = ShellMapping::Planar;
            return fastestPair(s.scene, curvedTimed, s.scene, planarTimed, runs);
        };
        const FastestPair pair = timedPair(false, false);
        const FastestPair shadedPair = timedPair(true, true);
        const FastestPair mapsPair = timedPair(true, false);
        const FastestPair selfPair = timedPair(false, true);
        say("  " + s.id + " world reference, " + std::to_string(curvedWidth) + "x" +
            std::to_string(curvedHeight));
        const TimedWorldReference reference =
            timedWorldReference(s.scene, curvedWidth, curvedHeight);
        const RenderLayersView truth = layers(reference.result.render);
        auto curvedRow = [&](const std::string& what) {
            SpeedRow row{kCurvedSection, s.id, what};
            row.width = curvedWidth;
            row.height = curvedHeight;
            return row;
        };
        SpeedRow timeRow = curvedRow("curved against planar");
        timeRow.seconds = pair.a.seconds;
        timeRow.comparedSeconds = pair.b.seconds;
        timeRow.note = "no shadows, no AOVs";
        rows.push_back(timeRow);
        for (const auto& [what, timed, note] :
             {std::tuple{"curved against planar, default render", &shadedPair,
                         "shadows on, no AOVs"},
              std::tuple{"curved against planar, shadow maps only", &mapsPair,
                         "shadow maps, no self-shadows, no AOVs"},
              std::tuple{"curved against planar, self-shadows only", &selfPair,
                         "self-shadows, no shadow maps, no AOVs"}}) {
            SpeedRow row = curvedRow(what);
            row.seconds = timed->a.seconds;
            row.comparedSeconds = timed->b.seconds;
            row.note = note;
            rows.push_back(row);
        }
        for (const auto& [what, render] : {std::pair{"curved", &curvedErrors.result},
                                           std::pair{"planar", &planarErrors.result}}) {
            SpeedRow errorRow = curvedRow(std::string(what) + " against the world reference");
            setError(errorRow, compareRenders(layers(*render), truth));
            rows.push_back(errorRow);
            std::snprintf(line, sizeof line,
                          "  %s %-6s interior mean %.4f p99 %.3f, all mean %.4f p99 %.3f texels, "
                          "coverage mismatch %.4f%%, normals %.2f deg interior, %.2f all",
                          s.id.c_str(), what, errorRow.interiorMeanHitErrorTexels,
                          errorRow.interiorP99HitErrorTexels, errorRow.meanHitErrorTexels,
                          errorRow.p99HitErrorTexels, 100.0 * errorRow.coverageMismatchShare,
                          errorRow.interiorMeanNormalErrorDeg, errorRow.meanNormalErrorDeg);
            say(line);
        }
        SpeedRow referenceRow = curvedRow("world reference");
        referenceRow.seconds = reference.seconds;
        referenceRow.note = "one run, its build included";
        rows.push_back(referenceRow);
        std::snprintf(line, sizeof line,
                      "  %s no shadows: curved %8.4f s, planar %8.4f s (%.3f); default render: "
                      "curved %8.4f s, planar %8.4f s (%.3f); shadow maps only %.3f, "
                      "self-shadows only %.3f; world reference %.2f s",
                      s.id.c_str(), pair.a.seconds, pair.b.seconds, pair.a.seconds / pair.b.seconds,
                      shadedPair.a.seconds, shadedPair.b.seconds,
                      shadedPair.a.seconds / shadedPair.b.seconds,
                      mapsPair.a.seconds / mapsPair.b.seconds,
                      selfPair.a.seconds / selfPair.b.seconds, reference.seconds);
        say(line);
    }

    // F and G. The main job as whole processes, and the demo's scaling with the thread count.
    say("bench --speed: F. distile render of the demo as whole processes; G. scaling");
    const MainJobReport mainJob = measureMainJob(arguments.outputDir, demo.scene, width, height,
                                                 arguments.quick ? 3 : 5, runs, say);
    writeText(arguments.outputDir / "main_job.csv", mainJob.csv);

    writeText(arguments.outputDir / "speed.csv", csvOf(rows, threads, width, height));

    // The report.
    std::ostringstream md;
    md << "# distile bench --speed\n\n"
       << width << "x" << height << ", " << threads << " threads, every time the minimum of "
       << runs
       << " runs (the machine is shared; the minimum is the least disturbed run). Scenes (JSON "
          "in scenes/): S1 the flat chain-mail sheet (4 x 4 tiles of 256x256x16), S2 the same "
          "with uv_scale 64 x 64 and the shell depth divided by 16, so the texels stay cubes "
          "(the same detail repeated 16 x 16 times more; keeping the depth instead would stretch "
          "every texel 16:1 in z, a different, much taller detail seen at grazing texel-space "
          "angles), S3 the built-in demo (chain mail on a torus on a plane: "
          "misses, back faces, a curved mesh, shadows), S4 the sheet with a smooth height field "
          "filling the lowest quarter of the slab, S5 that height field seen from about 12 degrees "
          "above (long empty paths above the detail), S6 the chain-mail sheet under three low "
          "lights from three sides (much of the detail faces away from one of them); in E only, "
          "S7 chain mail on a torus lying on the chain-mail sheet "
          "(data/scenes/torus_on_sheet.json)."
          "\n\n";

    md << "## A. Peers on S1 (primary visibility and a normal: distile without shadows or AOVs)"
          "\n\nA peer's trace of its built scene against distile's frame of its prepared scene "
          "(set-up "
       << fixed(sheetUnshadowed.setupSeconds, 4)
       << " s apart: BVH, tile layout and empty space; the peers' builds are on the terminal)."
          "\n\n| | trace s | distile frame s | ratio |\n|---|---|---|---|\n";
    const SpeedRow* embreeRow =
        findRow(rows, "peers", "S1", "distile (no shadows) against embree's trace");
    const SpeedRow* vdbRow =
        findRow(rows, "peers", "S1", "distile (no shadows) against vdb_render's trace");
    if (embreeRow)
        md << "| Embree | " << fixed(embreeRow->comparedSeconds, 4) << " | "
           << fixed(embreeRow->seconds, 4) << " | distile / Embree "
           << fixed(embreeRow->seconds / embreeRow->comparedSeconds, 3) << " |\n";
    if (vdbRow)
        md << "| vdb_render | " << fixed(vdbRow->comparedSeconds, 4) << " | "
           << fixed(vdbRow->seconds, 4) << " | vdb_render / distile "
           << fixed(vdbRow->comparedSeconds / vdbRow->seconds, 2) << " |\n";
    if (!embreeRow && !vdbRow)
        md << "| (peers not run) | | " << fixed(sheetUnshadowed.frameSeconds, 4) << " | |\n";
    const SpeedRow* errorRow =
        findRow(rows, "error", "S1", "distile against the analytic reference");
    md << "\ndistile's error on S1 against the analytic reference: mean hit error "
       << fixed(errorRow->meanHitErrorTexels, 4) << " texel (at most 0.25), coverage mismatch "
       << fixed(100.0 * errorRow->coverageMismatchShare, 4) << "% (at most 0.5%).\n\n";

    md << "## B. Repetition and memory\n\n| S2 / S1 | S1 s | S2 s | ratio |\n|---|---|---|---|\n";
    for (const char* what : {"S2 / S1, no shadows", "S2 / S1, shadows"}) {
        const SpeedRow* r = findRow(rows, "repetition", "S2", what);
        md << "| " << std::string(what).substr(9) << " | " << fixed(r->comparedSeconds, 4) << " | "
           << fixed(r->seconds, 4) << " | " << fixed(r->seconds / r->comparedSeconds, 3) << " |\n";
    }
    md << "\n| memory | S1 | S2 |\n|---|---|---|\n";
    for (const char* what : {"distile tile", "embree scene", "repeated level set"}) {
        const SpeedRow* s1 = findRow(rows, "memory", "S1", what);
        const SpeedRow* s2 = findRow(rows, "memory", "S2", what);
        auto cell = [](const SpeedRow* r) {
            if (std::isnan(r->bytes)) return std::string("not measured");
            return mib(r->bytes) + (r->estimated ? " (estimate, x256)" : "");
        };
        md << "| " << what << " | " << cell(s1) << " | " << cell(s2) << " |\n";
    }

    md << "\n## C. Skips (each skip off alone; the default render with shadows, primary "
          "visibility without shadows as in A, and that with the tricubic B-spline as the march's "
          "filter)\n\n"
          "Pixels > 1 code: share of pixels where a channel of the 8-bit sRGB image differs by "
          "more than 1 code from the render with every skip on. Work saved: the renderer's work "
          "counter (RenderStats) the skip lowers most, deterministic where the times are not. A "
          "skip saves time on a scene when it is more than 2% faster there and lowers a work "
          "counter: on a busy shared machine the times of identical renders can differ by far "
          "more than 2%, so a time alone does not count.\n\n"
          "| skip | render | scene | on s | off s | saving | work saved | pixels > 1 code | max "
          "codes |\n"
          "|---|---|---|---|---|---|---|---|---|\n";
    std::vector<std::string> verdicts;
    for (const RenderSkipSwitch& skip : kRenderSkipSwitches) {
        bool savesSomewhere = false;
        bool imageKept = true;
        for (const auto& [renderName, render] : skipRenders)
            for (const SpeedScene& s : scenes) {
                const SpeedRow* r = findRow(rows, "skip", s.id, skipRowName(skip, renderName));
                const double saving = 1.0 - r->seconds / r->comparedSeconds;
                savesSomewhere =
                    savesSomewhere || (saving > kSavingThreshold && r->workSavedShare > 0.0);
                imageKept = imageKept && r->differingShare <= kMaxDifferingShare;
                md << "| " << skip.name << " | " << renderName << " | " << s.id << " " << s.name
                   << " | " << fixed(r->seconds, 4) << " | " << fixed(r->comparedSeconds, 4)
                   << " | " << fixed(100.0 * saving, 1) << "% | " << r->workCounter
                   << (r->workSavedShare > 0.0 ? " -" + fixed(100.0 * r->workSavedShare, 1) + "%"
                                               : "")
                   << " | " << fixed(100.0 * r->differingShare, 4) << "% | "
                   << fixed(r->maxDifferenceCodes, 0) << " |\n";
            }
        verdicts.push_back(verdict(savesSomewhere && imageKept) + " skip " + skip.name + " (" +
                           skip.skipped + "): " +
                           (savesSomewhere ? "saves time (> 2%, less work) on at least one scene"
                                           : "saves no time (> 2% with less work) on any scene") +
                           ", " +
                           (imageKept ? "image within 1 code in 99.9% of pixels everywhere"
                                      : "image differs by more than 1 code in over 0.1% of "
                                        "pixels somewhere"));
    }
    if (const SpeedRow* r = findRow(rows, "cache", "S1", "bake cache")) {
        md << "\nBake cache: S1 loaded from a warm cache in " << fixed(r->seconds, 4)
           << " s (fastest of " << runs << "), baked with caching off in "
           << fixed(r->comparedSeconds, 3) << " s (one run); " << r->note << ".\n";
        verdicts.push_back(verdict(r->seconds < r->comparedSeconds && r->maxDifferenceCodes == 0) +
                           " bake cache: warm load " + fixed(r->comparedSeconds / r->seconds, 1) +
                           "x faster than baking, " + r->note);
    }

    const SpeedRow& threadRow =
        *findRow(rows, "threads", "S1", "1 thread against " + std::to_string(threads));
    md << "\n## D. Threads\n\nS1 (shadows on) on 1 thread against " << threads
       << " threads: " << threadRow.note << " (pixels > 1 code "
       << fixed(100.0 * threadRow.differingShare, 4) << "%, max "
       << fixed(threadRow.maxDifferenceCodes, 0) << " codes).\n";

    md << "\n## E. Curved shells (the curved march against the planar one, each against the world "
          "reference)\n\n"
          "Errors from renders as the peers' in A (no shadows), AOVs on. Times without AOVs "
          "(filling them costs both shell maps alike): without shadows (the march's own cost), "
          "the default render (shadows on: the verdict's, the cost a user sees), and each kind of "
          "its shadow work alone (shadow maps, self-shadow rays). Each time the fastest of "
       << runs
       << " runs, curved and planar alternated after one untimed warm-up render. Errors against "
          "the "
          "world reference of the same scene at the same size (render/world_reference.h: the "
          "detail mapped through the curved shell into world space and traced there; one run, "
          "its build included in its time), in texels. Interior: the pixels where both hit, away "
          "from silhouettes and depth jumps (render/compare.h); all: every pixel where both hit."
       << (arguments.quick && !sizeGiven
               ? " With --quick the images are a quarter of the scene's size per side."
               : "")
       << "\n\n| scene | image | render | time s | curved / planar | interior mean | interior "
          "p99 | all mean | all p99 | coverage mismatch | normal deg, interior | normal deg, all "
          "|\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    std::vector<std::string> curvedVerdicts;
    for (const CurvedShellScene& s : curvedScenes) {
        const SpeedRow* times = findRow(rows, kCurvedSection, s.id, "curved against planar");
        const SpeedRow* shaded =
            findRow(rows, kCurvedSection, s.id, "curved against planar, default render");
        const SpeedRow* reference = findRow(rows, kCurvedSection, s.id, "world reference");
        const double ratio = shaded->seconds / shaded->comparedSeconds;
        const double unshadedRatio = times->seconds / times->comparedSeconds;
        std::string image = std::to_string(times->width) + "x" + std::to_string(times->height);
        if (times->width != s.image.width || times->height != s.image.height)
            image += " (" + std::string(arguments.quick && !sizeGiven ? "--quick; " : "") +
                     "the scene's: " + std::to_string(s.image.width) + "x" +
                     std::to_string(s.image.height) + ")";
        for (const char* what : {"curved", "planar"}) {
            const SpeedRow* r = findRow(rows, kCurvedSection, s.id,
                                        std::string(what) + " against the world reference");
            const bool isCurved = what == std::string("curved");
            md << "| " << s.id << " " << s.name << " | " << image << " | " << what << " | "
               << fixed(isCurved ? times->seconds : times->comparedSeconds, 4) << " | "
               << (isCurved ? fixed(unshadedRatio, 3) : "") << " | "
               << fixed(r->interiorMeanHitErrorTexels, 4) << " | "
               << fixed(r->interiorP99HitErrorTexels, 3) << " | " << fixed(r->meanHitErrorTexels, 4)
               << " | " << fixed(r->p99HitErrorTexels, 3) << " | "
               << fixed(100.0 * r->coverageMismatchShare, 4) << "% | "
               << fixed(r->interiorMeanNormalErrorDeg, 2) << " | "
               << fixed(r->meanNormalErrorDeg, 2) << " |\n";
        }
        const SpeedRow* maps =
            findRow(rows, kCurvedSection, s.id, "curved against planar, shadow maps only");
        const SpeedRow* self =
            findRow(rows, kCurvedSection, s.id, "curved against planar, self-shadows only");
        for (const auto& [render, r] :
             {std::pair{"default render (shadows)", shaded}, std::pair{"shadow maps only", maps},
              std::pair{"self-shadows only", self}}) {
            md << "| " << s.id << " " << s.name << " | " << image << " | curved, " << render
               << " | " << fixed(r->seconds, 4) << " | "
               << fixed(r->seconds / r->comparedSeconds, 3) << " | | | | | | | |\n";
            md << "| " << s.id << " " << s.name << " | " << image << " | planar, " << render
               << " | " << fixed(r->comparedSeconds, 4) << " | | | | | | | | |\n";
        }
        md << "| " << s.id << " " << s.name << " | " << image << " | world reference | "
           << fixed(reference->seconds, 2) << " | | | | | | | | |\n";
        const SpeedRow* curved =
            findRow(rows, kCurvedSection, s.id, "curved against the world reference");
        curvedVerdicts.push_back(verdict(ratio <= kMaxCurvedOverPlanar) + " " + s.id +
                                 " curved / planar = " + fixed(ratio, 3) +
                                 " for the default render (<= " + fixed(kMaxCurvedOverPlanar, 1) +
                                 "); without shadows " + fixed(unshadedRatio, 3) +
                                 " (the march's own cost), shadow maps alone " +
                                 fixed(maps->seconds / maps->comparedSeconds, 3) +
                                 ", self-shadows alone " +
                                 fixed(self->seconds / self->comparedSeconds, 3));
        const bool accurate = curved->interiorMeanHitErrorTexels <= kMaxCurvedInteriorMeanTexels &&
                              curved->interiorP99HitErrorTexels <= kMaxCurvedInteriorP99Texels &&
                              curved->coverageMismatchShare <= kMaxCurvedCoverageMismatch &&
                              curved->interiorMeanNormalErrorDeg <= kMaxCurvedInteriorNormalDeg;
        curvedVerdicts.push_back(
            verdict(accurate) + " " + s.id + " curved against the world reference at " +
            std::to_string(times->width) + "x" + std::to_string(times->height) +
            ": interior mean " + fixed(curved->interiorMeanHitErrorTexels, 4) +
            " texel (<= " + fixed(kMaxCurvedInteriorMeanTexels, 1) + "), interior p99 " +
            fixed(curved->interiorP99HitErrorTexels, 3) +
            " (<= " + fixed(kMaxCurvedInteriorP99Texels, 0) + "), coverage mismatch " +
            fixed(100.0 * curved->coverageMismatchShare, 4) +
            "% (<= " + fixed(100.0 * kMaxCurvedCoverageMismatch, 1) + "%), interior normal " +
            fixed(curved->interiorMeanNormalErrorDeg, 2) +
            " deg (<= " + fixed(kMaxCurvedInteriorNormalDeg, 0) + ")");
    }
    md << "\n";
    for (const std::string& v : curvedVerdicts) md << "- " << v << "\n";

    // Verdicts, one per acceptance point.
    std::vector<std::string> acceptance;
    if (embreeRow) {
        const double ratio = embreeRow->seconds / embreeRow->comparedSeconds;
        acceptance.push_back(verdict(ratio <= 1.0) + " distile / Embree = " + fixed(ratio, 3) +
                             " (target <= 1.0; goal 0.5: " + (ratio <= 0.5 ? "met" : "not met") +
                             ")");
    } else {
        acceptance.push_back("not measured: distile / Embree (peers not run or unavailable)");
    }
    if (vdbRow) {
        const double ratio = vdbRow->comparedSeconds / vdbRow->seconds;
        acceptance.push_back(verdict(ratio >= 10.0) + " vdb_render / distile = " + fixed(ratio, 2) +
                             " (target >= 10)");
    } else {
        acceptance.push_back("not measured: vdb_render / distile (peers not run or unavailable)");
    }
    acceptance.push_back(
        verdict(errorRow->meanHitErrorTexels <= 0.25 && errorRow->coverageMismatchShare <= 0.005) +
        " S1 error: mean hit " + fixed(errorRow->meanHitErrorTexels, 4) +
        " texel (<= 0.25), coverage mismatch " + fixed(100.0 * errorRow->coverageMismatchShare, 4) +
        "% (<= 0.5%)");
    {
        const SpeedRow* r = findRow(rows, "repetition", "S2", "S2 / S1, no shadows");
        const double ratio = r->seconds / r->comparedSeconds;
        const bool sameTile = findRow(rows, "memory", "S2", "distile tile")->bytes == tileBytes;
        acceptance.push_back(verdict(ratio <= 1.3 && sameTile) + " repetition: S2 / S1 = " +
                             fixed(ratio, 3) + " (<= 1.3), tile memory " +
                             (sameTile ? "the same (" + mib(tileBytes) + ")" : "DIFFERS"));
    }
    for (const std::string& v : verdicts) acceptance.push_back(v);
    for (const std::string& v : curvedVerdicts) acceptance.push_back(v);
    acceptance.push_back(verdict(threadRow.note == "bit-identical") + " threads: 1 thread and " +
                         std::to_string(threads) + " give " + threadRow.note + " images");
    md << mainJob.markdown;
    for (const std::string& v : mainJob.verdicts) acceptance.push_back(v);
    md << "\n## Verdicts\n\n";
    for (const std::string& v : acceptance) md << "- " << v << "\n";
    if (!notes.empty()) {
        md << "\n## Notes\n\n";
        for (const std::string& note : notes) md << "- " << note << "\n";
    }
    writeText(arguments.outputDir / "speed.md", md.str());
    for (const std::string& v : acceptance) say("  " + v);
    say("bench --speed: wrote " + fs::absolute(arguments.outputDir / "speed.md").string() +
        ", speed.csv, scenes/");
}

}  // namespace distile::cli
