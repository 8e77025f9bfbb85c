// distile check: how far a tile is from the truth (analytic, mesh or level set).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <vector>

#include "bake/bake.h"
#include "bake/mesh_surface.h"
#include "bake/provenance.h"
#include "bake/resample.h"
#include "bake/soup_distance.h"
#include "bake/vdb_bake.h"
#include "cli/app.h"
#include "cli/arguments.h"
#include "cli/commands.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "mesh/detail_mesh.h"
#include "sampler/tile_error.h"
#include "sampler/tile_io.h"
#include "truth/mesh_truth.h"
#include "vdb/level_set.h"
#include "vdb/procedural.h"
#include "vdb/vdb_volume.h"
#include "view/contact_sheet.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

using nlohmann::json;

struct CheckArguments {
    fs::path tile;
    std::string against = "analytic";
    bool againstGiven = false;  ///< --against given: it overrides the tile's recorded source
    int samples = 100000;
    std::uint64_t seed = 1;
    bool json = false;
    double maxOverestimateTexels = 0.05;
    double maxOverestimateShare = 0.001;
    double maxRmsTexels = 0.1;
    std::optional<double> maxNearErrorTexels;
    bool allowSignErrors = false;
    std::optional<double> meshScale;
    std::vector<double> meshOffset;
    fs::path plot;  ///< --plot: where the error lies, as a contact sheet (.png)
};

}  // namespace

namespace {

void printReport(const CheckArguments& arguments, const std::string& against,
                 const TileErrorReport& report, double bandTexels, bool bandDeclared, bool passed,
                 const std::vector<std::string>& failures) {
    if (arguments.json) {
        json out = {{"tile", arguments.tile.string()},
                    {"against", against},
                    {"samples", report.samples},
                    {"seed", arguments.seed},
                    {"units", "texels"},
                    {"rms", report.rmsTexels},
                    {"max_abs", report.maxAbsTexels},
                    {"max_abs_at", {report.maxAbsAt.x, report.maxAbsAt.y, report.maxAbsAt.z}},
                    {"max_abs_true_distance", report.maxAbsTruthTexels},
                    {"near_surface_texels", 2.0},
                    {"near_samples", report.nearSamples},
                    {"near_rms", report.nearRmsTexels},
                    {"near_max_abs", report.nearMaxAbsTexels},
                    {"near_p999_abs", report.nearP999Texels},
                    {"overestimate_tolerance", arguments.maxOverestimateTexels},
                    {"overestimates", report.overestimates},
                    {"overestimate_share", report.overestimateShare},
                    {"max_overestimate", report.maxOverestimateTexels},
                    {"sign_errors", report.signErrors},
                    {"band", bandTexels},
                    {"band_declared", bandDeclared},
                    {"band_share", report.bandShare},
                    {"passed", passed},
                    {"failures", failures}};
        std::printf("%s\n", out.dump().c_str());
        return;
    }
    std::printf("%s against %s, %d samples (seed %llu), trilinear, texels:\n",
                arguments.tile.c_str(), against.c_str(), report.samples,
                static_cast<unsigned long long>(arguments.seed));
    std::printf("  near surface (|d| <= 2, %d samples): max %.4f  RMS %.4f  p99.9 %.4f\n",
                report.nearSamples, report.nearMaxAbsTexels, report.nearRmsTexels,
                report.nearP999Texels);
    std::printf(
        "  overall: max %.4f at (%.2f, %.2f, %.2f) where the true distance is %.3f  RMS %.4f\n",
        report.maxAbsTexels, report.maxAbsAt.x, report.maxAbsAt.y, report.maxAbsAt.z,
        report.maxAbsTruthTexels, report.rmsTexels);
    std::printf(
        "  overestimates beyond %.3f: %d (%.4f%%), largest %.4f; sign errors (|d| > 1): %d\n",
        arguments.maxOverestimateTexels, report.overestimates, 100.0 * report.overestimateShare,
        report.maxOverestimateTexels, report.signErrors);
    std::printf(
        "  band +-%g texels (%s): the truth is clamped to it; %.1f%% of the samples lie "
        "inside it\n",
        bandTexels, bandDeclared ? "declared by the tile" : "not declared: the tile depth",
        100.0 * report.bandShare);
    if (passed) {
        std::printf("passed\n");
    } else {
        for (const std::string& failure : failures) std::printf("FAILED: %s\n", failure.c_str());
    }
}

/// Whether `file` is a level set distile wrote (LevelSet::load reads it).
bool isDistileLevelSet(const fs::path& file) {
    try {
        LevelSet::load(file);
        return true;
    } catch (const FormatError&) {
        return false;
    }
}

/// The exact signed distance (texels, periodic) to a detail mesh placed in `tile`: CGAL's for a
/// closed mesh whose parts neither intersect nor nest (its inside test); otherwise, as the bake
/// measures open meshes and soups, the distance to the boundary of its inside (the triangles
/// that bound it and the caps over its holes), signed by the generalized winding number (inside
/// where it exceeds 1/2; bake/mesh_surface.h). A tile baked
/// `--unsigned` (distile:params "sign": "unsigned") compares with the unsigned distance minus half
/// its recorded thickness. `how` says which truth it is; `keepAlive` owns it.
std::function<double(const glm::dvec3&)> meshTruth(const TriangleSoup& placed, const Tile& tile,
                                                   std::shared_ptr<const void>& keepAlive,
                                                   std::string& how) {
    const nlohmann::json params =
        nlohmann::json::parse(tile.provenance.params, nullptr, /*allow_exceptions=*/false);
    const bool unsignedTile = params.is_object() && params.value("sign", "") == "unsigned";
    // Farther than any point of the tile's box can be from detail inside it.
    const double cutoff = double(tile.size().width + tile.size().height + tile.size().depth);
    if (unsignedTile) {
        const double thickness = params.is_object() && params.contains("thickness_texels") &&
                                         params["thickness_texels"].is_number()
                                     ? params["thickness_texels"].get<double>()
                                     : 0.0;
        auto soup = std::make_shared<const SoupDistance>(placed, tile.size());
        keepAlive = soup;
        how = "unsigned distance minus half the thickness";
        return [soup, cutoff, thickness](const glm::dvec3& p) {
            return soup->unsignedDistance(p, cutoff) - 0.5 * thickness;
        };
    }
    auto mesh = std::make_shared<const MeshDistance>(placed, MeshDistance::Periodic{tile.size()});
    auto surface = std::make_shared<const MeshSurfaceDistance>(placed, tile.size());
    if (insideTestSignsAlike(*mesh, surface->surface(), placed)) {
        keepAlive = mesh;
        how = "closed: CGAL's inside test";
        return [mesh](const glm::dvec3& p) { return mesh->signedDistance(p); };
    }
    keepAlive = surface;
    how = mesh->hasSign() ? "closed, its parts overlapping or nested: signed by its winding number"
                          : "not closed: signed by its winding number";
    if (const std::size_t trimmed = surface->surface().trimmedTriangles(); trimmed > 0)
        how += ", " + std::to_string(trimmed) + " triangles trimmed to the parts that bound it";
    const std::size_t caps = surface->surface().caps().triangles.size();
    if (caps > 0) how += ", its holes capped (" + std::to_string(caps) + " cap triangles)";
    return [surface, cutoff](const glm::dvec3& p) { return surface->signedDistance(p, cutoff); };
}

void runCheck(CheckArguments arguments) {
    OutputFiles outputs;
    fs::path plot;
    if (!arguments.plot.empty()) {
        requireOutput(arguments.plot, "--plot", {".png"});
        plot = outputs.add(arguments.plot, "--plot");
    }
    const Tile tile = readTileExr(arguments.tile);
    if (!arguments.againstGiven && tile.provenance.source == "vdb") {
        // The level set the tile was baked from (distile:source_file), placed as its params say.
        try {
            arguments.against =
                recordedSourceFile(tile, arguments.tile.string(), arguments.tile).string();
        } catch (const InputError& error) {
            throw InputError(std::string(error.what()) + "; pass --against FILE");
        }
    }
    const std::string tileName = arguments.tile.string();
    // The tile holds its level set's band: distances beyond it are clamped to +-band. The truth is
    // clamped to the band the tile declares, never to one read off its values (a flat tile would
    // then meet a flat truth). Tiles from before the declaration had the default band, the depth.
    const bool bandDeclared = tile.provenance.halfBandTexels > 0.0;
    const double bandTexels =
        bandDeclared ? tile.provenance.halfBandTexels : double(tile.size().depth);
    std::function<double(const glm::dvec3&)> truth;
    std::string against;
    // Keep the truth's owners alive while sampling.
    std::shared_ptr<const void> keepAlive;
    if (!arguments.againstGiven && tile.provenance.source == "mesh") {
        // The mesh the tile was baked from, placed as the bake placed it (distile:source_file,
        // distile:params).
        TriangleSoup placed;
        try {
            placed = sourceMeshPlaced(tile, tileName, arguments.tile);
        } catch (const InputError& error) {
            throw InputError(std::string(error.what()) + "; pass --against FILE");
        }
        std::string how;
        truth = meshTruth(placed, tile, keepAlive, how);
        against = "mesh " + tile.provenance.sourceFile.string() +
                  " (recorded source, placed as baked; " + how + ")";
    } else if (arguments.against == "analytic") {
        ProceduralOptions options;
        try {
            options = proceduralFromProvenance(tile.provenance, tileName);
        } catch (const InputError& error) {
            throw InputError(std::string(error.what()) + "; use --against MESH or LEVEL.vdb");
        }
        ProceduralDistance procedural;
        try {
            procedural = proceduralDistance(options, tile.size());
        } catch (const InputError& error) {
            throw FormatError(tileName + ": distile:params do not describe a valid pattern (" +
                              error.what() + ")");
        }
        truth = procedural.signedDistanceTexels;
        against = "analytic " + procedural.source + " " + procedural.paramsJson;
    } else if (lowerExtension(arguments.against) == ".vdb" && tile.provenance.source == "vdb" &&
               !isDistileLevelSet(arguments.against)) {
        // A tile of `bake vdb`: its source file placed as its params say, resampled at the texel
        // centres without the conservative lowering (as for distile's own level sets below).
        const VdbProvenance recorded = vdbFromProvenance(tile.provenance, tileName);
        const std::string& gridName = recorded.gridName;
        VdbPlacement explicitPlacement;
        explicitPlacement.mode = VdbPlacement::Mode::Explicit;
        explicitPlacement.scale = recorded.placement.scale;
        explicitPlacement.offsetTexels = recorded.placement.offsetTexels;
        BakeOptions exact;
        exact.size = tile.size();
        exact.halfBandTexels = float(bandTexels);
        exact.conservative.enabled = false;
        std::shared_ptr<const Tile> grid;
        try {
            grid = std::make_shared<const Tile>(
                bakeVdb(VdbVolume::read(arguments.against, gridName, recorded.iso),
                        explicitPlacement, exact, arguments.against)
                    .bake.tile);
        } catch (const InputError& error) {
            throw InputError("--against: " + std::string(error.what()));
        }
        keepAlive = grid;
        truth = [grid, filter = TrilinearFilter(*grid)](const glm::dvec3& p) {
            return double(filter.distanceTexels(glm::vec3(p)));
        };
        against = "level set " + arguments.against + " grid '" + gridName +
                  "' as placed by the bake (trilinear of its distances at the texel centres)";
    } else if (lowerExtension(arguments.against) == ".vdb") {
        const LevelSet levelSet = LevelSet::load(arguments.against);
        if (!(levelSet.tileSize() == tile.size())) {
            throw InputError("--against: level set '" + arguments.against + "' is " +
                             toString(levelSet.tileSize()) + " but the tile is " +
                             toString(tile.size()));
        }
        ConservativeOptions exact;
        exact.enabled = false;
        auto grid = std::make_shared<const Tile>(tileFromLevelSet(levelSet, exact));
        keepAlive = grid;
        truth = [grid, filter = TrilinearFilter(*grid)](const glm::dvec3& p) {
            return double(filter.distanceTexels(glm::vec3(p)));
        };
        against = "level set " + arguments.against + " (trilinear of its voxels)";
    } else {
        const TriangleSoup soup = loadDetailMesh(arguments.against);
        MeshPlacement placement;
        if (arguments.meshScale || !arguments.meshOffset.empty()) {
            placement.fit = false;
            placement.scale = arguments.meshScale.value_or(1.0);
            if (!arguments.meshOffset.empty()) {
                if (arguments.meshOffset.size() != 3)
                    throw InputError("--offset: give three numbers X Y Z (texels)");
                placement.offsetTexels = {arguments.meshOffset[0], arguments.meshOffset[1],
                                          arguments.meshOffset[2]};
            }
        }
        const TriangleSoup placed = placeMesh(soup, placement, tile.size());
        std::string how;
        truth = meshTruth(placed, tile, keepAlive, how);
        against = "mesh " + arguments.against +
                  (placement.fit ? " (fitted to the footprint; " : " (explicit placement; ") + how +
                  ")";
    }

    TileErrorOptions options;
    options.samples = arguments.samples;
    options.seed = arguments.seed;
    options.overestimateToleranceTexels = arguments.maxOverestimateTexels;
    options.truthClampTexels = bandTexels;
    TileErrorReport report;
    try {
        report = measureTileError(tile, truth, options);
    } catch (const InputError& error) {
        throw underFlag(error, {{"samples", "--samples"},
                                {"overestimateToleranceTexels", "--max-overestimate"}});
    }

    std::vector<std::string> failures;
    auto text = [](double value) {
        std::ostringstream out;
        out << value;
        return out.str();
    };
    if (report.overestimateShare > arguments.maxOverestimateShare) {
        failures.push_back("overestimates beyond " + text(arguments.maxOverestimateTexels) +
                           " texel in " + text(100.0 * report.overestimateShare) +
                           "% of samples (allowed " + text(100.0 * arguments.maxOverestimateShare) +
                           "%)");
    }
    if (report.rmsTexels > arguments.maxRmsTexels) {
        failures.push_back("RMS " + text(report.rmsTexels) + " texel (allowed " +
                           text(arguments.maxRmsTexels) + ")");
    }
    if (arguments.maxNearErrorTexels && report.nearMaxAbsTexels > *arguments.maxNearErrorTexels) {
        failures.push_back("max error near the surface " + text(report.nearMaxAbsTexels) +
                           " texel (allowed " + text(*arguments.maxNearErrorTexels) + ")");
    }
    if (report.signErrors > 0 && !arguments.allowSignErrors) {
        failures.push_back(std::to_string(report.signErrors) +
                           " sign errors more than 1 texel from the surface");
    }
    printReport(arguments, against, report, bandTexels, bandDeclared, failures.empty(), failures);
    if (!plot.empty()) {
        const bool labelled = writeTileErrorPlot(tile, truth, bandTexels, plot);
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
    if (!failures.empty()) {
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
    command
        ->add_option("--against", arguments->against,
                     "Truth: analytic (from the tile's distile:source/params), a mesh file "
                     "(OBJ, PLY, OFF, STL; placed as `bake mesh` does) or a level set (.vdb). "
                     "Default: the analytic truth, or for a tile baked from a mesh or a .vdb file "
                     "that file (its recorded distile:source_file, placed as it was baked)")
        ->capture_default_str();
    // Time and memory grow linearly: 10^7 points take ~5 s and ~400 MB.
    command
        ->add_option("--samples", arguments->samples,
                     "Uniform random sample points, at most 10^7 (~5 s, ~400 MB)")
        ->capture_default_str()
        ->check(CLI::Range(1, 10000000));
    command->add_option("--seed", arguments->seed, "Seed of the sample points")
        ->capture_default_str();
    command->add_flag("--json", arguments->json, "Print the report as one JSON object");
    command->add_option("--plot", arguments->plot,
                        "Also draw where the error lies: tile - truth at every texel, slice by "
                        "slice (.png; red: the tile overestimates)");
    command
        ->add_option(
            "--max-overestimate", arguments->maxOverestimateTexels,
            "Overestimate tolerance, texels: tile - truth above it counts as an overestimate")
        ->capture_default_str()
        ->check(finiteRange(0.0, 1e6));
    command
        ->add_option("--max-overestimate-share", arguments->maxOverestimateShare,
                     "Largest accepted share of overestimates (0.001 = 0.1%)")
        ->capture_default_str()
        ->check(finiteRange(0.0, 1.0));
    command->add_option("--max-rms", arguments->maxRmsTexels, "Largest accepted RMS error, texels")
        ->capture_default_str()
        ->check(finiteRange(0.0, 1e6));
    command
        ->add_option("--max-near-error", arguments->maxNearErrorTexels,
                     "Largest accepted error within 2 texels of the surface (default: not checked)")
        ->check(finiteRange(0.0, 1e6));
    command->add_flag("--allow-sign-errors", arguments->allowSignErrors,
                      "Do not fail on sign errors (samples more than 1 texel from the surface with "
                      "the wrong sign)");
    command->add_option("--scale", arguments->meshScale,
                        "Mesh truth: explicit placement, texels per file unit");
    command
        ->add_option("--offset", arguments->meshOffset,
                     "Mesh truth: explicit placement, offset X Y Z in texels")
        ->expected(3);
    command->callback([arguments, command] {
        arguments->againstGiven = command->count("--against") > 0;
        runCheck(*arguments);
    });
}

}  // namespace distile::cli
