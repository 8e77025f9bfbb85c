// The `distile` command: bake and render. Thin: parses the command line, fills the libraries'
// option structs, calls them, reports. Errors become one line on stderr and a non-zero exit.

#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>

#include "cli/progress_bar.h"
#include "cli/scene_json.h"
#include "common/error.h"
#include "render/renderer.h"
#include "sampler/bake.h"
#include "sampler/tile_io.h"

namespace fs = std::filesystem;

namespace distile::cli {
namespace {

constexpr int kExitInput = 2;  ///< bad input: arguments, files, scenes
constexpr int kExitFailure = 1;

Size3 parseSizeArgument(const std::string& text) {
    Size3 size{0, 0, 0};
    char x1 = 0, x2 = 0;
    std::string rest;
    std::istringstream in(text);
    if (!(in >> size.width >> x1 >> size.height >> x2 >> size.depth) || x1 != 'x' || x2 != 'x' || (in >> rest)) {
        throw InputError("--size: '" + text + "' is not a size; write WxHxD, e.g. 256x256x16");
    }
    validateTileSize(size, "--size");
    return size;
}

std::string lowerExtension(const fs::path& path) {
    std::string extension = path.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
    return extension;
}

/// Checked before any work, so a bad output path costs nothing and leaves nothing.
void requireOutput(const fs::path& path, const std::string& option, std::initializer_list<const char*> extensions) {
    const std::string extension = lowerExtension(path);
    bool accepted = false;
    std::string list;
    for (const char* candidate : extensions) {
        accepted = accepted || extension == candidate;
        list += std::string(list.empty() ? "" : ", ") + candidate;
    }
    if (!accepted) {
        throw InputError(option + ": '" + path.string() + "' has extension '" + extension + "'; accepted: " + list);
    }
    const fs::path folder = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (!fs::is_directory(folder)) {
        throw InputError(option + ": folder '" + folder.string() + "' of '" + path.string() + "' does not exist");
    }
}

struct BakeArguments {
    std::string detail;
    fs::path output;
    std::string size = "256x256x16";
    fs::path vdbOutput;
    bool half = false;
    float halfBandTexels = 0.0f;
    ChainmailOptions chainmail;
};

int runBake(const BakeArguments& arguments) {
    if (arguments.detail != "chainmail") {
        throw InputError("bake: '" + arguments.detail + "' is not a known detail; accepted: chainmail");
    }
    BakeOptions options;
    options.size = parseSizeArgument(arguments.size);
    options.halfBandTexels = arguments.halfBandTexels;
    requireOutput(arguments.output, "-o", {".exr"});
    if (!arguments.vdbOutput.empty()) requireOutput(arguments.vdbOutput, "--vdb", {".vdb"});

    const auto start = std::chrono::steady_clock::now();
    std::optional<BakeResult> result;
    {
        ProgressBar progress("bake chainmail " + toString(options.size));
        result.emplace(bakeChainmail(arguments.chainmail, options, std::ref(progress)));
    }
    writeTileExr(result->tile, arguments.output, arguments.half ? TileStorage::Half16 : TileStorage::Float32);
    std::printf("tile %s (%s, %s) written to %s\n", toString(options.size).c_str(), arguments.detail.c_str(),
                arguments.half ? "half" : "float", arguments.output.c_str());
    if (!arguments.vdbOutput.empty()) {
        result->levelSet.save(arguments.vdbOutput);
        std::printf("level set (%zu active voxels, half band %.1f texels) written to %s\n",
                    result->levelSet.activeVoxelCount(), result->levelSet.halfBandTexels(),
                    arguments.vdbOutput.c_str());
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("baked in %.2f s\n", seconds);
    return 0;
}

struct RenderArguments {
    fs::path scene;
    fs::path output;
    std::optional<int> width;
    std::optional<int> height;
    std::optional<int> samplesPerPixel;
    RenderOptions options;
    bool noShadows = false;
};

int runRender(RenderArguments arguments) {
    requireOutput(arguments.output, "-o", {".png", ".exr", ".tif", ".tiff"});
    TileCache tiles;
    SceneFile sceneFile = arguments.scene.empty() ? demoScene(tiles) : loadSceneFile(arguments.scene, tiles);
    RenderOptions& options = arguments.options;
    options.width = arguments.width.value_or(sceneFile.image.width);
    options.height = arguments.height.value_or(sceneFile.image.height);
    options.samplesPerPixel = arguments.samplesPerPixel.value_or(sceneFile.image.samplesPerPixel);
    options.selfShadows = !arguments.noShadows;

    const auto start = std::chrono::steady_clock::now();
    RenderStats stats;
    Image image;
    {
        ProgressBar progress("render " + std::to_string(options.width) + "x" + std::to_string(options.height));
        image = renderScene(sceneFile.scene, options, &stats, std::ref(progress));
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    writeImage(image, arguments.output);
    std::printf("rendered %s (%dx%d, %d spp) in %.2f s: %llu rays, %.1f%% on detail shells, mean %.2f "
                "iterations, %.1f%% converged within %d\n",
                arguments.scene.empty() ? "the demo scene" : arguments.scene.c_str(), options.width, options.height,
                options.samplesPerPixel, seconds, static_cast<unsigned long long>(stats.rays),
                stats.rays ? 100.0 * double(stats.baseHits) / double(stats.rays) : 0.0, stats.meanIterations(),
                stats.baseHits ? 100.0 * double(stats.converged) / double(stats.baseHits) : 0.0,
                options.maxIterations);
    std::printf("image written to %s\n", fs::absolute(arguments.output).c_str());
    return 0;
}

int run(int argc, char** argv) {
    CLI::App app{
        "distile: volumetric distance detail. Bakes detail (chain mail, ...) into exact, periodic distance tiles\n"
        "(OpenVDB level set -> 256x256x16 EXR atlas) and renders them on base meshes with a CPU sphere tracer.\n"};
    app.name("distile");
    app.require_subcommand(1);
    int threads = 0;
    app.add_option("--threads", threads, "Worker threads (default: all cores)")->check(CLI::Range(1, 1024));
    app.set_version_flag("--version", "distile 0.1.0");

    BakeArguments bake;
    CLI::App* bakeCommand = app.add_subcommand("bake", "Bake detail into a distance tile (EXR atlas) and optionally a level set (.vdb)");
    bakeCommand->add_option("detail", bake.detail, "What to bake: chainmail")->required();
    bakeCommand->add_option("-o,--output", bake.output, "Tile file to write (.exr)")->required();
    bakeCommand->add_option("--size", bake.size, "Tile size WxHxD in texels")->capture_default_str();
    bakeCommand->add_option("--vdb", bake.vdbOutput, "Also write the narrow-band level set (.vdb, texel units)");
    bakeCommand->add_flag("--half", bake.half, "Store half floats instead of 32-bit floats");
    bakeCommand->add_option("--band", bake.halfBandTexels, "Half width of the level set's narrow band in texels (default: tile depth)");
    auto* chainmail = bakeCommand->add_option_group("chainmail", "European 4-in-1 chain mail (defaults fill 256x256x16)");
    chainmail->add_option("--rings-per-row", bake.chainmail.ringsPerRow, "Rings along x per tile")->capture_default_str();
    chainmail->add_option("--rows", bake.chainmail.rowsPerTile, "Rows along y per tile (even)")->capture_default_str();
    chainmail->add_option("--ring-radius", bake.chainmail.ringRadiusSpacings, "Ring centreline radius, in ring spacings")->capture_default_str();
    chainmail->add_option("--wire-radius", bake.chainmail.wireRadiusSpacings, "Wire radius, in ring spacings")->capture_default_str();
    chainmail->add_option("--tilt", bake.chainmail.tiltDeg, "Ring tilt about y, degrees")->capture_default_str();

    RenderArguments render;
    CLI::App* renderCommand = app.add_subcommand("render", "Render a scene (JSON, see DESIGN.md) or, without one, the built-in demo");
    renderCommand->add_option("scene", render.scene, "Scene file (.json); omit for the demo scene");
    renderCommand->add_option("-o,--output", render.output, "Image to write (.png, .exr, .tif)")->required();
    renderCommand->add_option("--width", render.width, "Image width in pixels (default: the scene's, else 1280)")->check(CLI::Range(1, 16384));
    renderCommand->add_option("--height", render.height, "Image height in pixels (default: the scene's, else 1024)")->check(CLI::Range(1, 16384));
    renderCommand->add_option("--spp", render.samplesPerPixel, "Samples per pixel (default: the scene's, else 1)")->check(CLI::Range(1, 256));
    renderCommand->add_option("--iterations", render.options.maxIterations, "Sphere-tracing budget per ray")->capture_default_str()->check(CLI::Range(1, 4096));
    renderCommand->add_option("--epsilon", render.options.epsilonTexels, "Hit threshold in texels")->capture_default_str();
    renderCommand->add_flag("--no-shadows", render.noShadows, "Skip self-shadow rays");

    try {
        app.parse(argc, argv);
    } catch (const CLI::Success& success) {  // --help, --version
        return app.exit(success);
    } catch (const CLI::ParseError& error) {
        std::fprintf(stderr, "distile: error: %s (see distile --help)\n", error.what());
        return kExitInput;
    }
    std::optional<tbb::global_control> threadLimit;
    if (threads > 0) threadLimit.emplace(tbb::global_control::max_allowed_parallelism, std::size_t(threads));

    if (bakeCommand->parsed()) return runBake(bake);
    return runRender(render);
}

}  // namespace
}  // namespace distile::cli

int main(int argc, char** argv) {
    try {
        return distile::cli::run(argc, argv);
    } catch (const distile::InputError& error) {
        std::fprintf(stderr, "distile: error: %s\n", error.what());
        return distile::cli::kExitInput;
    } catch (const distile::FormatError& error) {
        std::fprintf(stderr, "distile: error: %s\n", error.what());
        return distile::cli::kExitInput;
    } catch (const std::exception& error) {
        std::fprintf(stderr, "distile: error: %s\n", error.what());
        return distile::cli::kExitFailure;
    }
}
