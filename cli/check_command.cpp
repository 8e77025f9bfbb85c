// distile check: how far a tile is from the truth (analytic, mesh or level set).
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <vector>

#include "check/reports.h"
#include "check/tile_check.h"
#include "cli/app.h"
#include "cli/arguments.h"
#include "cli/commands.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "sampler/tile_io.h"
#include "view/contact_sheet.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

struct CheckArguments {
    fs::path tile;
    /// --against (empty unless given: it overrides the tile's recorded source) and the others.
    TileCheckOptions options;
    bool json = false;
    std::vector<double> meshOffset;
    fs::path plot;  ///< --plot: where the error lies, as a contact sheet (.png)
};

}  // namespace

namespace {

void printReport(const CheckArguments& arguments, const TileCheckOptions& options,
                 const TileCheck& check) {
    const TileErrorReport& report = check.report;
    const std::string& against = check.against;
    const double bandTexels = check.bandTexels;
    const bool bandDeclared = check.bandDeclared;
    if (arguments.json) {
        const nlohmann::json out = tileCheckJson(check, options, arguments.tile.string());
        std::printf("%s\n", reportText(out).c_str());
        return;
    }
    std::printf("%s against %s, %d samples (seed %llu), trilinear, texels:\n",
                arguments.tile.c_str(), against.c_str(), report.samples,
                static_cast<unsigned long long>(options.seed));
    std::printf("  near surface (|d| <= 2, %d samples): max %.4f  RMS %.4f  p99.9 %.4f\n",
                report.nearSamples, report.nearMaxAbsTexels, report.nearRmsTexels,
                report.nearP999Texels);
    std::printf(
        "  overall: max %.4f at (%.2f, %.2f, %.2f) where the true distance is %.3f  RMS %.4f\n",
        report.maxAbsTexels, report.maxAbsAt.x, report.maxAbsAt.y, report.maxAbsAt.z,
        report.maxAbsTruthTexels, report.rmsTexels);
    std::printf(
        "  overestimates beyond %.3f: %d (%.4f%%), largest %.4f; sign errors (|d| > 1): %d\n",
        options.maxOverestimateTexels, report.overestimates, 100.0 * report.overestimateShare,
        report.maxOverestimateTexels, report.signErrors);
    std::printf(
        "    of them where a sphere tracer could step over the surface (tile above max(truth, 0)): "
        "%d, largest %.4f\n",
        report.tracerOverestimates, report.maxTracerOverestimateTexels);
    std::printf(
        "  band +-%g texels (%s): the truth is clamped to it; %.1f%% of the samples lie "
        "inside it\n",
        bandTexels, bandDeclared ? "declared by the tile" : "not declared: the tile depth",
        100.0 * report.bandShare);
    if (check.passed()) {
        std::printf("passed\n");
    } else {
        for (const std::string& failure : check.failures)
            std::printf("FAILED: %s\n", failure.c_str());
    }
}

void runCheck(const CheckArguments& arguments) {
    OutputFiles outputs;
    fs::path plot;
    if (!arguments.plot.empty()) {
        requireOutput(arguments.plot, "--plot", {".png"});
        plot = outputs.add(arguments.plot, "--plot");
    }
    const Tile tile = readTileExr(arguments.tile);
    TileCheckOptions options = arguments.options;
    if (!arguments.meshOffset.empty()) {
        if (arguments.meshOffset.size() != 3)
            throw InputError("--offset: give three numbers X,Y,Z (texels)");
        options.meshOffsetTexels = {arguments.meshOffset[0], arguments.meshOffset[1],
                                    arguments.meshOffset[2]};
    }
    TileCheck check;
    try {
        check = checkTile(tile, arguments.tile.string(), arguments.tile, options);
    } catch (const InputError& error) {
        throw shownUnder(error, {{"against", "--against"},
                                 {"samples", "--samples"},
                                 {"maxOverestimateTexels", "--max-overestimate"},
                                 {"meshScale", "--scale"},
                                 {"meshOffsetTexels", "--offset"}});
    }
    printReport(arguments, options, check);
    if (!plot.empty()) {
        const bool labelled = writeTileErrorPlot(tile, check.truth, check.bandTexels, plot);
        outputs.commit();
        if (!labelled) {
            std::fprintf(stderr,
                         "distile: warning: --plot: the labels were left out: no DejaVu "
                         "Sans font (Debian: fonts-dejavu-core)\n");
        }
        if (!arguments.json)
            std::printf("error plot (tile - truth per texel) written to %s\n",
                        arguments.plot.c_str());
    }
    if (!check.passed()) {
        std::fflush(stdout);
        std::exit(kExitFailure);  // a tolerance is exceeded: the work failed (cli/app.h)
    }
}

}  // namespace

void addCheckCommand(CLI::App& app) {
    auto arguments = std::make_shared<CheckArguments>();
    CLI::App* command = app.add_subcommand("check",
                                           "Sample a tile (trilinear) against the truth and report "
                                           "its error in texels; exit 1 when a tolerance "
                                           "is exceeded");
    command->add_option("tile", arguments->tile, "Tile file (.exr)")->required();
    command->add_option(
        "--against", arguments->options.against,
        "Truth: analytic (from the tile's distile:source/params), a mesh file "
        "(OBJ, PLY, OFF, STL; placed as `bake mesh` does) or a level set (.vdb). "
        "Default: the analytic truth, or for a tile baked from a mesh, a height map or a .vdb "
        "file that file (its recorded distile:source_file, placed as it was baked)");
    // Time and memory grow linearly: 10^7 points take ~5 s and ~400 MB.
    command
        ->add_option("--samples", arguments->options.samples,
                     "Uniform random sample points, at most 10^7 (~5 s, ~400 MB)")
        ->capture_default_str()
        ->check(integerRange(1, 10000000));
    command->add_option("--seed", arguments->options.seed, "Seed of the sample points")
        ->capture_default_str()
        ->check(CLI::Validator(
            [](const std::string& text) {
                std::uint64_t seed = 0;
                const auto [end, error] =
                    std::from_chars(text.data(), text.data() + text.size(), seed);
                return error == std::errc() && end == text.data() + text.size() && !text.empty()
                           ? std::string()
                           : "'" + text + "' is not accepted; give an integer in [0, 2^64 - 1]";
            },
            "SEED"));
    command->add_flag("--json", arguments->json, "Print the report as one JSON object");
    command->add_option("--plot", arguments->plot,
                        "Also draw where the error lies: tile - truth at every texel, slice by "
                        "slice (.png; red: the tile overestimates)");
    command
        ->add_option(
            "--max-overestimate", arguments->options.maxOverestimateTexels,
            "Overestimate tolerance, texels: tile - truth above it counts as an overestimate "
            "(more than 2 texels inside the detail the truth counts as -2: the tile need only "
            "read that deep there)")
        ->capture_default_str()
        ->check(finiteRange(0.0, 1e6));
    command
        ->add_option("--max-overestimate-share", arguments->options.maxOverestimateShare,
                     "Largest accepted share of overestimates (0.001 = 0.1%)")
        ->capture_default_str()
        ->check(finiteRange(0.0, 1.0));
    command
        ->add_option("--max-rms", arguments->options.maxRmsTexels,
                     "Largest accepted RMS error, texels")
        ->capture_default_str()
        ->check(finiteRange(0.0, 1e6));
    command
        ->add_option("--max-tracer-overestimate", arguments->options.maxTracerOverestimateTexels,
                     "Largest accepted step past the surface, texels: tile - max(truth, 0) at any "
                     "sample (a local error, such as a damaged texel, the share above misses)")
        ->capture_default_str()
        ->check(finiteRange(0.0, 1e6));
    command
        ->add_option("--max-near-error", arguments->options.maxNearErrorTexels,
                     "Largest accepted error within 2 texels of the surface (default: not checked)")
        ->check(finiteRange(0.0, 1e6));
    command->add_flag("--allow-sign-errors", arguments->options.allowSignErrors,
                      "Do not fail on sign errors (samples more than 1 texel from the surface with "
                      "the wrong sign)");
    command->add_option("--scale", arguments->options.meshScale,
                        "A mesh given with --against: explicit placement, texels per file unit");
    command
        ->add_option("--offset", arguments->meshOffset,
                     "A mesh given with --against: explicit placement, offset X,Y,Z (or X Y Z) in "
                     "texels")
        ->expected(3)
        ->delimiter(',');
    command->callback([arguments, command] { runCheck(*arguments); });
}

}  // namespace distile::cli
