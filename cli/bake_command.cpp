// distile bake: detail -> level set (.vdb) -> tile (.exr).
#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>

#include "cli/arguments.h"
#include "cli/commands.h"
#include "cli/progress_bar.h"
#include "common/error.h"
#include "sampler/bake.h"
#include "sampler/tile_io.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

struct BakeArguments {
    std::string detail;
    fs::path output;
    std::string size = "256x256x16";
    fs::path vdbOutput;
    bool half = false;
    float halfBandTexels = 0.0f;
    ChainmailOptions chainmail;
};

void runBake(const BakeArguments& arguments) {
    if (arguments.detail != "chainmail") {
        throw InputError("bake: '" + arguments.detail + "' is not a known detail; accepted: chainmail");
    }
    BakeOptions options;
    options.size = parseSize(arguments.size, "--size");
    options.halfBandTexels = arguments.halfBandTexels;
    requireOutput(arguments.output, "-o", {".exr"});
    if (!arguments.vdbOutput.empty()) requireOutput(arguments.vdbOutput, "--vdb", {".vdb"});

    const auto start = std::chrono::steady_clock::now();
    std::optional<BakeResult> result;
    {
        ProgressBar progress("bake " + arguments.detail + " " + toString(options.size));
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
}

}  // namespace

void addBakeCommand(CLI::App& app) {
    auto arguments = std::make_shared<BakeArguments>();
    CLI::App* command = app.add_subcommand(
        "bake", "Bake detail into a distance tile (EXR atlas) and optionally its level set (.vdb)");
    command->add_option("detail", arguments->detail, "What to bake: chainmail")->required();
    command->add_option("-o,--output", arguments->output, "Tile file to write (.exr)")->required();
    command->add_option("--size", arguments->size, "Tile size WxHxD in texels")->capture_default_str();
    command->add_option("--vdb", arguments->vdbOutput, "Also write the narrow-band level set (.vdb, texel units)");
    command->add_flag("--half", arguments->half, "Store half floats instead of 32-bit floats");
    command->add_option("--band", arguments->halfBandTexels,
                        "Half width of the level set's narrow band in texels (default: the tile depth)");
    auto* chainmail = command->add_option_group("chainmail", "European 4-in-1 chain mail (defaults fill 256x256x16)");
    chainmail->add_option("--rings-per-row", arguments->chainmail.ringsPerRow, "Rings along x per tile")
        ->capture_default_str();
    chainmail->add_option("--rows", arguments->chainmail.rowsPerTile, "Rows along y per tile (even)")
        ->capture_default_str();
    chainmail->add_option("--ring-radius", arguments->chainmail.ringRadiusSpacings, "Ring centreline radius, in ring spacings")
        ->capture_default_str();
    chainmail->add_option("--wire-radius", arguments->chainmail.wireRadiusSpacings, "Wire radius, in ring spacings")
        ->capture_default_str();
    chainmail->add_option("--tilt", arguments->chainmail.tiltDeg, "Ring tilt about y, degrees")->capture_default_str();
    command->callback([arguments] { runBake(*arguments); });
}

}  // namespace distile::cli
