#include "check/tile_check.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bake/bake.h"
#include "bake/height_image.h"
#include "bake/mesh_surface.h"
#include "bake/provenance.h"
#include "bake/resample.h"
#include "bake/soup_distance.h"
#include "bake/vdb_bake.h"
#include "common/error.h"
#include "common/input_file.h"
#include "mesh/detail_mesh.h"
#include "sampler/filters.h"
#include "truth/mesh_truth.h"
#include "vdb/height_field.h"
#include "vdb/level_set.h"
#include "vdb/procedural.h"
#include "vdb/vdb_volume.h"

namespace distile {

namespace fs = std::filesystem;

namespace {

/// The tile's own truth cannot be found (`error` says why): the caller must name one.
InputError noTruth(const InputError& error) {
    return InputError::inField("against",
                               "needed: " + std::string(error.what()) + "; give the truth's file");
}

/// Throws InputError::inField(field) unless `value` is a finite number in [0, highest].
void requireTolerance(const char* field, double value, double highest) {
    if (std::isfinite(value) && value >= 0.0 && value <= highest) return;
    std::ostringstream problem;
    problem << value << " is not accepted; give a finite number in [0, " << highest << "]";
    throw InputError::inField(field, problem.str());
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

/// The truth of a tile baked from a height map: the exact distance to the surface the bake
/// triangulated through its texel columns' heights (vdb/height_field.h), from the image it
/// records, negative below the surface.
std::function<double(const glm::dvec3&)> heightMapTruth(const Tile& tile,
                                                        const std::string& tileName,
                                                        const fs::path& tileFile,
                                                        std::shared_ptr<const void>& keepAlive,
                                                        std::string& how) {
    fs::path image;
    try {
        image = recordedSourceFile(tile, tileName, tileFile);
    } catch (const InputError& error) {
        throw noTruth(error);
    }
    const nlohmann::json params =
        nlohmann::json::parse(tile.provenance.params, nullptr, /*allow_exceptions=*/false);
    if (!params.is_object() || !params.contains("height_texels") ||
        !params["height_texels"].is_number()) {
        throw FormatError(tileName + ": distile:params '" + tile.provenance.params +
                          "' hold no height_texels, which a height-map tile records");
    }
    const double heightTexels = params["height_texels"].get<double>();
    HeightField field;
    try {
        field = heightFieldFromImage(readHeightImage(image), tile.size(), heightTexels);
    } catch (const InputError& error) {
        throw FormatError(tileName + ": its height map does not fit it (" + error.what() + ")");
    }
    const Size3 size = tile.size();
    auto surface = std::make_shared<const HeightFieldDistance>(
        std::move(field), double(size.width + size.height + size.depth));
    keepAlive = surface;
    std::ostringstream text;
    text << "height map " << tile.provenance.sourceFile.string() << " (recorded source, "
         << heightTexels << " texels high, triangulated through the texel columns)";
    how = text.str();
    return [surface, size](const glm::dvec3& p) {
        // Into the footprint: the field repeats.
        const glm::dvec3 wrapped(p.x - size.width * std::floor(p.x / size.width),
                                 p.y - size.height * std::floor(p.y / size.height), p.z);
        return surface->signedDistanceTexels(wrapped);
    };
}

}  // namespace

TileCheck checkTile(const Tile& tile, const std::string& tileName, const fs::path& tileFile,
                    const TileCheckOptions& options) {
    if (options.samples < 1 || options.samples > 10000000) {
        throw InputError::inField(
            "samples", std::to_string(options.samples) + " is not accepted; give 1 to 10^7 points");
    }
    requireTolerance("maxOverestimateTexels", options.maxOverestimateTexels, 1e6);
    requireTolerance("maxOverestimateShare", options.maxOverestimateShare, 1.0);
    requireTolerance("maxRmsTexels", options.maxRmsTexels, 1e6);
    requireTolerance("maxTracerOverestimateTexels", options.maxTracerOverestimateTexels, 1e6);
    if (options.maxNearErrorTexels)
        requireTolerance("maxNearErrorTexels", *options.maxNearErrorTexels, 1e6);
    const bool againstGiven = !options.against.empty();
    std::string againstFile = againstGiven ? options.against : "analytic";
    if (options.meshScale || options.meshOffsetTexels) {
        // Only a mesh given as the truth is placed by them; ignoring them elsewhere would measure
        // against a truth the user did not ask for.
        const std::string extension = lowerExtension(againstFile);
        if (extension != ".obj" && extension != ".ply" && extension != ".off" &&
            extension != ".stl") {
            throw InputError::inField(
                options.meshScale ? "meshScale" : "meshOffsetTexels",
                "places only a mesh given as the truth (against: .obj, .ply, .off, .stl); the "
                "truth here is " +
                    (againstGiven ? "'" + againstFile + "'"
                                  : std::string("the tile's own (its recorded source)")));
        }
    }
    if (!againstGiven && tile.provenance.source == "vdb") {
        // The level set the tile was baked from (distile:source_file), placed as its params say.
        try {
            againstFile = recordedSourceFile(tile, tileName, tileFile).string();
        } catch (const InputError& error) {
            throw noTruth(error);
        }
    }
    // The tile holds its level set's band: distances beyond it are clamped to +-band. The truth is
    // clamped to the band the tile declares, never to one read off its values (a flat tile would
    // then meet a flat truth). Tiles from before the declaration had the default band, the depth.
    TileCheck check;
    check.bandDeclared = tile.provenance.halfBandTexels > 0.0;
    check.bandTexels =
        check.bandDeclared ? tile.provenance.halfBandTexels : double(tile.size().depth);
    const double bandTexels = check.bandTexels;
    std::function<double(const glm::dvec3&)> truth;
    std::string& against = check.against;
    // Keep the truth's owners alive while sampling.
    std::shared_ptr<const void> keepAlive;
    if (!againstGiven && tile.provenance.source == "mesh") {
        // The mesh the tile was baked from, placed as the bake placed it (distile:source_file,
        // distile:params).
        TriangleSoup placed;
        try {
            placed = sourceMeshPlaced(tile, tileName, tileFile);
        } catch (const InputError& error) {
            throw noTruth(error);
        }
        std::string how;
        truth = meshTruth(placed, tile, keepAlive, how);
        against = "mesh " + tile.provenance.sourceFile.string() +
                  " (recorded source, placed as baked; " + how + ")";
    } else if (!againstGiven && tile.provenance.source == "heightmap") {
        truth = heightMapTruth(tile, tileName, tileFile, keepAlive, against);
    } else if (againstFile == "analytic") {
        ProceduralOptions pattern;
        try {
            pattern = proceduralFromProvenance(tile.provenance, tileName);
        } catch (const InputError& error) {
            throw noTruth(error);
        }
        ProceduralDistance procedural;
        try {
            procedural = proceduralDistance(pattern, tile.size());
        } catch (const InputError& error) {
            throw FormatError(tileName + ": distile:params do not describe a valid pattern (" +
                              error.what() + ")");
        }
        truth = procedural.signedDistanceTexels;
        against = "analytic " + procedural.source + " " + procedural.paramsJson;
    } else if (lowerExtension(againstFile) == ".vdb" && tile.provenance.source == "vdb" &&
               (!againstGiven || !isDistileLevelSet(againstFile))) {
        // A tile of `bake vdb`: its source file placed as its params say, resampled at the texel
        // centres without the conservative lowering (as for distile's own level sets below). The
        // recorded source is placed even when distile wrote it (a level set of another tile); a
        // distile level set given with --against is the tile's own (`bake vdb --vdb`).
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
                bakeVdb(VdbVolume::read(againstFile, gridName, recorded.iso), explicitPlacement,
                        exact, againstFile)
                    .bake.tile);
        } catch (const InputError& error) {
            throw InputError::inField("against", error.what());
        }
        keepAlive = grid;
        truth = [grid, filter = TrilinearFilter(*grid)](const glm::dvec3& p) {
            return double(filter.distanceTexels(glm::vec3(p)));
        };
        against = "level set " + againstFile + " grid '" + gridName +
                  "' as placed by the bake (trilinear of its distances at the texel centres)";
    } else if (lowerExtension(againstFile) == ".vdb") {
        const LevelSet levelSet = LevelSet::load(againstFile);
        if (!(levelSet.tileSize() == tile.size())) {
            throw InputError::inField("against", "level set '" + againstFile + "' is " +
                                                     toString(levelSet.tileSize()) +
                                                     " but the tile is " + toString(tile.size()));
        }
        ConservativeOptions exact;
        exact.enabled = false;
        auto grid = std::make_shared<const Tile>(tileFromLevelSet(levelSet, exact));
        keepAlive = grid;
        truth = [grid, filter = TrilinearFilter(*grid)](const glm::dvec3& p) {
            return double(filter.distanceTexels(glm::vec3(p)));
        };
        against = "level set " + againstFile + " (trilinear of its voxels)";
    } else {
        const std::string extension = lowerExtension(againstFile);
        if (extension != ".obj" && extension != ".ply" && extension != ".off" &&
            extension != ".stl") {
            throw InputError::inField(
                "against", "'" + againstFile +
                               "' is not a truth check reads; accepted: analytic, a level set "
                               "(.vdb) or a mesh (.obj, .ply, .off, .stl)");
        }
        const TriangleSoup soup = loadDetailMesh(againstFile);
        MeshPlacement placement;
        if (options.meshScale || options.meshOffsetTexels) {
            placement.fit = false;
            placement.scale = options.meshScale.value_or(1.0);
            if (const auto& offset = options.meshOffsetTexels)
                placement.offsetTexels = {(*offset)[0], (*offset)[1], (*offset)[2]};
        }
        TriangleSoup placed;
        try {
            placed = placeMesh(soup, placement, tile.size());
        } catch (const InputError& error) {
            if (error.field() == "placement.scale") throw error.renamed("meshScale");
            if (error.field() == "placement.offsetTexels") throw error.renamed("meshOffsetTexels");
            if (error.field() == "size") throw error.renamed("against");  // the mesh, fitted
            throw;
        }
        std::string how;
        truth = meshTruth(placed, tile, keepAlive, how);
        against = "mesh " + againstFile +
                  (placement.fit ? " (fitted to the footprint; " : " (explicit placement; ") + how +
                  ")";
    }

    TileErrorOptions errorOptions;
    errorOptions.samples = options.samples;
    errorOptions.seed = options.seed;
    errorOptions.overestimateToleranceTexels = options.maxOverestimateTexels;
    errorOptions.truthClampTexels = bandTexels;
    TileErrorReport& report = check.report;
    try {
        report = measureTileError(tile, truth, errorOptions);
    } catch (const InputError& error) {
        if (error.field() == "overestimateToleranceTexels")
            throw error.renamed("maxOverestimateTexels");
        throw;
    }

    check.truth = [keepAlive, truth](const glm::dvec3& p) { return truth(p); };
    std::vector<std::string>& failures = check.failures;
    auto text = [](double value) {
        std::ostringstream out;
        out << value;
        return out.str();
    };
    if (report.overestimateShare > options.maxOverestimateShare) {
        failures.push_back("overestimates beyond " + text(options.maxOverestimateTexels) +
                           " texel in " + text(100.0 * report.overestimateShare) +
                           "% of samples (allowed " + text(100.0 * options.maxOverestimateShare) +
                           "%)");
    }
    if (report.rmsTexels > options.maxRmsTexels) {
        failures.push_back("RMS " + text(report.rmsTexels) + " texel (allowed " +
                           text(options.maxRmsTexels) + ")");
    }
    if (report.maxTracerOverestimateTexels > options.maxTracerOverestimateTexels) {
        failures.push_back("a tracer can step past the surface by " +
                           text(report.maxTracerOverestimateTexels) + " texel (allowed " +
                           text(options.maxTracerOverestimateTexels) + ")");
    }
    if (options.maxNearErrorTexels && report.nearMaxAbsTexels > *options.maxNearErrorTexels) {
        failures.push_back("max error near the surface " + text(report.nearMaxAbsTexels) +
                           " texel (allowed " + text(*options.maxNearErrorTexels) + ")");
    }
    if (report.signErrors > 0 && !options.allowSignErrors) {
        failures.push_back(std::to_string(report.signErrors) +
                           " sign errors more than 1 texel from the surface");
    }
    return check;
}

TileCheck recordAnalyticCheck(Tile& tile) {
    const TileCheckOptions options;
    TileCheck check = checkTile(tile, "tile", {}, options);
    const TileErrorReport& report = check.report;
    std::ostringstream verdict;
    verdict.precision(4);
    if (check.passed()) {
        verdict << TileProvenance::kCheckWithin << ": RMS " << report.rmsTexels
                << " texel, overestimates beyond " << options.maxOverestimateTexels << " texel in "
                << 100.0 * report.overestimateShare << "% of samples";
    } else {
        verdict << TileProvenance::kCheckBeyond << ": ";
        for (std::size_t i = 0; i < check.failures.size(); ++i)
            verdict << (i == 0 ? "" : "; ") << check.failures[i];
    }
    verdict << "; " << report.samples << " samples against the analytic truth";
    tile.provenance.check = verdict.str();
    return check;
}

std::string recordedCheckWarning(const Tile& tile, const std::string& tileName) {
    const std::string_view check = tile.provenance.check;
    if (!check.starts_with(TileProvenance::kCheckBeyond)) return {};
    // After "beyond tolerances: ", as recordAnalyticCheck writes it.
    const std::string_view figures =
        check.substr(std::min(check.size(), TileProvenance::kCheckBeyond.size() + 2));
    return tileName + " misses distile check's tolerances: " + std::string(figures) +
           ". Wires under about 1.25 texels in radius and sharp edges are what a tile holds "
           "poorly";
}

}  // namespace distile
