// distile render: a scene (or the built-in demo) to an image, with optional AOVs.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "bake/provenance.h"
#include "cli/arguments.h"
#include "cli/commands.h"
#include "cli/progress_bar.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "common/image_files.h"
#include "render/render_files.h"
#include "render/renderer.h"
#include "render/world_reference.h"
#include "scene/scene_file.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

struct RenderArguments {
    fs::path scene;
    fs::path output;
    std::optional<int> width;
    std::optional<int> height;
    std::optional<int> samplesPerPixel;
    RenderOptions options;
    bool noShadows = false;
    /// --no-skip: names of RenderSkips switched off (the work done anyway, for measurements).
    std::vector<std::string> noSkips;
    /// --reference [analytic|world|world-levelset]: empty when given without a value (analytic).
    std::string referenceKind;
    bool referenceGiven = false;
    /// --reference-voxels: world voxels per world texel of --reference world-levelset.
    double referenceVoxelsPerTexel = DisplacedLevelSetOptions{}.voxelsPerTexel;
};

/// The files a render writes, checked before the work and renamed together after it
/// (common/atomic_file.h): the image and, with --aovs, the AOVs beside it.
class RenderOutputs {
  public:
    /// `aovs`: the names of the AOVs (render/render_files.h kAovFiles) the render writes with
    /// --aovs; empty: all of them.
    RenderOutputs(const fs::path& image, bool withAovs, std::span<const char* const> aovs = {})
        : image_(files_.add(image, "-o")) {
        if (!withAovs) return;
        for (const AovFile& aov : kAovFiles) {
            if (!holdsAov(aovs, aov.name)) continue;
            aovs_[aov.name] = files_.add(aovPath(image, aov.name, aov.extension),
                                         "-o (its AOV " + std::string(aov.name) + ")");
        }
    }
    /// Writes each AOV added of `aovs`.
    void writeAovs(const RenderAovs& aovs) const {
        for (const AovFile& aov : kAovFiles) {
            if (const auto found = aovs_.find(aov.name); found != aovs_.end())
                writeImage(aovs.*aov.layer, found->second);
        }
    }
    const fs::path& image() const { return image_; }
    void commit() { files_.commit(); }

  private:
    OutputFiles files_;
    fs::path image_;
    std::map<std::string, fs::path> aovs_;
};

/// distile render --reference world | world-levelset: the scene against world-space meshes of
/// its detail (a BVH, or level sets of the same meshes).
void runWorldReference(const RenderArguments& arguments, SceneFile sceneFile,
                       RenderOutputs& outputs) {
    WorldReferenceOptions options;
    options.width = arguments.width.value_or(sceneFile.image.width);
    options.height = arguments.height.value_or(sceneFile.image.height);
    options.outputAovs = arguments.options.outputAovs;
    options.method = arguments.referenceKind == "world-levelset" ? WorldReferenceMethod::LevelSet
                                                                 : WorldReferenceMethod::Bvh;
    options.levelSet.voxelsPerTexel = arguments.referenceVoxelsPerTexel;
    attachTruth(sceneFile);  // analytic detail where there is one, else the tile
    const auto start = std::chrono::steady_clock::now();
    WorldReferenceResult result;
    {
        ProgressBar progress("world reference " + std::to_string(options.width) + "x" +
                             std::to_string(options.height));
        result = renderWorldReference(sceneFile.scene, options, std::ref(progress));
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    writeImage(result.render.image, outputs.image());
    if (result.render.aovs) outputs.writeAovs(*result.render.aovs);
    outputs.commit();
    for (std::size_t index = 0; index < result.meshes.size(); ++index) {
        const DisplacedMeshStats& mesh = result.meshes[index];
        std::printf(
            "detail mesh %zu: %zu polygons, %zu vertices (tile isosurface %zu polygons, %zu "
            "border edges walled; texel %.3g world units); lattice %.2f s, isosurface %.2f s, "
            "mapping %.2f s\n",
            index, mesh.meshPolygons, mesh.meshVertices, mesh.tilePolygons, mesh.borderEdges,
            mesh.texelSizeWorld, mesh.latticeSeconds, mesh.extractSeconds, mesh.mapSeconds);
    }
    for (std::size_t index = 0; index < result.levelSets.size(); ++index) {
        const DisplacedLevelSetStats& levelSet = result.levelSets[index];
        std::printf(
            "level set %zu: %.3g voxels per texel (voxel %.3g world units), %zu active "
            "voxels, %.1f MB, %.2f s\n",
            index, levelSet.voxelsPerTexel, levelSet.voxelSizeWorld, levelSet.activeVoxels,
            double(levelSet.memoryBytes) / 1e6, levelSet.levelSetSeconds);
    }
    const RenderStats& stats = result.render.stats;
    char levelSets[64] = "";
    if (options.method == WorldReferenceMethod::LevelSet)
        std::snprintf(levelSets, sizeof levelSets, "level sets %.2f s, ", result.levelSetSeconds);
    std::printf(
        "world reference (%dx%d, %s) in %.2f s: meshes %.2f s, %sBVH %.2f s (%.0f MB), trace "
        "and shade %.2f s; %.1f%% of %llu rays hit\n",
        options.width, options.height,
        options.method == WorldReferenceMethod::LevelSet ? "level sets" : "BVH", seconds,
        result.meshSeconds, levelSets, result.bvhSeconds, double(result.bvhBytes) / 1e6,
        result.traceSeconds, stats.rays ? 100.0 * double(stats.baseHits) / double(stats.rays) : 0.0,
        static_cast<unsigned long long>(stats.rays));
    std::printf(
        "detail hits on the exact surface: %llu refined, %llu left on the traced %s; %llu rays "
        "stopped by a back face of a tiled base mesh\n",
        static_cast<unsigned long long>(result.refinedHits),
        static_cast<unsigned long long>(result.unrefinedHits),
        options.method == WorldReferenceMethod::LevelSet ? "level set" : "mesh",
        static_cast<unsigned long long>(result.backFaceStops));
    if (result.render.aovs) {
        std::printf(
            "AOVs written beside it: %s, %s, %s (texel scale 0: compare takes the other "
            "render's)\n",
            aovPath(arguments.output, "depth", ".exr").c_str(),
            aovPath(arguments.output, "normal", ".png").c_str(),
            aovPath(arguments.output, "texel_scale", ".exr").c_str());
    }
    std::printf("image written to %s\n", fs::absolute(arguments.output).c_str());
}

/// The library's names of `values` (named by `nameOf`), as CLI11's transformers take them.
template <class Value, std::size_t N>
std::map<std::string, Value> namesOf(const Value (&values)[N], const char* (*nameOf)(Value)) {
    std::map<std::string, Value> names;
    for (const Value value : values) names[nameOf(value)] = value;
    return names;
}

/// A library's InputError as the user wrote the value: under the render command's flag, or the
/// scene file's JSON path (validateScene's Scene members) after the file's name (empty for the
/// demo). The image size and samples are named where they came from: the flag when given, else
/// the scene's `image` field.
InputError underRenderNames(const InputError& error, const RenderArguments& arguments) {
    if (error.field().empty()) return error;
    const fs::path& scene = arguments.scene;
    if (!scene.empty()) {
        const std::pair<const char*, const char*> fromScene[] = {
            {"width", arguments.width ? nullptr : "image.width"},
            {"height", arguments.height ? nullptr : "image.height"},
            {"samplesPerPixel", arguments.samplesPerPixel ? nullptr : "image.spp"}};
        for (const auto& [field, path] : fromScene) {
            if (path && error.field() == field) return error.renamed(scene.string() + ": " + path);
        }
    }
    const InputError flagged = shownUnder(error, {{"width", "--width"},
                                                  {"height", "--height"},
                                                  {"samplesPerPixel", "--spp"},
                                                  {"outputAovs", "--aovs"},
                                                  {"march.maxIterations", "--iterations"},
                                                  {"march.epsilonTexels", "--epsilon"},
                                                  {"march.relaxation", "--relaxation"}});
    if (flagged.field() != error.field()) return flagged;
    const InputError inScene = underSceneJsonPath(error);
    return scene.empty() ? inScene : inScene.renamed(scene.string() + ": " + inScene.field());
}

/// Refuses what `command`'s flags ask that the render would not do: a flag of the tile renderer
/// beside --reference world or world-levelset (kSettingsAWorldReferenceIgnores),
/// --reference-voxels without world-levelset.
void refuseIgnoredFlags(const CLI::App& command, const RenderArguments& arguments) {
    const bool world =
        arguments.referenceKind == "world" || arguments.referenceKind == "world-levelset";
    if (world) {
        for (const char* setting : kSettingsAWorldReferenceIgnores) {
            const std::string flag = std::string("--") + setting;
            if (command.get_option(flag)->count() == 0) continue;
            throw InputError(flag + ": does not apply to --reference " + arguments.referenceKind +
                             ", which " + kWorldReferenceReads + "; leave it out");
        }
    }
    if (command.get_option("--reference-voxels")->count() > 0 &&
        arguments.referenceKind != "world-levelset") {
        throw InputError(
            "--reference-voxels: applies to --reference world-levelset only (the voxels of its "
            "level set)");
    }
}

void runRender(RenderArguments arguments) {
    requireOutput(arguments.output, "-o", {".png", ".exr", ".tif", ".tiff"});
    // The image is written at the end. A PNG is written with libpng and an EXR (the AOVs are
    // both) with OpenEXR; a TIFF needs OpenImageIO, which starts loading meanwhile.
    if (!image_files::writesWithoutModule(arguments.output)) image_files::loadInBackground();
    // The outputs are checked (and reserved) before the scene is read and its tiles baked.
    const bool worldReference =
        arguments.referenceKind == "world" || arguments.referenceKind == "world-levelset";
    RenderOutputs outputs =
        worldReference
            ? RenderOutputs(arguments.output, arguments.options.outputAovs, kWorldReferenceAovs)
            : RenderOutputs(arguments.output, arguments.options.outputAovs);
    const auto commandStart = std::chrono::steady_clock::now();
    TileCache tiles;
    const auto warn = [](const std::string& warning) {
        std::fprintf(stderr, "distile: warning: %s\n", warning.c_str());
    };
    // A bar for each tile the scene bakes (none for tiles from the cache).
    const BakeProgress bakeProgress = [](const std::string& what) {
        auto bar = std::make_shared<ProgressBar>("bake " + what);
        return ProgressCallback([bar](double fractionDone) { (*bar)(fractionDone); });
    };
    SceneFile sceneFile = arguments.scene.empty()
                              ? demoScene(tiles, bakeProgress)
                              : loadSceneFile(arguments.scene, tiles, warn, bakeProgress);
    if (worldReference) {
        runWorldReference(arguments, std::move(sceneFile), outputs);
        return;
    }
    RenderOptions& options = arguments.options;
    options.reference = arguments.referenceGiven;
    options.width = arguments.width.value_or(sceneFile.image.width);
    options.height = arguments.height.value_or(sceneFile.image.height);
    options.samplesPerPixel = arguments.samplesPerPixel.value_or(sceneFile.image.samplesPerPixel);
    // --no-shadows is --shadows none: neither shadow maps nor self-shadow rays.
    if (arguments.noShadows) options.shadowFilter = ShadowFilter::None;
    for (const std::string& name : arguments.noSkips) {
        for (const RenderSkipSwitch& skip : kRenderSkipSwitches) {
            if (name == skip.name) options.skips.*skip.enabled = false;
        }
    }
    options.selfShadows = options.shadowFilter != ShadowFilter::None;
    if (options.reference) attachTruth(sceneFile);

    const auto secondsSince = [](std::chrono::steady_clock::time_point from) {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - from).count();
    };
    const double sceneSeconds = secondsSince(commandStart);
    const auto start = std::chrono::steady_clock::now();
    RenderResult result;
    double preparationSeconds = 0.0;
    {
        ProgressBar progress("render " + std::to_string(options.width) + "x" +
                             std::to_string(options.height));
        const PreparedScene prepared(sceneFile.scene, options);
        preparationSeconds = secondsSince(start);
        result = prepared.render(progress.enabled() ? ProgressCallback(std::ref(progress))
                                                    : ProgressCallback());
    }
    const double seconds = secondsSince(start);
    for (const std::string& warning : result.warnings)
        std::fprintf(stderr, "warning: %s\n", warning.c_str());
    const auto writeStart = std::chrono::steady_clock::now();
    writeImage(result.image, outputs.image());
    if (result.aovs) outputs.writeAovs(*result.aovs);
    outputs.commit();
    const double writeSeconds = secondsSince(writeStart);
    const RenderStats& stats = result.stats;
    std::printf(
        "rendered %s (%dx%d, %d spp) in %.2f s: %llu rays, %.1f%% hit a surface (%.1f%% a "
        "tile), mean %.2f iterations, %.1f%% of the tile hits converged within %d\n",
        arguments.scene.empty() ? "the demo scene" : arguments.scene.c_str(), options.width,
        options.height, options.samplesPerPixel, seconds,
        static_cast<unsigned long long>(stats.rays),
        stats.rays ? 100.0 * double(stats.baseHits) / double(stats.rays) : 0.0,
        stats.rays ? 100.0 * double(stats.detailHits) / double(stats.rays) : 0.0,
        stats.meanIterations(), 100.0 * stats.convergedShare(),
        options.reference ? RenderOptions::kReferenceIterations : options.march.maxIterations);
    std::printf("shells: %llu coverage tests, %llu traced (%.2f per ray), culling %s\n",
                static_cast<unsigned long long>(stats.shellsTested),
                static_cast<unsigned long long>(stats.shellsTraced),
                stats.rays ? double(stats.shellsTraced) / double(stats.rays) : 0.0,
                options.skips.shellCulling ? "on" : "off");
    if (options.shadowFilter != ShadowFilter::None) {
        std::printf(
            "shadow maps: %llu samples (%.1f per surface hit); %llu of %llu texels traced "
            "(where lookups reached)\n",
            static_cast<unsigned long long>(stats.shadowMapSamples),
            stats.baseHits ? double(stats.shadowMapSamples) / double(stats.baseHits) : 0.0,
            static_cast<unsigned long long>(stats.shadowMapTexels),
            static_cast<unsigned long long>(stats.shadowMapTexelsAll));
    }
    if (result.aovs) {
        std::printf("AOVs written beside it: %s, %s, %s, %s, %s, %s\n",
                    aovPath(arguments.output, "depth", ".exr").c_str(),
                    aovPath(arguments.output, "normal", ".png").c_str(),
                    aovPath(arguments.output, "iterations", ".png").c_str(),
                    aovPath(arguments.output, "shadow_samples", ".png").c_str(),
                    aovPath(arguments.output, "shadow_map_samples", ".png").c_str(),
                    aovPath(arguments.output, "curvature", ".png").c_str());
        std::printf("  and %s (texels per world unit along the ray, for distile compare)\n",
                    aovPath(arguments.output, "texel_scale", ".exr").c_str());
    }
    std::printf(
        "time: scene %.3f s (read, tiles baked or from the cache), preparation %.3f s, frame "
        "%.3f s, image files %.3f s\n",
        sceneSeconds, preparationSeconds, seconds - preparationSeconds, writeSeconds);
    std::printf("image written to %s\n", fs::absolute(arguments.output).c_str());
}

}  // namespace

void addRenderCommand(CLI::App& app) {
    auto arguments = std::make_shared<RenderArguments>();
    CLI::App* command = app.add_subcommand(
        "render", "Render a scene (JSON, see docs/scene.md) or, without one, the built-in demo");
    command->add_option("scene", arguments->scene, "Scene file (.json); omit for the demo scene");
    command->add_option("-o,--output", arguments->output, "Image to write (.png, .exr, .tif)")
        ->required();
    command
        ->add_option("--width", arguments->width,
                     "Image width in pixels (default: the scene's, else 1280); see --spp for "
                     "the bound on width x height")
        ->check(integerRange(1, 16384));
    command
        ->add_option("--height", arguments->height,
                     "Image height in pixels (default: the scene's, else 1024)")
        ->check(integerRange(1, 16384));
    command
        ->add_option("--spp", arguments->samplesPerPixel,
                     "Samples per pixel (default: the scene's, else 1); width x height x spp at "
                     "most 2^24 (~40 s on two cores)")
        ->check(integerRange(1, 256));
    command
        ->add_option("--iterations", arguments->options.march.maxIterations,
                     "Sphere-tracing budget per ray")
        ->capture_default_str()
        ->check(integerRange(1, 4096));
    command
        ->add_option("--epsilon", arguments->options.march.epsilonTexels,
                     "Hit threshold in texels, in [1e-5, 1]")
        ->capture_default_str();
    const auto methods = namesOf(kMarchMethods, marchMethodName);
    command
        ->add_option("--march", arguments->options.march.method,
                     "March method: sphere (ch. 8 sphere tracing), relaxed (over-relaxed sphere "
                     "tracing with a safe fallback), budgeted (sphere tracing with steps of at "
                     "least the path left over the samples left, then regula falsi), relief "
                     "(linear + binary search), fixed "
                     "(fixed steps)")
        ->transform(CLI::CheckedTransformer(methods, CLI::ignore_case))
        ->default_str(marchMethodName(MarchSettings{}.method));
    command
        ->add_option("--relaxation", arguments->options.march.relaxation,
                     "Step factor of --march relaxed, in [1, 2)")
        ->capture_default_str();
    const auto filters = namesOf(kFilterKinds, filterKindName);
    command->add_option("--filter", arguments->options.filter, "Tile reconstruction filter")
        ->transform(CLI::CheckedTransformer(filters, CLI::ignore_case))
        ->default_str("trilinear");
    command
        ->add_option("--normal-filter", arguments->options.normalFilter,
                     "Filter whose gradient gives the shading normal (same names as --filter)")
        ->transform(CLI::CheckedTransformer(filters, CLI::ignore_case))
        ->default_str("tricubic");
    const auto shellMappings = namesOf(kShellMappings, shellMappingName);
    command
        ->add_option("--shell", arguments->options.shellMapping,
                     "How rays cross the detail shell of a curved base mesh: curved (follow the "
                     "shell map from prism to prism: the ray bends in texel space, silhouettes "
                     "are the detail's) or planar (ch. 8: the ray mapped into texel space once "
                     "at its entry and marched straight; faster, wrong by texels on curved "
                     "bases). Flat faces take the planar march either way (exact there)")
        ->transform(CLI::CheckedTransformer(shellMappings, CLI::ignore_case))
        ->default_str("curved");
    const auto shadowFilters = namesOf(kShadowFilters, shadowFilterName);
    CLI::Option* shadows =
        command
            ->add_option(
                "--shadows", arguments->options.shadowFilter,
                "Shadows: none (no shadow maps, no self-shadow rays), full (64-sample soft shadow "
                "maps everywhere) or adaptive (9 test samples first, 64 only in penumbrae)")
            ->transform(CLI::CheckedTransformer(shadowFilters, CLI::ignore_case))
            ->default_str("adaptive");
    command->add_flag("--no-shadows", arguments->noShadows, "Same as --shadows none")
        ->excludes(shadows);
    std::vector<std::string> skipNames;
    for (const RenderSkipSwitch& skip : kRenderSkipSwitches) skipNames.push_back(skip.name);
    command
        ->add_option("--no-skip", arguments->noSkips,
                     "Do work the renderer normally skips, to measure the skip (repeatable): "
                     "empty-space (march from the top face, not from the top of the occupied "
                     "layers), "
                     "shell-culling (trace every detail shell under a pixel; same image), "
                     "unlit-shadows (shadow work also where the detail faces away from the "
                     "light; same image), casterless-shadow-maps (shadow maps also for a scene "
                     "of one flat object, where nothing can cast into them)")
        ->check(CLI::IsMember(skipNames))
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    command->add_flag("--aovs", arguments->options.outputAovs,
                      "Also write depth and texel scale (.exr: what distile compare reads), "
                      "normal, iteration, shadow-sample and curvature heat maps beside the image");
    CLI::Option* reference =
        command
            ->add_option(
                "--reference", arguments->referenceKind,
                "Trace the truth instead of the tiles (the ground truth for distile compare). "
                "analytic (the default when given without a value): each tile's analytic "
                "procedural detail in double precision with the planar tangent frame of ch. 8, "
                "512 iterations, epsilon 0.001 texel; world: the detail mapped through the base "
                "mesh's curved shell, triangle by triangle (mirrored UVs included), into a "
                "world-space mesh traced with Embree, each hit refined along the ray onto the "
                "exact detail (1e-4 texel; normals from its gradient through the shell), back "
                "faces of base meshes stopping rays, shaded as the renderer shades (sky, "
                "ambient, Blinn-Phong, 16 soft-shadow rays per light; the meshes and BVH of a "
                "scene estimated to need more than 8 GiB are refused); world-levelset: the same "
                "mesh as an OpenVDB level set (--reference-voxels) for its hits, refined the "
                "same way, much slower: the check of the world reference. Both world references "
                "refuse the tile renderer's flags (--spp, --iterations, --epsilon, --march, "
                "--relaxation, --filter, --normal-filter, --shell, --shadows, --no-skip)")
            ->expected(0, 1)
            ->check(
                [](const std::string& kind) {
                    return kind.empty() || kind == "analytic" || kind == "world" ||
                                   kind == "world-levelset"
                               ? std::string()
                               : "'" + kind +
                                     "' is not a reference: use analytic, world or world-levelset";
                },
                "analytic|world|world-levelset");
    command
        ->add_option("--reference-voxels", arguments->referenceVoxelsPerTexel,
                     "With --reference world-levelset: world voxels per world size of a texel, in "
                     "[0.25, 16] (2: voxels of half a texel); memory grows as its square, and "
                     "a level set estimated to need more than 1 GiB is refused. Default: 2, or "
                     "the finest that fits in 1 GiB")
        ->check(finiteRange(0.25, 16.0));
    command->callback([command, arguments, reference] {
        arguments->referenceGiven = reference->count() > 0;
        try {
            refuseIgnoredFlags(*command, *arguments);
            runRender(*arguments);
        } catch (const InputError& error) {
            throw underRenderNames(error, *arguments);
        }
    });
}

}  // namespace distile::cli
