// distile bake: detail -> level set (.vdb) -> tile (.exr).
#include <array>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <utility>

#include "bake/bake.h"
#include "bake/height_image.h"
#include "bake/provenance.h"
#include "bake/solid_mesh.h"
#include "bake/vdb_bake.h"
#include "check/tile_check.h"
#include "cli/arguments.h"
#include "cli/commands.h"
#include "cli/progress_bar.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "sampler/tile_io.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

struct BakeArguments {
    std::string detail;
    fs::path input;  ///< mesh, height map or .vdb file
    fs::path output;
    std::string size = "256x256x16";
    fs::path vdbOutput;
    bool half = false;
    float halfBandTexels = 0.0f;
    ChainmailOptions chainmail;
    std::string weave = "european4in1";
    GratingOptions grating;
    fs::path png8Output;
    fs::path png16Output;
    fs::path png16SignedOutput;
    std::string repeat;
    bool exactTexels = false;
    /// The detail-specific options given on the command line (kDetailOptions' flags): others
    /// take the detail's defaults (a chain mail's, its weave's).
    std::set<std::string> detailOptionsGiven;
    bool fit = false;  ///< --fit given (it is also the default placement)
    std::optional<double> meshScale;
    std::vector<double> meshOffset;
    double heightTexels = 0.0;
    bool unsignedDistance = false;
    std::optional<double> thicknessTexels;
    std::string gridName;
    std::optional<double> iso;
    std::vector<double> window;
};

/// The files a bake writes: the temporary path of each output given (empty when not given).
struct BakeOutputs {
    OutputFiles files;
    fs::path tile, vdb, png8, png16, png16Signed;
};

/// The options that only some details take, and which: any other detail refuses them rather
/// than ignore them.
struct DetailOption {
    const char* flag;
    const char* detail;
    const char* alsoDetail = nullptr;  ///< a second detail taking it, if any
};
constexpr DetailOption kDetailOptions[] = {
    {"--rings-per-row", "chainmail"},
    {"--rows", "chainmail"},
    {"--ring-radius", "chainmail"},
    {"--wire-radius", "chainmail"},
    {"--tilt", "chainmail"},
    {"--weave", "chainmail"},
    {"--small-ring-radius", "chainmail"},
    {"--small-wire-radius", "chainmail"},
    {"--bars", "grating"},
    {"--bar-width", "grating"},
    {"--bar-height", "grating"},
    {"--edge-radius", "grating"},
    {"--layer-gap", "grating"},
    {"--fit", "mesh", "vdb"},
    {"--scale", "mesh", "vdb"},
    {"--offset", "mesh", "vdb"},
    {"--unsigned", "mesh"},
    {"--thickness", "mesh"},
    {"--height-texels", "heightmap"},
    {"--grid", "vdb"},
    {"--iso", "vdb"},
    {"--window", "vdb"},
};

/// Throws InputError for the first option given that `detail` does not take.
void requireOptionsOfDetail(const BakeArguments& arguments) {
    for (const DetailOption& option : kDetailOptions) {
        if (!arguments.detailOptionsGiven.contains(option.flag)) continue;
        if (arguments.detail == option.detail ||
            (option.alsoDetail && arguments.detail == option.alsoDetail))
            continue;
        throw InputError(std::string(option.flag) + ": only for bake " + option.detail +
                         (option.alsoDetail ? std::string(" and bake ") + option.alsoDetail : ""));
    }
}

/// How `bake mesh` places the mesh: --fit (default) or --scale/--offset.
MeshPlacement meshPlacement(const BakeArguments& arguments) {
    MeshPlacement placement;
    const bool explicitPlacement = arguments.meshScale || !arguments.meshOffset.empty();
    if (arguments.fit && explicitPlacement) {
        throw InputError("--fit: cannot be combined with --scale/--offset; give one placement");
    }
    if (!explicitPlacement) return placement;
    placement.fit = false;
    placement.scale = arguments.meshScale.value_or(1.0);
    if (!arguments.meshOffset.empty()) {
        if (arguments.meshOffset.size() != 3)
            throw InputError("--offset: give three numbers X,Y,Z (texels)");
        placement.offsetTexels = {arguments.meshOffset[0], arguments.meshOffset[1],
                                  arguments.meshOffset[2]};
    }
    return placement;
}

/// `bake mesh FILE`: load, warn about what is odd, bake the exact distance signed by the winding
/// number, or unsigned with --unsigned (bake/solid_mesh.h). Throws before anything is written.
BakeResult bakeMeshFile(const BakeArguments& arguments, const BakeOptions& options,
                        ProgressBar& progress) {
    const std::string file = arguments.input.string();
    MeshSignOptions sign;
    sign.unsignedDistance = arguments.unsignedDistance;
    if (arguments.thicknessTexels) {
        if (!arguments.unsignedDistance)
            throw InputError(
                "--thickness: needs --unsigned (it is the thickness of the shell "
                "around an unsigned surface)");
        sign.thicknessTexels = *arguments.thicknessTexels;
    }
    const SolidDetailMesh solid = loadSolidDetailMesh(arguments.input, sign);
    const MeshPlacement placement = meshPlacement(arguments);
    SolidMeshBake bake = [&] {
        try {
            return bakeSolidMesh(solid.mesh, placement, options, file, std::ref(progress), sign);
        } catch (const InputError& error) {  // the placement's: say which mesh
            const std::string problem = error.problem().find(file) != std::string::npos
                                            ? error.problem()
                                            : file + ": " + error.problem();
            throw error.field().empty() ? InputError(problem)
                                        : InputError::inField(error.field(), problem);
        }
    }();
    // After the bake: a refused mesh gets its one-line error only.
    for (const std::string& warning : solid.warnings)
        std::fprintf(stderr, "distile: warning: %s\n", warning.c_str());
    if (sign.unsignedDistance) {
        std::printf("%s: %zu triangles; unsigned distance, shell %g texels thick\n", file.c_str(),
                    solid.mesh.triangles.size(), sign.thicknessTexels);
    } else {
        std::printf("%s: %zu triangles; inside where the winding number exceeds 1/2 (%zu texels)\n",
                    file.c_str(), solid.mesh.triangles.size(), bake.insideTexels);
    }
    return std::move(bake.result);
}

/// `bake vdb FILE`: read the grid, place it (--fit, --scale/--offset or --window), bake; report
/// the placement and, with a window, the seam mismatch. Throws before anything is written.
BakeResult bakeVdbFile(const BakeArguments& arguments, const BakeOptions& options,
                       ProgressBar& progress) {
    const std::string file = arguments.input.string();
    VdbPlacement placement;
    if (!arguments.window.empty()) {
        if (arguments.fit || arguments.meshScale || !arguments.meshOffset.empty()) {
            throw InputError(
                "--window: cannot be combined with --fit/--scale/--offset; give one placement");
        }
        const std::vector<double>& w = arguments.window;
        placement.mode = VdbPlacement::Mode::Window;
        placement.windowWorld = {{w[0], w[1], w[2]}, {w[3], w[4], w[5]}};
    } else {
        const MeshPlacement fitOrExplicit = meshPlacement(arguments);
        if (!fitOrExplicit.fit) {
            placement.mode = VdbPlacement::Mode::Explicit;
            placement.scale = fitOrExplicit.scale;
            placement.offsetTexels = fitOrExplicit.offsetTexels;
        }
    }
    const VdbVolume volume = VdbVolume::read(arguments.input, arguments.gridName, arguments.iso);
    VdbBakeResult bake = bakeVdb(volume, placement, options, arguments.input.filename().string(),
                                 std::ref(progress));
    const glm::dvec3 voxel = volume.voxelSizeWorld();
    const glm::dvec3 offset = bake.placement.offsetTexels;
    std::printf(
        "%s: grid '%s' (%s, voxel size %g x %g x %g), placed at %g texels per unit, "
        "offset (%g, %g, %g) texels%s\n",
        file.c_str(), volume.gridName().c_str(),
        volume.isLevelSet() ? "level set" : "surface at the iso value", voxel.x, voxel.y, voxel.z,
        bake.placement.scale, offset.x, offset.y, offset.z,
        bake.rebuilt ? "; band rebuilt from the surface" : "");
    if (bake.seamMismatchTexels) {
        std::printf("seam mismatch x: %.4f texels, y: %.4f texels\n", bake.seamMismatchTexels->x,
                    bake.seamMismatchTexels->y);
    }
    return std::move(bake.bake);
}

/// The library's error about one field of the bake's options (bake/bake.h) under the flag that
/// filled it; other errors as they are.
InputError underBakeFlag(const InputError& error) {
    return shownUnder(error, {{"size", "--size"},
                              {"halfBandTexels", "--band"},
                              {"placement.scale", "--scale"},
                              {"placement.offsetTexels", "--offset"},
                              {"heightTexels", "--height-texels"},
                              {"sign.unsignedDistance", "--unsigned"},
                              {"sign.thicknessTexels", "--thickness"},

                              {"grid", "--grid"},
                              {"iso", "--iso"},
                              {"placement.windowWorld", "--window"},
                              {"repeatX, repeatY", "--repeat"},
                              {"chainmail.ringsPerRow", "--rings-per-row"},
                              {"chainmail.rowsPerTile", "--rows"},
                              {"chainmail.ringRadiusSpacings", "--ring-radius"},
                              {"chainmail.wireRadiusSpacings", "--wire-radius"},
                              {"chainmail.tiltDeg", "--tilt"},
                              {"chainmail.smallRingRadiusSpacings", "--small-ring-radius"},
                              {"chainmail.smallWireRadiusSpacings", "--small-wire-radius"},
                              {"grating.barsPerTile", "--bars"},
                              {"grating.barWidthTexels", "--bar-width"},
                              {"grating.barHeightTexels", "--bar-height"},
                              {"grating.edgeRadiusTexels", "--edge-radius"},
                              {"grating.layerGapTexels", "--layer-gap"}});
}

/// "NxM" -> (N, M) for --repeat; the level set checks the range.
std::pair<int, int> parseRepeat(const std::string& text) {
    std::array<int, 2> repeat{0, 0};
    try {
        repeat = parseSize2(text, "--repeat");
    } catch (const InputError&) {  // told below with the accepted range
    }
    const auto [x, y] = repeat;
    if (x < 1 || x > 64 || y < 1 || y > 64) {
        throw InputError("--repeat: '" + text +
                         "' is not accepted; write NxM with N and M in [1, 64], e.g. 2x2");
    }
    return {x, y};
}

/// The procedural pattern the arguments describe (chain mail of the chosen weave, or grating).
ProceduralOptions proceduralOptions(const BakeArguments& arguments) {
    ProceduralOptions procedural;
    if (arguments.detail == "grating") {
        procedural.kind = ProceduralKind::Grating;
        procedural.grating = arguments.grating;
        return procedural;
    }
    procedural.kind = ProceduralKind::Chainmail;
    procedural.chainmail = arguments.chainmail;
    if (arguments.weave == "japanese4in1") {
        // Options not given take the Japanese weave's defaults.
        ChainmailOptions& chainmail = procedural.chainmail;
        const ChainmailOptions defaults = japanese4in1Defaults();
        auto given = [&](const char* name) { return arguments.detailOptionsGiven.contains(name); };
        chainmail.weave = ChainmailWeave::Japanese4in1;
        if (!given("--rings-per-row")) chainmail.ringsPerRow = defaults.ringsPerRow;
        if (!given("--rows")) chainmail.rowsPerTile = defaults.rowsPerTile;
        if (!given("--ring-radius")) chainmail.ringRadiusSpacings = defaults.ringRadiusSpacings;
        if (!given("--wire-radius")) chainmail.wireRadiusSpacings = defaults.wireRadiusSpacings;
        if (!given("--tilt")) chainmail.tiltDeg = defaults.tiltDeg;
        if (!given("--small-ring-radius"))
            chainmail.smallRingRadiusSpacings = defaults.smallRingRadiusSpacings;
        if (!given("--small-wire-radius"))
            chainmail.smallWireRadiusSpacings = defaults.smallWireRadiusSpacings;
    } else if (arguments.weave != "european4in1") {
        throw InputError("--weave: '" + arguments.weave +
                         "' is not accepted; accepted: european4in1, japanese4in1");
    } else {
        // The European weave has no small rings: an option for them would be silently ignored.
        for (const char* name : {"--small-ring-radius", "--small-wire-radius"}) {
            if (arguments.detailOptionsGiven.contains(name))
                throw InputError(std::string(name) +
                                 ": only for --weave japanese4in1 (the European weave has no "
                                 "small rings)");
        }
    }
    return procedural;
}

/// The figures of a procedural tile's check against its analytic truth (recordAnalyticCheck, as
/// `distile check` measures it; 0.07 s for the default chain mail): one line, and a warning when
/// the tile misses the tolerances, which a wire about a texel thin or a sharp edge does.
void reportAgainstAnalyticTruth(const Tile& tile, const TileCheck& check, const fs::path& output) {
    const TileErrorReport& report = check.report;
    std::printf(
        "against its analytic truth (%d samples, as distile check): RMS %.4f texel, "
        "overestimates beyond %g texel %.3f%%: %s\n",
        report.samples, report.rmsTexels, TileCheckOptions().maxOverestimateTexels,
        100.0 * report.overestimateShare,
        check.passed() ? "within the check's tolerances" : "beyond them");
    if (const std::string warning = recordedCheckWarning(tile, output.string()); !warning.empty()) {
        std::fprintf(stderr,
                     "distile: warning: %s; raise --size, or thicken or round the detail; "
                     "`distile check %s --plot error.png` shows where\n",
                     warning.c_str(), output.c_str());
    }
}

void runBake(const BakeArguments& arguments) {
    const bool fromFile =
        arguments.detail == "mesh" || arguments.detail == "heightmap" || arguments.detail == "vdb";
    if (arguments.detail != "chainmail" && arguments.detail != "grating" && !fromFile) {
        throw InputError(
            "bake: '" + arguments.detail +
            "' is not a known detail; accepted: chainmail, grating, mesh FILE, heightmap IMAGE, "
            "vdb FILE");
    }
    if (fromFile && arguments.input.empty()) {
        throw InputError("bake " + arguments.detail +
                         ": needs the input file, e.g. `distile bake " + arguments.detail +
                         (arguments.detail == "mesh"  ? " ring.obj"
                          : arguments.detail == "vdb" ? " level.vdb"
                                                      : " stones.png") +
                         " -o tile.exr`");
    }
    requireOptionsOfDetail(arguments);
    if (!fromFile && !arguments.input.empty()) {
        throw InputError("bake " + arguments.detail + ": takes no input file ('" +
                         arguments.input.string() + "')");
    }
    const ProceduralOptions procedural =
        fromFile ? ProceduralOptions() : proceduralOptions(arguments);
    BakeOptions options;
    options.size = parseSize(arguments.size, "--size");
    options.halfBandTexels = arguments.halfBandTexels;
    requireOutput(arguments.output, "-o", {".exr"});
    if (!arguments.vdbOutput.empty()) requireOutput(arguments.vdbOutput, "--vdb", {".vdb"});
    if (!arguments.png8Output.empty()) requireOutput(arguments.png8Output, "--png8", {".png"});
    if (!arguments.png16Output.empty()) requireOutput(arguments.png16Output, "--png16", {".png"});
    if (!arguments.png16SignedOutput.empty())
        requireOutput(arguments.png16SignedOutput, "--png16-signed", {".png"});
    std::pair<int, int> repeat{1, 1};
    if (!arguments.repeat.empty()) {
        if (arguments.vdbOutput.empty())
            throw InputError("--repeat: needs --vdb FILE (it tiles the level set written there)");
        repeat = parseRepeat(arguments.repeat);
        try {  // before the bake: the band is known from the options
            LevelSet::checkRepeat(options.size, validatedHalfBandTexels(options), repeat.first,
                                  repeat.second);
        } catch (const InputError& error) {
            throw underBakeFlag(error);
        }
    }
    // Checked before the work, written together after it (common/atomic_file.h).
    BakeOutputs outputs;
    outputs.tile = outputs.files.add(arguments.output, "-o");
    if (!arguments.vdbOutput.empty()) outputs.vdb = outputs.files.add(arguments.vdbOutput, "--vdb");
    if (!arguments.png8Output.empty())
        outputs.png8 = outputs.files.add(arguments.png8Output, "--png8");
    if (!arguments.png16Output.empty())
        outputs.png16 = outputs.files.add(arguments.png16Output, "--png16");
    if (!arguments.png16SignedOutput.empty())
        outputs.png16Signed = outputs.files.add(arguments.png16SignedOutput, "--png16-signed");
    options.conservative.enabled = !arguments.exactTexels;
    // Only a written level set needs its margin above and below the tile.
    options.fillLevelSetMargins = !arguments.vdbOutput.empty();

    const auto start = std::chrono::steady_clock::now();
    std::optional<BakeResult> result;
    try {
        ProgressBar progress("bake " + arguments.detail + " " + toString(options.size));
        if (arguments.detail == "mesh") {
            result.emplace(bakeMeshFile(arguments, options, progress));
        } else if (arguments.detail == "vdb") {
            result.emplace(bakeVdbFile(arguments, options, progress));
        } else if (arguments.detail == "heightmap") {
            const HeightImage image = readHeightImage(arguments.input);
            HeightMapOptions heightMap;
            heightMap.heightTexels = arguments.heightTexels;
            result.emplace(bakeHeightMap(image, heightMap, options, std::ref(progress)));
        } else {
            result.emplace(bakeProcedural(procedural, options, std::ref(progress)));
        }
        if (fromFile) recordSourceFile(result->tile.provenance, arguments.input);
    } catch (const InputError& error) {
        throw underBakeFlag(error);
    }
    // Procedural detail has an analytic truth: its check's verdict is written with the tile.
    std::optional<TileCheck> check;
    if (!fromFile) check = recordAnalyticCheck(result->tile);
    // The repeated level set is built before anything is written: a refused --repeat leaves no
    // file.
    std::optional<LevelSet> repeatedLevelSet;
    if (repeat.first > 1 || repeat.second > 1) {
        try {
            repeatedLevelSet.emplace(result->levelSet.repeated(repeat.first, repeat.second));
        } catch (const InputError& error) {
            throw underBakeFlag(error);
        }
    }
    // Every output is written to its temporary file first and renamed only once all are.
    writeTileExr(result->tile, outputs.tile,
                 arguments.half ? TileStorage::Half16 : TileStorage::Float32);
    if (!outputs.png8.empty()) writeTilePng(result->tile, outputs.png8, 8);
    if (!outputs.png16.empty()) writeTilePng(result->tile, outputs.png16, 16);
    if (!outputs.png16Signed.empty()) writeSignedTilePng(result->tile, outputs.png16Signed);
    const LevelSet* levelSet = repeatedLevelSet ? &*repeatedLevelSet : &result->levelSet;
    if (!outputs.vdb.empty()) levelSet->save(outputs.vdb);
    outputs.files.commit();

    std::printf("tile %s (%s, %s) written to %s\n", toString(options.size).c_str(),
                arguments.detail.c_str(), arguments.half ? "half" : "float",
                arguments.output.c_str());
    if (!arguments.png8Output.empty())
        std::printf("8-bit PNG atlas written to %s\n", arguments.png8Output.c_str());
    if (!arguments.png16Output.empty())
        std::printf("16-bit PNG atlas written to %s\n", arguments.png16Output.c_str());
    if (!arguments.png16SignedOutput.empty()) {
        std::printf("signed 16-bit PNG atlas written to %s\n", arguments.png16SignedOutput.c_str());
    }
    if (repeatedLevelSet) {
        std::printf("level set tiled %dx%d (%s texels, %zu active voxels) written to %s\n",
                    repeat.first, repeat.second, toString(levelSet->tileSize()).c_str(),
                    levelSet->activeVoxelCount(), arguments.vdbOutput.c_str());
    } else if (!arguments.vdbOutput.empty()) {
        std::printf("level set (%zu active voxels, half band %.1f texels) written to %s\n",
                    levelSet->activeVoxelCount(), levelSet->halfBandTexels(),
                    arguments.vdbOutput.c_str());
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("baked in %.2f s\n", seconds);
    if (check) reportAgainstAnalyticTruth(result->tile, *check, arguments.output);
}

}  // namespace

void addBakeCommand(CLI::App& app) {
    auto arguments = std::make_shared<BakeArguments>();
    CLI::App* command = app.add_subcommand(
        "bake", "Bake detail into a distance tile (EXR atlas) and optionally its level set (.vdb)");
    command
        ->add_option("detail", arguments->detail,
                     "What to bake: chainmail, grating, mesh FILE, heightmap IMAGE, vdb FILE")
        ->required();
    command->add_option(
        "input", arguments->input,
        "mesh: the detail mesh (OBJ, PLY, OFF, STL); heightmap: the image; vdb: the "
        ".vdb file");
    command->add_option("-o,--output", arguments->output, "Tile file to write (.exr)")->required();
    command->add_option("--size", arguments->size, "Tile size WxHxD in texels")
        ->capture_default_str();
    command->add_option("--vdb", arguments->vdbOutput,
                        "Also write the narrow-band level set (.vdb, texel units)");
    command->add_flag("--half", arguments->half, "Store half floats instead of 32-bit floats");
    command->add_option(
        "--band", arguments->halfBandTexels,
        "Half width of the level set's narrow band in texels, from 1 to twice the tile depth "
        "(and 1024), or 0 for the default: the tile depth, at most 1024; the time grows steeply "
        "with it");
    auto* chainmail = command->add_option_group(
        "chainmail", "European 4-in-1 chain mail (defaults fill 256x256x16)");
    chainmail
        ->add_option("--rings-per-row", arguments->chainmail.ringsPerRow,
                     "Rings along x per tile, at most W/4")
        ->capture_default_str();
    chainmail
        ->add_option("--rows", arguments->chainmail.rowsPerTile,
                     "Rows along y per tile (European: even, at most H/2; Japanese: at most H/4)")
        ->capture_default_str();
    chainmail
        ->add_option("--ring-radius", arguments->chainmail.ringRadiusSpacings,
                     "Ring centreline radius, in ring spacings")
        ->capture_default_str();
    chainmail
        ->add_option("--wire-radius", arguments->chainmail.wireRadiusSpacings,
                     "Wire radius, in ring spacings")
        ->capture_default_str();
    chainmail->add_option("--tilt", arguments->chainmail.tiltDeg, "Ring tilt about y, degrees")
        ->capture_default_str();
    chainmail
        ->add_option("--weave", arguments->weave, "european4in1 or japanese4in1 (its own defaults)")
        ->capture_default_str();
    chainmail->add_option("--small-ring-radius", arguments->chainmail.smallRingRadiusSpacings,
                          "Japanese 4-in-1 only: small ring radius, in ring spacings");
    chainmail->add_option("--small-wire-radius", arguments->chainmail.smallWireRadiusSpacings,
                          "Japanese 4-in-1 only: small ring wire radius, in ring spacings");
    auto* grating =
        command->add_option_group("grating", "Grating: two layers of bars with rounded edges");
    grating->add_option("--bars", arguments->grating.barsPerTile, "Bars per layer across the tile")
        ->capture_default_str();
    grating->add_option("--bar-width", arguments->grating.barWidthTexels, "Bar width, texels")
        ->capture_default_str();
    grating->add_option("--bar-height", arguments->grating.barHeightTexels, "Bar thickness, texels")
        ->capture_default_str();
    grating
        ->add_option("--edge-radius", arguments->grating.edgeRadiusTexels,
                     "Rounding of the bar edges, texels")
        ->capture_default_str();
    grating
        ->add_option("--layer-gap", arguments->grating.layerGapTexels,
                     "Gap between the two layers, texels")
        ->capture_default_str();
    command->add_option("--png8", arguments->png8Output,
                        "Also write an 8-bit PNG atlas (distance / depth, ch. 8)");
    command->add_option("--png16", arguments->png16Output,
                        "Also write a 16-bit PNG atlas (distance / depth, ch. 8)");
    command->add_option("--png16-signed", arguments->png16SignedOutput,
                        "Also write a 16-bit PNG atlas that keeps the sign: 0.5 + distance / 2R, "
                        "R the largest |distance| (its distile:png_range_texels)");
    command->add_option("--repeat", arguments->repeat,
                        "Write the --vdb level set tiled NxM (world units = texels), N and M in "
                        "[1, 64], at most 2^28 voxels (1 GiB) in all");
    auto* mesh =
        command->add_option_group("mesh",
                                  "bake mesh FILE: a triangle mesh (OBJ, PLY, OFF, STL; corners "
                                  "at identical positions are welded). Every texel takes the "
                                  "exact distance to the mesh, negative where its generalized "
                                  "winding number exceeds 1/2, so open meshes, soups of "
                                  "overlapping parts and flipped faces bake too; sheet-like "
                                  "detail without an inside needs --unsigned. Placement in texel "
                                  "space (x, y in [0,W) x [0,H), z = "
                                  "0 the floor, z = D the top): by default "
                                  "(--fit) the mesh is scaled uniformly so its x/y bounding box "
                                  "spans the tile footprint (the axis with the "
                                  "larger extent relative to W or H spans it exactly), centred in "
                                  "x and y, its lowest point on the floor; give "
                                  "a repeating mesh its period as its x/y bounding box. With "
                                  "--scale/--offset: texel = S * file position + "
                                  "(X, Y, Z). The tile is periodic: parts beyond the footprint "
                                  "continue on the other side");
    mesh->add_flag("--fit", arguments->fit,
                   "Fit the x/y bounding box to the footprint, floor at z = 0 (the default)");
    mesh->add_option("--scale", arguments->meshScale,
                     "Explicit placement: texels per file unit S (> 0); the placed mesh must "
                     "overlap the tile, be at least a texel and at most 2 footprints across");
    mesh->add_option("--offset", arguments->meshOffset,
                     "Explicit placement: where the file's origin goes, X,Y,Z texels")
        ->expected(3)
        ->delimiter(',');
    mesh->add_flag("--unsigned", arguments->unsignedDistance,
                   "Sheet-like detail without an inside (cloth, leaves, a grille of quads): store "
                   "the unsigned distance, so the tracer's surface (the zero set) is the "
                   "triangles themselves; give it --thickness to make a solid shell");
    mesh->add_option("--thickness", arguments->thicknessTexels,
                     "With --unsigned: shell thickness T in texels, in [0, D]; the tile stores "
                     "the unsigned distance minus T/2 (default 0)");
    auto* heightmap = command->add_option_group(
        "heightmap",
        "bake heightmap IMAGE: an 8/16-bit PNG or an EXR read as grey, values in [0,1] mapped to "
        "heights "
        "0..--height-texels; the image is stretched over the footprint (any size, sampled "
        "periodically and "
        "bilinearly at the texel columns); material is solid below the surface");
    heightmap->add_option("--height-texels", arguments->heightTexels,
                          "Height of image value 1, texels, in (0, D] (default: D - 1)");
    auto* vdb = command->add_option_group(
        "vdb",
        "bake vdb FILE: a float level set (or, with --iso, a fog volume) from any .vdb file, any "
        "voxel size and transform. Placement as for meshes, in the file's world units: --fit "
        "(default; the surface's box) or --scale/--offset (texel = S * world + (X, Y, Z)), or "
        "--window. Distances are the file's own where its band covers the tile's; a thinner band "
        "is rebuilt: the exact distance to its surface, refined on its triquadratic "
        "reconstruction, signed by the file. Nothing is wrapped");
    vdb->add_option("--grid", arguments->gridName,
                    "The grid to bake (default: the file's only float level set)")
        ->check(CLI::Validator(
            [](const std::string& name) {
                return name.empty() ? "is empty; name a grid, or leave --grid out for the file's "
                                      "only float level set"
                                    : std::string();
            },
            "NAME"));
    vdb->add_option("--iso", arguments->iso,
                    "The surface's value: required for a fog volume (inside above it, e.g. 0.5); "
                    "for a level set it offsets the surface (inside below it)");
    vdb->add_option("--window", arguments->window,
                    "One period X0 Y0 Z0 X1 Y1 Z1 (world units) cut from a larger volume: its x/y "
                    "extent spans the footprint, Z0 goes to the floor; prints the seam mismatch")
        ->expected(6);
    command->add_flag("--exact-texels", arguments->exactTexels,
                      "Keep the exact distances at texel centres (no conservative lowering; "
                      "trilinear may overestimate)");
    command->callback([arguments, command] {
        for (const DetailOption& option : kDetailOptions) {
            if (command->count(option.flag) > 0) arguments->detailOptionsGiven.insert(option.flag);
        }
        runBake(*arguments);
    });
}

}  // namespace distile::cli
