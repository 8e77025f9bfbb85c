#include "scene/scene_file.h"

#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <glm/common.hpp>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <utility>

#include "bake/bake.h"
#include "bake/bake_cache.h"
#include "bake/mesh_surface.h"
#include "bake/provenance.h"
#include "bake/solid_mesh.h"
#include "bake/vdb_bake.h"
#include "check/tile_check.h"
#include "common/error.h"
#include "common/input_file.h"
#include "mesh/base_mesh.h"
#include "render/demo_scene.h"
#include "render/image.h"
#include "sampler/tile_io.h"
#include "truth/mesh_truth.h"
#include "vdb/procedural.h"

namespace distile {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

/// Whether `path` names something that exists; false also where it cannot be looked up (a name
/// too long for the system): the throwing fs::exists ended the process on such a name.
bool fileExists(const fs::path& path) {
    std::error_code status;
    return fs::exists(path, status);
}

/// A JSON value with the path that leads to it, for error messages.
class Field {
  public:
    Field(const json& value, std::string path, const std::string& file)
        : value_(value), path_(std::move(path)), file_(file) {}

    [[noreturn]] void fail(const std::string& message) const {
        throw InputError(where() + ": " + message);
    }
    /// A file this field names is not what distile reads: FormatError, under the field.
    [[noreturn]] void failFormat(const FormatError& error) const {
        throw FormatError(where() + ": " + error.what());
    }
    /// "FILE: PATH", as messages name the field.
    std::string where() const { return file_ + ": " + (path_.empty() ? "top level" : path_); }
    /// "FILE: PATH", or FILE alone for the whole document (a recipe given on its own).
    std::string name() const { return path_.empty() ? file_ : where(); }

    const json& value() const { return value_; }
    const std::string& path() const { return path_; }

    bool has(const std::string& key) const { return value_.contains(key); }

    Field operator[](const std::string& key) const {
        return Field(value_.at(key), path_.empty() ? key : path_ + "." + key, file_);
    }
    Field operator[](std::size_t index) const {
        return Field(value_.at(index), path_ + "[" + std::to_string(index) + "]", file_);
    }

    /// This must be an object whose keys are all in `accepted`.
    void requireObject(std::initializer_list<const char*> accepted) const {
        if (!value_.is_object()) fail("must be an object, not " + std::string(value_.type_name()));
        std::set<std::string> known(accepted.begin(), accepted.end());
        for (const auto& [key, unused] : value_.items()) {
            if (!known.count(key)) {
                std::string list;
                for (const char* name : accepted)
                    list += std::string(list.empty() ? "" : ", ") + name;
                Field(value_.at(key), path_.empty() ? key : path_ + "." + key, file_)
                    .fail("unknown field; accepted here: " + list);
            }
        }
    }

    double number() const {
        if (!value_.is_number()) fail("must be a number, not " + std::string(value_.type_name()));
        const double result = value_.get<double>();
        if (!std::isfinite(result)) fail("must be finite");
        return result;
    }
    double number(double low, double high) const {
        const double result = number();
        if (!(result >= low && result <= high)) {
            fail(numberText(result) + " is not accepted; it must be in [" + numberText(low) + ", " +
                 numberText(high) + "]");
        }
        return result;
    }
    /// Sets `target` to the number at `key`, in [low, high], when the key is given.
    void numberInto(const std::string& key, double& target, double low, double high) const {
        if (has(key)) target = (*this)[key].number(low, high);
    }
    int integer(int low, int high) const {
        const double result = number(low, high);
        if (result != std::floor(result)) fail("must be a whole number");
        return int(result);
    }
    bool boolean() const {
        if (!value_.is_boolean())
            fail("must be true or false, not " + std::string(value_.type_name()));
        return value_.get<bool>();
    }
    std::string string() const {
        if (!value_.is_string()) fail("must be a string, not " + std::string(value_.type_name()));
        return value_.get<std::string>();
    }
    /// A file named by this string, relative to `folder` unless absolute; an empty name is
    /// refused (it named the folder itself).
    fs::path file(const fs::path& folder) const {
        const std::string name = string();
        if (name.empty()) fail("is empty; give a file name");
        return folder / name;
    }
    /// file(folder), which must exist: else "<what> '<path>' does not exist".
    fs::path existingFile(const fs::path& folder, const std::string& what) const {
        const fs::path path = file(folder);
        if (!fileExists(path)) fail(what + " '" + path.string() + "' does not exist");
        return path;
    }
    /// A colour: three numbers, none negative (light and albedo add up, they do not subtract)
    /// nor above kMaxColorComponent (their products over the lights stay finite).
    glm::vec3 colour() const {
        const glm::vec3 result = vector<3>();
        for (int i = 0; i < 3; ++i) {
            if (!acceptedColorComponent(result[i])) {
                (*this)[std::size_t(i)].fail(numberText(result[i]) + " is not accepted; " +
                                             kColorComponentRule);
            }
        }
        return result;
    }
    template <int N>
    glm::vec<N, float> vector() const {
        return glm::vec<N, float>(vectorInDouble<N>());
    }
    /// vector(), its components as given (a position far from the origin keeps its fraction).
    template <int N>
    glm::vec<N, double> vectorInDouble() const {
        if (!value_.is_array() || value_.size() != N)
            fail("must be an array of " + std::to_string(N) + " numbers");
        glm::vec<N, double> result;
        for (int i = 0; i < N; ++i) {
            const double component = (*this)[std::size_t(i)].number();
            if (std::abs(component) > 1e30) {
                std::ostringstream problem;
                problem << component << " is too large; components must be within +-1e30";
                (*this)[std::size_t(i)].fail(problem.str());
            }
            result[i] = component;
        }
        return result;
    }

  private:
    const json& value_;
    std::string path_;
    const std::string& file_;
};

/// A tile size written "WxHxD" or [W, H, D].
Size3 parseSize(const Field& field) {
    Size3 size{0, 0, 0};
    if (field.value().is_array()) {
        if (field.value().size() != 3)
            field.fail("must be [W, H, D] (three whole numbers) or \"WxHxD\"");
        size = {field[0].integer(kMinTileExtent, kMaxTileExtent),
                field[1].integer(kMinTileExtent, kMaxTileExtent),
                field[2].integer(kMinTileExtent, kMaxTileExtent)};
    } else {
        if (!field.value().is_string()) {
            field.fail("must be [W, H, D] (three whole numbers) or \"WxHxD\", not " +
                       std::string(field.value().type_name()));
        }
        try {
            size = parseSize3(field.value().get<std::string>(), field.path());
        } catch (const InputError& error) {
            field.fail(error.problem());
        }
    }
    try {
        validateTileSize(size, field.path());
    } catch (const InputError& error) {
        field.fail(error.problem());
    }
    return size;
}

/// The part of a recipe that BakeOptions decide: "size WxHxD band B\nconservative E T".
std::string bakeOptionsRecipe(const BakeOptions& options) {
    std::ostringstream recipe;
    recipe.precision(17);
    recipe << "size " << options.size.width << "x" << options.size.height << "x"
           << options.size.depth << " band " << options.halfBandTexels << "\nconservative "
           << options.conservative.enabled << " " << options.conservative.toleranceTexels;
    return recipe.str();
}

/// Everything a scene's chain-mail bake depends on (bake/bake_cache.h).
std::string chainmailRecipe(const ChainmailOptions& chainmail, const BakeOptions& options) {
    std::ostringstream recipe;
    recipe.precision(17);
    recipe << "chainmail weave " << weaveName(chainmail.weave) << " rings " << chainmail.ringsPerRow
           << " rows " << chainmail.rowsPerTile << " ring " << chainmail.ringRadiusSpacings
           << " wire " << chainmail.wireRadiusSpacings << " tilt " << chainmail.tiltDeg
           << " small ring " << chainmail.smallRingRadiusSpacings << " small wire "
           << chainmail.smallWireRadiusSpacings << "\n"
           << bakeOptionsRecipe(options) << "\n";
    return recipe.str();
}

/// Everything a scene's grating bake depends on (bake/bake_cache.h).
std::string gratingRecipe(const GratingOptions& grating, const BakeOptions& options) {
    std::ostringstream recipe;
    recipe.precision(17);
    recipe << "grating bars " << grating.barsPerTile << " width " << grating.barWidthTexels
           << " height " << grating.barHeightTexels << " edge " << grating.edgeRadiusTexels
           << " gap " << grating.layerGapTexels << "\n"
           << bakeOptionsRecipe(options) << "\n";
    return recipe.str();
}

/// The part of a recipe that names an input file by its bytes: "KIND file fnv1a HASH bytes N".
std::string fileRecipe(const char* kind, const std::string& fileBytes) {
    return std::string(kind) + " file fnv1a " + contentHash(fileBytes) + " bytes " +
           std::to_string(fileBytes.size());
}

/// Everything a scene's height-map bake depends on (bake/bake_cache.h): the image file's bytes
/// (by hash), the height and the bake options.
std::string heightMapRecipe(const std::string& imageFileBytes, const HeightMapOptions& heightMap,
                            const BakeOptions& options) {
    std::ostringstream recipe;
    recipe.precision(17);
    recipe << fileRecipe("heightmap", imageFileBytes) << " height " << heightMap.heightTexels
           << "\n"
           << bakeOptionsRecipe(options) << "\n";
    return recipe.str();
}

/// Everything a scene's mesh bake depends on (bake/bake_cache.h): the mesh file's bytes (by
/// hash), the placement and the bake options.
std::string meshRecipe(const std::string& meshFileBytes, const MeshPlacement& placement,
                       const MeshSignOptions& sign, const BakeOptions& options) {
    std::ostringstream recipe;
    recipe.precision(17);
    recipe << fileRecipe("mesh", meshFileBytes) << "\nplacement ";
    if (placement.fit) {
        recipe << "fit";
    } else {
        recipe << "scale " << placement.scale << " offset " << placement.offsetTexels.x << " "
               << placement.offsetTexels.y << " " << placement.offsetTexels.z;
    }
    // The recipe's text is part of its hash: changing a word here bakes every cached tile again.
    recipe << "\n" << bakeOptionsRecipe(options);
    if (sign.unsignedDistance) {
        recipe << "\nexact BVH distance, unsigned, thickness " << sign.thicknessTexels << "\n";
    } else {
        recipe << "\nexact BVH distance, winding-number sign (solid mesh bake)\n";
    }
    return recipe.str();
}

/// Everything a scene's vdb bake depends on (bake/bake_cache.h): the file's bytes (by hash), the
/// grid, iso value, placement and the bake options.
std::string vdbRecipe(const std::string& vdbFileBytes, const std::string& gridName,
                      std::optional<double> iso, const VdbPlacement& placement,
                      const BakeOptions& options) {
    std::ostringstream recipe;
    recipe.precision(17);
    recipe << fileRecipe("vdb", vdbFileBytes) << "\ngrid '" << gridName << "' iso ";
    if (iso) {
        recipe << *iso;
    } else {
        recipe << "none";
    }
    recipe << "\nplacement ";
    switch (placement.mode) {
        case VdbPlacement::Mode::Fit:
            recipe << "fit";
            break;
        case VdbPlacement::Mode::Explicit:
            recipe << "scale " << placement.scale << " offset " << placement.offsetTexels.x << " "
                   << placement.offsetTexels.y << " " << placement.offsetTexels.z;
            break;
        case VdbPlacement::Mode::Window:
            recipe << "window " << placement.windowWorld.min.x << " " << placement.windowWorld.min.y
                   << " " << placement.windowWorld.min.z << " " << placement.windowWorld.max.x
                   << " " << placement.windowWorld.max.y << " " << placement.windowWorld.max.z;
            break;
    }
    recipe << "\n"
           << bakeOptionsRecipe(options)
           << "\nband rebuilt: exact BVH distance to the refined surface\n";
    return recipe.str();
}

/// The bake library's error about one field of its options (bake/bake.h) under the key of the
/// tile spec that filled it; other errors under `fallback`, as they are.
[[noreturn]] void failInSpec(const Field& spec, const Field& fallback, const InputError& error) {
    // The library's field and the recipe's key that filled it (a field with two keys, the new
    // name and the older one, is listed under both).
    static const std::pair<std::string_view, std::string_view> keys[] = {
        {"size", "size"},
        {"halfBandTexels", "band"},
        {"heightTexels", "height_texels"},
        {"placement.scale", "scale"},
        {"placement.offsetTexels", "offset"},
        {"placement.windowWorld", "window"},
        {"sign.thicknessTexels", "thickness"},
        {"grid", "grid"},
        {"iso", "iso"},
        {"chainmail.ringsPerRow", "rings_per_row"},
        {"chainmail.rowsPerTile", "rows"},
        {"chainmail.rowsPerTile", "rows_per_tile"},
        {"chainmail.ringRadiusSpacings", "ring_radius"},
        {"chainmail.wireRadiusSpacings", "wire_radius"},
        {"chainmail.tiltDeg", "tilt"},
        {"chainmail.tiltDeg", "tilt_deg"},
        {"chainmail.smallRingRadiusSpacings", "small_ring_radius"},
        {"chainmail.smallWireRadiusSpacings", "small_wire_radius"},
        {"grating.barsPerTile", "bars"},
        {"grating.barWidthTexels", "bar_width"},
        {"grating.barHeightTexels", "bar_height"},
        {"grating.edgeRadiusTexels", "edge_radius"},
        {"grating.layerGapTexels", "layer_gap"}};
    for (const auto& [field, key] : keys) {
        if (error.field() == field && spec.has(std::string(key)))
            spec[std::string(key)].fail(error.problem());
    }
    for (const auto& [field, key] : keys) {  // a default the recipe did not override
        if (error.field() == field)
            spec.fail(std::string(key) + " (not given, its default): " + error.problem());
    }
    // The mesh's sign options have no key in a recipe: their problem (it names the mesh) only.
    if (error.field().rfind("sign.", 0) == 0) fallback.fail(error.problem());
    fallback.fail(error.what());
}

/// The options every recipe shares, under the names of `distile bake`'s flags: size, band,
/// exact_texels.
BakeOptions bakeOptionsOf(const Field& spec) {
    BakeOptions options;
    if (spec.has("size")) options.size = parseSize(spec["size"]);
    if (spec.has("band")) options.halfBandTexels = float(spec["band"].number(0.0, 65536.0));
    if (spec.has("exact_texels")) options.conservative.enabled = !spec["exact_texels"].boolean();
    return options;
}

/// The field `name`, or `olderName` (its older spelling, still accepted) when only that is given.
std::optional<Field> aliased(const Field& spec, const char* name, const char* olderName) {
    if (spec.has(name) && spec.has(olderName)) {
        spec[olderName].fail(std::string("is the older name of '") + name + "'; give only '" +
                             name + "'");
    }
    if (spec.has(name)) return spec[name];
    if (spec.has(olderName)) return spec[olderName];
    return std::nullopt;
}

/// How far a scene is read. Check: every field, and that the files named exist, with nothing
/// loaded or baked; Load: all of it.
enum class Pass { Check, Load };

/// The Check pass's look at a recipe's bake options (size, band), as its bake would refuse them.
void checkBakeOptions(const Field& spec, const BakeOptions& options) {
    try {
        validateBakeOptions(options);
    } catch (const InputError& error) {
        failInSpec(spec, spec, error);
    }
}

/// A recipe's input file (`"file"`, relative to the scene's folder).
struct RecipeFile {
    fs::path path;
    std::string bytes;
};

/// The recipe's input file, read; `what` says what it must be.
RecipeFile recipeFile(const Field& spec, const fs::path& folder, const std::string& what,
                      Pass pass) {
    if (!spec.has("file")) spec.fail("missing field 'file' (" + what + ")");
    const Field file = spec["file"];
    const fs::path path = file.existingFile(folder, "file");
    std::uint64_t bytesInFile = 0;
    try {
        bytesInFile = requireRegularFile(path, "the recipe's input file");
    } catch (const InputError& error) {
        file.fail(error.what());
    }
    requireWithinMemoryBudget(path, "the recipe's input file", bytesInFile);
    if (pass == Pass::Check) return {path, {}};
    std::ifstream in(path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!in.good() && !in.eof()) file.fail("cannot read '" + path.string() + "'");
    return {path, std::move(bytes)};
}

/// A tile a scene bakes, and for a mesh recipe the mesh placed in it (texels).
struct BakedTile {
    std::shared_ptr<const Tile> tile;
    std::shared_ptr<const TriangleSoup> placedMesh;  ///< null unless "bake": "mesh"
};

/// A recipe's level set asked for with its tile (bakeRecipeLevelSet, with an empty TileCache):
/// the bake cache holds tiles only, so such a recipe is always baked (bakeThroughCache).
struct LevelSetRequest {
    int repeatX = 1, repeatY = 1;      ///< the level set tiled so many times (LevelSet::repeated)
    std::optional<LevelSet> levelSet;  ///< the bake's, once baked
};

/// Refuses `request`'s repeats for the level set of the recipe `spec` (LevelSet::checkRepeat)
/// under the keyword "repeat", before the bake; its size and band first under their own keys.
void checkRepeat(const Field& spec, const LevelSetRequest& request) {
    const BakeOptions options = bakeOptionsOf(spec);
    checkBakeOptions(spec, options);
    try {
        LevelSet::checkRepeat(options.size, validatedHalfBandTexels(options), request.repeatX,
                              request.repeatY);
    } catch (const InputError& error) {
        throw InputError(spec.name() + ": repeat: " + error.problem());
    }
}

/// The tile `bake` makes for `recipe`, through the bake cache (cachedBake, `sourceHash` as
/// there); with `levelSet`, baked here and its level set tiled into `levelSet`, the cache
/// neither read nor written.
std::shared_ptr<const Tile> bakeThroughCache(const std::string& recipe,
                                             const std::function<BakeResult()>& bake,
                                             LevelSetRequest* levelSet,
                                             const std::string& sourceHash = {}) {
    if (!levelSet)
        return cachedBake(
            recipe, [&] { return bake().tile; }, sourceHash);
    BakeResult baked = bake();
    if (levelSet->repeatX > 1 || levelSet->repeatY > 1)
        levelSet->levelSet.emplace(baked.levelSet.repeated(levelSet->repeatX, levelSet->repeatY));
    else
        levelSet->levelSet.emplace(std::move(baked.levelSet));
    return std::make_shared<const Tile>(std::move(baked.tile));
}

/// `tile` recording `path` as its source file. A recipe names its input file by the file's bytes,
/// so the tile that `tiles` or the bake cache hold for it may have been baked from a copy of the
/// file elsewhere and record that copy: the tile a bake returns would then depend on what was
/// baked before. The distances are the same; a copy of the tile names `path` instead.
std::shared_ptr<const Tile> recordingSource(std::shared_ptr<const Tile> tile,
                                            const fs::path& path) {
    const fs::path file = fs::absolute(path).lexically_normal();  // as recordSourceFile
    if (tile->provenance.sourceFile == file) return tile;
    auto copy = std::make_shared<Tile>(*tile);
    copy->provenance.sourceFile = file;
    return copy;
}

/// The tile of a recipe that bakes the file `source` read (`bake` bakes it again from its path):
/// from `tiles` or the bake cache when there, else baked and recorded there, its source file
/// recorded in its provenance; with `levelSet`, as bakeThroughCache bakes it.
/// The bake's errors are told under the spec's keys or its "file".
BakedTile bakedFileTile(const Field& spec, TileCache& tiles, const std::string& recipe,
                        const RecipeFile& source, const std::function<BakeResult()>& bake,
                        LevelSetRequest* levelSet) {
    const fs::path& path = source.path;
    const std::string key = "bake:" + recipe;
    if (auto found = tiles.find(key); found != tiles.end())
        return {recordingSource(found->second, path), nullptr};
    try {
        auto tile = bakeThroughCache(
            recipe,
            [&] {
                BakeResult baked = bake();
                recordSourceFile(baked.tile.provenance, path);
                return baked;
            },
            levelSet, contentHash(source.bytes));
        tiles[key] = tile;
        return {recordingSource(tile, path), nullptr};
    } catch (const InputError& error) {
        failInSpec(spec, spec["file"], error);
    } catch (const FormatError& error) {
        spec["file"].failFormat(error);
    }
}

/// The placement of a mesh or vdb recipe under the names of `distile bake`'s flags: "fit"
/// (the default) or "scale" and "offset" (texels).
MeshPlacement meshPlacementOf(const Field& spec) {
    MeshPlacement placement;
    if (spec.has("fit") && spec["fit"].boolean() && (spec.has("scale") || spec.has("offset")))
        spec["fit"].fail("cannot be combined with scale/offset; give one placement");
    if (spec.has("fit") && !spec["fit"].boolean() && !spec.has("scale") && !spec.has("offset"))
        spec["fit"].fail("false needs the explicit placement instead: give scale and/or offset");
    if (spec.has("scale") || spec.has("offset")) {
        placement.fit = false;
        if (spec.has("scale")) placement.scale = spec["scale"].number(1e-12, 1e12);
        if (spec.has("offset")) {
            const Field offset = spec["offset"];
            if (!offset.value().is_array() || offset.value().size() != 3)
                offset.fail("must be an array of 3 numbers (texels)");
            for (int axis = 0; axis < 3; ++axis)
                placement.offsetTexels[axis] = offset[std::size_t(axis)].number(-1e6, 1e6);
        }
    }
    return placement;
}

/// `"tile": {"bake": "vdb", "file": ..., "grid": ..., "iso": ..., "fit" | "scale"/"offset" |
/// "window": [X0, Y0, Z0, X1, Y1, Z1]}`: the level set baked as `distile bake vdb` does
/// (bake/vdb_bake.h).
BakedTile bakedVdbTile(const Field& spec, const fs::path& folder, TileCache& tiles, Pass pass,
                       LevelSetRequest* levelSet, const ProgressCallback& progress) {
    spec.requireObject({"bake", "file", "size", "band", "exact_texels", "grid", "iso", "fit",
                        "scale", "offset", "window"});
    const BakeOptions options = bakeOptionsOf(spec);
    VdbPlacement placement;
    if (spec.has("window")) {
        if (spec.has("fit") || spec.has("scale") || spec.has("offset"))
            spec["window"].fail("cannot be combined with fit/scale/offset; give one placement");
        const Field window = spec["window"];
        if (!window.value().is_array() || window.value().size() != 6)
            window.fail("must be an array of 6 numbers [X0, Y0, Z0, X1, Y1, Z1] (world units)");
        glm::dvec3 corners[2];
        for (int i = 0; i < 6; ++i) corners[i / 3][i % 3] = window[std::size_t(i)].number();
        placement.mode = VdbPlacement::Mode::Window;
        placement.windowWorld = {corners[0], corners[1]};
    } else if (const MeshPlacement fitOrExplicit = meshPlacementOf(spec); !fitOrExplicit.fit) {
        placement.mode = VdbPlacement::Mode::Explicit;
        placement.scale = fitOrExplicit.scale;
        placement.offsetTexels = fitOrExplicit.offsetTexels;
    }
    const std::string gridName = spec.has("grid") ? spec["grid"].string() : std::string();
    if (spec.has("grid") && gridName.empty())
        spec["grid"].fail(
            "is empty; name a grid, or leave \"grid\" out for the file's only float "
            "level set");
    std::optional<double> iso;
    if (spec.has("iso")) iso = spec["iso"].number();
    const RecipeFile source = recipeFile(spec, folder, "an OpenVDB .vdb file", pass);
    if (pass == Pass::Check) {
        checkBakeOptions(spec, options);
        return {};
    }
    const fs::path& path = source.path;
    const std::string& bytes = source.bytes;
    const std::string recipe = vdbRecipe(bytes, gridName, iso, placement, options);
    return bakedFileTile(
        spec, tiles, recipe, source,
        [&] {
            const VdbVolume volume = VdbVolume::read(path, gridName, iso);
            return bakeVdb(volume, placement, options, path.filename().string(), progress).bake;
        },
        levelSet);
}

/// `"tile": {"bake": "mesh", "file": ..., "size": ..., "scale": ..., "offset": ...}`: the detail
/// mesh baked as `distile bake mesh` does (bake/solid_mesh.h), fitted to the footprint unless
/// scale or offset is given. The mesh's warnings go to `warn`.
BakedTile bakedMeshTile(const Field& spec, const fs::path& folder, TileCache& tiles,
                        const SceneWarningCallback& warn, Pass pass, LevelSetRequest* levelSet,
                        const ProgressCallback& progress) {
    spec.requireObject({"bake", "file", "size", "band", "exact_texels", "fit", "scale", "offset",
                        "unsigned", "thickness"});
    BakeOptions options = bakeOptionsOf(spec);
    options.fillLevelSetMargins = levelSet != nullptr;  // only a written level set needs them
    const MeshPlacement placement = meshPlacementOf(spec);
    MeshSignOptions sign;
    if (spec.has("unsigned")) sign.unsignedDistance = spec["unsigned"].boolean();
    if (spec.has("thickness")) {
        if (!sign.unsignedDistance)
            spec["thickness"].fail(
                "needs \"unsigned\": true (it is the thickness of the shell around an unsigned "
                "surface)");
        sign.thicknessTexels = spec["thickness"].number(0.0, 65536.0);
    }
    const RecipeFile source = recipeFile(spec, folder, "a detail mesh: OBJ, PLY, OFF or STL", pass);
    if (pass == Pass::Check) {
        checkBakeOptions(spec, options);
        return {};
    }
    const fs::path& path = source.path;
    const std::string& bytes = source.bytes;
    const Field file = spec["file"];
    const std::string recipe = meshRecipe(bytes, placement, sign, options);
    BakedTile baked;
    try {
        const SolidDetailMesh solid = loadSolidDetailMesh(path, sign);
        const TriangleSoup& mesh = solid.mesh;
        baked.placedMesh =
            std::make_shared<const TriangleSoup>(placeMesh(mesh, placement, options.size));
        const std::string key = "bake:" + recipe;
        if (auto found = tiles.find(key); found != tiles.end()) {
            baked.tile = found->second;
        } else {
            baked.tile = bakeThroughCache(
                recipe,
                [&] {
                    BakeResult result =
                        bakeSolidMesh(mesh, placement, options, path.string(), progress, sign)
                            .result;
                    recordSourceFile(result.tile.provenance, path);
                    return result;
                },
                levelSet, contentHash(bytes));
            tiles[key] = baked.tile;
        }
        baked.tile = recordingSource(baked.tile, path);
        // After the bake: a refused mesh gets its one-line error only.
        if (warn) {
            for (const std::string& warning : solid.warnings) warn(warning);
        }
    } catch (const InputError& error) {
        failInSpec(spec, file, error);
    } catch (const FormatError& error) {
        file.failFormat(error);
    }
    return baked;
}

/// `"tile": {"bake": "heightmap", "file": ..., "height_texels": ...}`: the image baked as
/// `distile bake heightmap` does.
BakedTile bakedHeightMapTile(const Field& spec, const fs::path& folder, TileCache& tiles, Pass pass,
                             LevelSetRequest* levelSet, const ProgressCallback& progress) {
    spec.requireObject({"bake", "file", "size", "band", "exact_texels", "height_texels"});
    const BakeOptions options = bakeOptionsOf(spec);
    HeightMapOptions heightMap;
    spec.numberInto("height_texels", heightMap.heightTexels, 0.0, 65536.0);
    const RecipeFile source = recipeFile(spec, folder, "a grey image: PNG or EXR", pass);
    if (pass == Pass::Check) {
        checkBakeOptions(spec, options);
        return {};
    }
    const fs::path& path = source.path;
    const std::string& bytes = source.bytes;
    const std::string recipe = heightMapRecipe(bytes, heightMap, options);
    return bakedFileTile(
        spec, tiles, recipe, source,
        [&] { return bakeHeightMap(readHeightImage(path), heightMap, options, progress); },
        levelSet);
}

/// The chain mail of `"bake": "chainmail"`, under the names of `distile bake chainmail`'s flags
/// (`rows_per_tile` and `tilt_deg` are the older names of `rows` and `tilt`); options not given
/// take the weave's defaults.
ChainmailOptions chainmailOf(const Field& spec) {
    spec.requireObject({"bake", "size", "band", "exact_texels", "weave", "rings_per_row", "rows",
                        "rows_per_tile", "ring_radius", "wire_radius", "tilt", "tilt_deg",
                        "small_ring_radius", "small_wire_radius"});
    ChainmailOptions chainmail;
    if (spec.has("weave")) {
        const std::string weave = spec["weave"].string();
        if (weave == weaveName(ChainmailWeave::Japanese4in1)) {
            chainmail = japanese4in1Defaults();
        } else if (weave != weaveName(ChainmailWeave::European4in1)) {
            spec["weave"].fail("'" + weave +
                               "' is not accepted; accepted: european4in1, japanese4in1");
        }
    }
    if (spec.has("rings_per_row")) chainmail.ringsPerRow = spec["rings_per_row"].integer(1, 4096);
    if (const auto rows = aliased(spec, "rows", "rows_per_tile"))
        chainmail.rowsPerTile = rows->integer(1, 4096);
    spec.numberInto("ring_radius", chainmail.ringRadiusSpacings, 0.0, 2.0);
    spec.numberInto("wire_radius", chainmail.wireRadiusSpacings, 0.0, 2.0);
    if (const auto tilt = aliased(spec, "tilt", "tilt_deg"))
        chainmail.tiltDeg = tilt->number(0.0, 60.0);
    if (chainmail.weave != ChainmailWeave::Japanese4in1) {
        // The European weave has no small rings: a value for them would be silently ignored.
        for (const char* name : {"small_ring_radius", "small_wire_radius"}) {
            if (spec.has(name))
                spec[name].fail(
                    "only for \"weave\": \"japanese4in1\" (the European weave has "
                    "no small rings)");
        }
    }
    spec.numberInto("small_ring_radius", chainmail.smallRingRadiusSpacings, 0.0, 1.0);
    spec.numberInto("small_wire_radius", chainmail.smallWireRadiusSpacings, 0.0, 1.0);
    return chainmail;
}

/// The grating of `"bake": "grating"`, under the names of `distile bake grating`'s flags.
GratingOptions gratingOf(const Field& spec) {
    spec.requireObject({"bake", "size", "band", "exact_texels", "bars", "bar_width", "bar_height",
                        "edge_radius", "layer_gap"});
    GratingOptions grating;
    if (spec.has("bars")) grating.barsPerTile = spec["bars"].integer(1, 16384);
    spec.numberInto("bar_width", grating.barWidthTexels, 0.0, 65536.0);
    spec.numberInto("bar_height", grating.barHeightTexels, 0.0, 65536.0);
    spec.numberInto("edge_radius", grating.edgeRadiusTexels, 0.0, 65536.0);
    spec.numberInto("layer_gap", grating.layerGapTexels, 0.0, 65536.0);
    return grating;
}

/// The tile of a procedural pattern with the verdict of its check against the analytic truth
/// recorded (check/tile_check.h), so a cached tile warns as a fresh one does.
BakeResult checkedProceduralBake(const ProceduralOptions& procedural, const BakeOptions& options,
                                 const ProgressCallback& progress = {}) {
    BakeResult baked = bakeProcedural(procedural, options, progress);
    recordAnalyticCheck(baked.tile);
    return baked;
}

/// Gives `warn` the warning of a tile whose recorded check missed the tolerances, naming the
/// scene's field that holds it. Called once per tile and load: when it is first read or baked.
void warnOfRecordedCheck(const Tile& tile, const Field& field, const SceneWarningCallback& warn) {
    if (!warn) return;
    if (const std::string warning = recordedCheckWarning(tile, field.name()); !warning.empty())
        warn(warning + "; a larger \"size\", or thicker or rounder detail, holds them better");
}

BakedTile bakedTile(const Field& spec, const fs::path& folder, TileCache& tiles,
                    const SceneWarningCallback& warn, Pass pass,
                    LevelSetRequest* levelSet = nullptr, const ProgressCallback& progress = {}) {
    if (!spec.has("bake")) {
        spec.fail(
            "missing field 'bake' (the detail to bake: chainmail, grating, heightmap, mesh, vdb)");
    }
    const std::string kind = spec["bake"].string();
    if (kind == "mesh") return bakedMeshTile(spec, folder, tiles, warn, pass, levelSet, progress);
    if (kind == "heightmap")
        return bakedHeightMapTile(spec, folder, tiles, pass, levelSet, progress);
    if (kind == "vdb") return bakedVdbTile(spec, folder, tiles, pass, levelSet, progress);
    ProceduralOptions procedural;
    std::string recipe;
    if (kind == "chainmail") {
        procedural.kind = ProceduralKind::Chainmail;
        procedural.chainmail = chainmailOf(spec);
        recipe = chainmailRecipe(procedural.chainmail, bakeOptionsOf(spec));
    } else if (kind == "grating") {
        procedural.kind = ProceduralKind::Grating;
        procedural.grating = gratingOf(spec);
        recipe = gratingRecipe(procedural.grating, bakeOptionsOf(spec));
    } else {
        spec["bake"].fail("'" + kind +
                          "' is not a known detail; accepted: chainmail, grating, heightmap, mesh, "
                          "vdb");
    }
    const BakeOptions options = bakeOptionsOf(spec);
    if (pass == Pass::Check) {
        checkBakeOptions(spec, options);
        try {
            proceduralDistance(procedural, options.size);  // the pattern's own checks
        } catch (const InputError& error) {
            failInSpec(spec, spec, error);
        }
        return {};
    }
    const std::string key = "bake:" + recipe;
    if (auto found = tiles.find(key); found != tiles.end()) return {found->second, nullptr};
    try {
        auto tile = bakeThroughCache(
            recipe, [&] { return checkedProceduralBake(procedural, options, progress); }, levelSet);
        tiles[key] = tile;
        warnOfRecordedCheck(*tile, spec, warn);
        return {tile, nullptr};
    } catch (const InputError& error) {
        failInSpec(spec, spec, error);
    }
}

std::shared_ptr<const Tile> tileFile(const Field& field, const fs::path& folder, TileCache& tiles,
                                     const SceneWarningCallback& warn, Pass pass) {
    const fs::path path = field.existingFile(folder, "tile file");
    if (pass == Pass::Check) return nullptr;
    std::error_code status;  // weakly_canonical only fails where fileExists did not
    const std::string key = "file:" + fs::weakly_canonical(path, status).string();
    if (auto found = tiles.find(key); found != tiles.end()) return found->second;
    try {
        auto tile = std::make_shared<const Tile>(readTileExr(path));
        tiles[key] = tile;
        warnOfRecordedCheck(*tile, field, warn);
        return tile;
    } catch (const FormatError& error) {
        field.failFormat(error);
    }
}

/// The built-in mesh `name` (plane, sphere, torus), or null for any other name (a file). Each is
/// made once per process and copied where it is used: a scene of many spheres spent most of its
/// loading on the same tangent frames and welds again (1000 spheres: 3.3 s).
const BaseMesh* builtInMesh(const std::string& name) {
    if (name == "plane") {
        static const BaseMesh plane = makePlane(2.0f, 1);
        return &plane;
    }
    if (name == "sphere") {
        static const BaseMesh sphere = makeUvSphere(1.0f, 96, 48);
        return &sphere;
    }
    if (name == "torus") {
        static const BaseMesh torus = makeTorus(1.0f, 0.4f, 128, 48);
        return &torus;
    }
    return nullptr;
}

/// The mesh file `field` names (not a built-in mesh), which must exist.
fs::path meshFile(const Field& field, const fs::path& folder) {
    const fs::path path = field.file(folder);
    if (!fileExists(path)) {
        field.fail("'" + field.string() +
                   "' is neither a built-in mesh (plane, sphere, torus) nor an existing file (" +
                   path.string() + ")");
    }
    return path;
}

BaseMesh loadMesh(const Field& field, const fs::path& folder) {
    if (const BaseMesh* builtIn = builtInMesh(field.string())) return *builtIn;
    return loadBaseMesh(meshFile(field, folder));
}

/// A progress callback that asks `bakeProgress` for the callback of the bake of `what` on its
/// first report (a bake reports; a tile read from a cache does not) and reports to it; that
/// callback lives as long as this one's copies. None without `bakeProgress`.
ProgressCallback reportingBake(const BakeProgress& bakeProgress, const std::string& what) {
    if (!bakeProgress) return {};
    auto made = std::make_shared<ProgressCallback>();
    return [bakeProgress, what, made](double fractionDone) {
        if (!*made) *made = bakeProgress(what);
        if (*made) (*made)(fractionDone);
    };
}

/// The material of `field`; stores the placed mesh of a `"bake": "mesh"` tile in `placedMesh`
/// and gives the warnings of its bake to `warn`, its progress to the callback `bakeProgress`
/// makes. Pass::Check reads the fields and looks for the files only: the material has no tile or
/// colour texture.
Material loadMaterial(const Field& field, const fs::path& folder, TileCache& tiles,
                      std::shared_ptr<const TriangleSoup>& placedMesh,
                      const SceneWarningCallback& warn, Pass pass,
                      const BakeProgress& bakeProgress) {
    field.requireObject({"tile", "uv_scale", "depth", "floor", "color"});
    Material material;
    if (field.has("tile")) {
        const Field tile = field["tile"];
        if (tile.value().is_object()) {
            BakedTile baked = bakedTile(tile, folder, tiles, warn, pass, nullptr,
                                        reportingBake(bakeProgress, tile.name()));
            material.tile = std::move(baked.tile);
            placedMesh = std::move(baked.placedMesh);
        } else {
            material.tile = tileFile(tile, folder, tiles, warn, pass);
        }
    }
    if (field.has("uv_scale")) material.uvScale = field["uv_scale"].vector<2>();
    if (material.uvScale.x <= 0.0f || material.uvScale.y <= 0.0f)
        field["uv_scale"].fail("must be two positive numbers");
    if (field.has("depth")) {
        material.depthWorld = float(field["depth"].number());
        if (!(material.depthWorld > 0.0f)) {
            std::ostringstream message;
            message << material.depthWorld
                    << " is not accepted; it must be a positive number of world units";
            field["depth"].fail(message.str());
        }
    }
    if (field.has("floor")) {
        const std::string floor = field["floor"].string();
        if (floor == "solid") {
            material.floor = Floor::Solid;
        } else if (floor == "open") {
            material.floor = Floor::Open;
        } else {
            field["floor"].fail("'" + floor + "' is not accepted; accepted: solid, open");
        }
    }
    if (field.has("color")) {
        const Field color = field["color"];
        if (color.value().is_string()) {
            const fs::path path = color.existingFile(folder, "colour texture");
            if (pass == Pass::Check) return material;
            try {
                material.colorTexture = std::make_shared<const Image>(readImage(path));
            } catch (const FormatError& error) {
                color.failFormat(error);
            }
            // An albedo is in [0, kMaxColorComponent], in a texture as in an array (an EXR may
            // hold any value).
            const auto& texels = material.colorTexture->rgbLinear;
            for (std::size_t i = 0; i < texels.size(); ++i) {
                const glm::vec3& texel = texels[i];
                if (!(acceptedColorComponent(texel.r) && acceptedColorComponent(texel.g) &&
                      acceptedColorComponent(texel.b))) {
                    const std::size_t width = std::size_t(material.colorTexture->width);
                    std::ostringstream message;
                    message << "colour texture '" << path.string() << "': pixel (" << i % width
                            << ", " << i / width << ") is (" << texel.r << ", " << texel.g << ", "
                            << texel.b << "); " << kColorComponentRule;
                    color.fail(message.str());
                }
            }
        } else {
            material.color = color.colour();
        }
    }
    return material;
}

/// `text` parsed as JSON; FormatError naming `name` when it is not JSON, or when it holds a NUL
/// character or a key given twice in one object. The parser stops at a NUL byte (what follows
/// went unread), a path ends at one (a "tile" of "chain.exr\u0000x" opened chain.exr), messages
/// quoting one were cut short; and it keeps the last of a key given twice, where which was meant
/// is unknown.
json parseJson(const std::string& text, const std::string& name) {
    if (const std::size_t at = text.find('\0'); at != std::string::npos) {
        throw FormatError(name + ": byte " + std::to_string(at) +
                          " is a NUL byte; a scene is JSON text");
    }
    // The path to each value is followed as the parser reads (it reads iteratively, however
    // deep the document nests), and the first problem is kept with it.
    struct Level {
        bool array = false;
        std::size_t index = 0;       ///< array: the element being read
        std::string key;             ///< object: the member being read
        std::set<std::string> keys;  ///< object: the keys so far
    };
    std::vector<Level> levels;
    std::string problem;  ///< "PATH: what is wrong" of the first problem
    const auto pathOf = [&](std::size_t count) {
        std::string path;
        for (std::size_t i = 0; i < count; ++i) {
            path += levels[i].array ? "[" + std::to_string(levels[i].index) + "]"
                                    : (path.empty() ? "" : ".") + levels[i].key;
        }
        return path.empty() ? std::string("top level") : path;
    };
    const auto holdsNul = [](const json& value) {
        return value.get_ref<const std::string&>().find('\0') != std::string::npos;
    };
    const std::string kNul = " holds a NUL character (\\u0000); accepted: text without one";
    const json::parser_callback_t track = [&](int, json::parse_event_t event, json& parsed) {
        using Event = json::parse_event_t;
        const auto elementDone = [&] {
            if (!levels.empty() && levels.back().array) ++levels.back().index;
        };
        switch (event) {
            case Event::object_start:
            case Event::array_start:
                levels.push_back({event == Event::array_start, 0, {}, {}});
                break;
            case Event::key: {
                const std::string& key = parsed.get_ref<const std::string&>();
                if (problem.empty() && holdsNul(parsed))
                    problem = pathOf(levels.size() - 1) + ": a key" + kNul;
                if (!levels.back().keys.insert(key).second && problem.empty()) {
                    problem = pathOf(levels.size() - 1) + ": key '" + key +
                              "' is given twice in one object; give each key once";
                }
                levels.back().key = key;
                break;
            }
            case Event::object_end:
            case Event::array_end:
                levels.pop_back();
                elementDone();
                break;
            case Event::value:
                if (problem.empty() && parsed.is_string() && holdsNul(parsed))
                    problem = pathOf(levels.size()) + ": the text" + kNul;
                elementDone();
                break;
        }
        return true;
    };
    json document;
    try {
        document = json::parse(text, track);
    } catch (const json::exception& error) {
        // The parser's message quotes the bytes it last read, which may be any bytes.
        const std::string what = error.what();
        throw FormatError(name + ": not valid JSON (" + quotedInput(what, what.size()) + ")");
    }
    if (!problem.empty()) throw FormatError(name + ": " + problem);
    return document;
}

}  // namespace

SceneFile loadSceneFile(const fs::path& file, TileCache& tiles, const SceneWarningCallback& warn,
                        const BakeProgress& bakeProgress) {
    requireWithinMemoryBudget(file, "a scene file", requireRegularFile(file, "a scene .json file"));
    std::ifstream in(file);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const fs::path folder = file.has_parent_path() ? file.parent_path() : fs::path(".");
    return loadSceneJson(text, folder, file.string(), tiles, warn, bakeProgress);
}

std::shared_ptr<const Tile> bakeRecipeTile(const std::string& recipeJson, const fs::path& folder,
                                           const std::string& name, TileCache& tiles,
                                           const SceneWarningCallback& warn,
                                           const ProgressCallback& progress) {
    const json document = parseJson(recipeJson, name);
    return bakedTile(Field(document, "", name), folder, tiles, warn, Pass::Load, nullptr, progress)
        .tile;
}

RecipeLevelSet bakeRecipeLevelSet(const std::string& recipeJson, const fs::path& folder,
                                  const std::string& name, int repeatX, int repeatY,
                                  const SceneWarningCallback& warn,
                                  const ProgressCallback& progress) {
    const json document = parseJson(recipeJson, name);
    TileCache unused;
    LevelSetRequest request;
    request.repeatX = repeatX;
    request.repeatY = repeatY;
    checkRepeat(Field(document, "", name), request);
    std::shared_ptr<const Tile> tile =
        bakedTile(Field(document, "", name), folder, unused, warn, Pass::Load, &request, progress)
            .tile;
    return {std::move(tile), std::move(*request.levelSet)};
}

/// The grid of the origin a scene is moved to (loadSceneJson): world units.
constexpr double kOriginGridWorld = 1024.0;

SceneFile loadSceneJson(const std::string& sceneJson, const fs::path& folder,
                        const std::string& name, TileCache& tiles, const SceneWarningCallback& warn,
                        const BakeProgress& bakeProgress) {
    const json document = parseJson(sceneJson, name);
    const std::string& fileName = name;
    const Field root(document, "", fileName);
    // "$schema" lets editors find docs/scene.schema.json; the reader only checks it is a string.
    root.requireObject({"$schema", "camera", "image", "lights", "objects"});
    if (root.has("$schema")) root["$schema"].string();

    SceneFile result;
    Scene& scene = result.scene;
    // The scene is placed relative to what its camera looks at: positions are taken in double
    // precision and moved by `origin`, the multiple of kOriginGridWorld nearest the camera's
    // target, before they are rounded to float, so a scene far from the world origin renders as
    // precisely as one near it (floats at 1e5 resolve 0.008 world units). The target, not the
    // eye: the objects looked at keep their precision when the eye is far from them (a distant
    // eye at 1e5 moved a unit sphere at the origin there, and its shell folded). A target within
    // half the grid of the origin moves nothing. What the renderer writes (colours, depth along
    // the ray, normals) does not depend on where the origin is.
    glm::dvec3 eye(scene.camera.eye), target(scene.camera.target);
    if (root.has("camera")) {
        const Field camera = root["camera"];
        camera.requireObject({"eye", "target", "up", "fov_deg"});
        if (camera.has("eye")) eye = camera["eye"].vectorInDouble<3>();
        if (camera.has("target")) target = camera["target"].vectorInDouble<3>();
        if (camera.has("up")) scene.camera.up = camera["up"].vector<3>();
        if (camera.has("fov_deg"))
            scene.camera.fovDeg = float(camera["fov_deg"].number(1e-3, 179.0));
    }
    const glm::dvec3 origin = kOriginGridWorld * glm::round(target / kOriginGridWorld);
    scene.camera.eye = glm::vec3(eye - origin);
    scene.camera.target = glm::vec3(target - origin);
    if (root.has("image")) {
        const Field image = root["image"];
        image.requireObject({"width", "height", "spp"});
        if (image.has("width")) result.image.width = image["width"].integer(1, 16384);
        if (image.has("height")) result.image.height = image["height"].integer(1, 16384);
        if (image.has("spp")) result.image.samplesPerPixel = image["spp"].integer(1, 256);
    }
    if (root.has("lights")) {
        const Field lights = root["lights"];
        if (!lights.value().is_array()) lights.fail("must be an array");
        scene.lights.clear();
        for (std::size_t i = 0; i < lights.value().size(); ++i) {
            const Field light = lights[i];
            light.requireObject({"type", "direction", "color", "angle_deg"});
            DirectionalLight parsed;
            if (light.has("type") && light["type"].string() != "directional") {
                light["type"].fail("'" + light["type"].string() +
                                   "' is not accepted; accepted: directional");
            }
            if (light.has("direction")) parsed.direction = light["direction"].vector<3>();
            if (light.has("color")) parsed.color = light["color"].colour();
            if (light.has("angle_deg"))
                parsed.angleDeg = float(light["angle_deg"].number(0.0, 89.0));
            scene.lights.push_back(parsed);
        }
    }
    if (!root.has("objects"))
        root.fail("missing field 'objects' (an array of objects with mesh and material)");
    const Field objects = root["objects"];
    if (!objects.value().is_array() || objects.value().empty())
        objects.fail("must be a non-empty array");
    // The objects are read twice: first every field, and that the files named exist, with
    // nothing loaded or baked, so that a mistake anywhere in the scene is reported at once (a
    // misspelt key after a tile to bake took the bake's seconds, a missing file after a large
    // mesh its loading); then loaded.
    for (const Pass pass : {Pass::Check, Pass::Load}) {
        std::size_t triangles = 0;
        for (std::size_t i = 0; i < objects.value().size(); ++i) {
            const Field object = objects[i];
            object.requireObject({"mesh", "transform", "material"});
            if (!object.has("mesh"))
                object.fail("missing field 'mesh' (plane, sphere, torus or a mesh file)");
            SceneObject parsed;
            if (pass == Pass::Check) {
                if (!builtInMesh(object["mesh"].string())) meshFile(object["mesh"], folder);
            } else {
                parsed.mesh = loadMesh(object["mesh"], folder);
                triangles += parsed.mesh.triangles.size();
                try {
                    requireSceneTriangleBudget(i, triangles);
                } catch (const InputError& error) {
                    object["mesh"].fail(error.problem());
                }
            }
            Transform placement;
            glm::dvec3 translate(0.0);
            if (object.has("transform")) {
                const Field transform = object["transform"];
                transform.requireObject({"translate", "rotate_deg", "scale"});
                if (transform.has("translate"))
                    translate = transform["translate"].vectorInDouble<3>();
                if (transform.has("rotate_deg"))
                    placement.rotateDeg = transform["rotate_deg"].vector<3>();
                if (transform.has("scale"))
                    placement.scale = float(transform["scale"].number(1e-12, 1e12));
            }
            placement.translate = glm::vec3(translate - origin);
            // A mesh neither transformed nor moved is left as read (applyTransform would normalise
            // its normals again, changing their last bits).
            if (pass == Pass::Load && (object.has("transform") || origin != glm::dvec3(0.0)))
                applyTransform(parsed.mesh, placement);
            std::shared_ptr<const TriangleSoup> placedMesh;
            if (object.has("material")) {
                parsed.material = loadMaterial(object["material"], folder, tiles, placedMesh, warn,
                                               pass, bakeProgress);
            }
            if (pass == Pass::Check) continue;
            scene.objects.push_back(std::move(parsed));
            result.placedDetailMeshes.push_back(std::move(placedMesh));
        }
    }
    try {
        validateScene(scene);
    } catch (const InputError& error) {
        throw InputError(fileName + ": " + underSceneJsonPath(error).what());
    }
    return result;
}

std::string sceneJsonPath(std::string_view field) {
    // The Scene members whose JSON key differs (docs/scene.md); the others are spelled alike.
    static constexpr std::pair<std::string_view, std::string_view> kKeys[] = {
        {"fovDeg", "fov_deg"},   {"angleDeg", "angle_deg"}, {"rotateDeg", "rotate_deg"},
        {"depthWorld", "depth"}, {"uvScale", "uv_scale"},
    };
    std::string path;
    std::size_t begin = 0;
    while (begin <= field.size()) {
        const std::size_t dot = std::min(field.find('.', begin), field.size());
        std::string_view part = field.substr(begin, dot - begin);
        const std::string_view index = part.substr(std::min(part.find('['), part.size()));
        const std::string_view name = part.substr(0, part.size() - index.size());
        std::string key(name);
        for (const auto& [member, json] : kKeys) {
            if (name == member) key = json;
        }
        path += (begin == 0 ? "" : ".") + key + std::string(index);
        begin = dot + 1;
    }
    return path;
}

InputError underSceneJsonPath(const InputError& error) {
    return error.field().empty() ? error : error.renamed(sceneJsonPath(error.field()));
}

SceneFile demoScene(TileCache& tiles, const BakeProgress& bakeProgress) {
    auto key = std::string("bake:demo-chainmail");
    // The meshes are built while the tile is read (or baked): neither needs the other.
    DemoMeshes meshes;
    tbb::parallel_invoke(
        [&] { meshes = demoMeshes(); },
        [&] {
            if (tiles.count(key)) return;
            const ProgressCallback progress = reportingBake(bakeProgress, "the demo's tile");
            tiles[key] = cachedBake(chainmailRecipe({}, {}),
                                    [&] { return checkedProceduralBake({}, {}, progress).tile; });
        });
    SceneFile demo;
    demo.scene = distile::demoScene(tiles[key], std::move(meshes));
    return demo;
}

namespace {

/// The mesh truth of a `"bake": "mesh"` tile as the material's exact hit and analytic distance;
/// for a mesh that is not closed or whose parts overlap or nest, the analytic distance the bake
/// measured (its triangles and the caps over its holes, signed by its winding number:
/// bake/mesh_surface.h), sphere traced.
void attachMeshTruth(Material& material, const TriangleSoup& placedMesh) {
    auto truth = std::make_shared<const MeshDistance>(
        placedMesh, MeshDistance::Periodic{material.tile->size()});
    const Size3 size = material.tile->size();
    auto surface = std::make_shared<const MeshSurfaceDistance>(placedMesh, size);
    if (!insideTestSignsAlike(*truth, surface->surface(), placedMesh)) {
        // Farther than any point of the tile's box can be from detail inside it.
        const double cutoff = double(size.width + size.height + size.depth);
        material.analyticDistance = [surface, cutoff](const glm::dvec3& texelPosition) {
            return surface->signedDistance(texelPosition, cutoff);
        };
        return;
    }
    const double meshTopTexels = boundsOf(placedMesh).max.z;
    material.analyticDistance = [truth](const glm::dvec3& texelPosition) {
        return truth->signedDistance(texelPosition);
    };
    material.exactHit = [truth, meshTopTexels](const glm::dvec3& origin,
                                               const glm::dvec3& direction,
                                               double maxTravelTexels) -> std::optional<DetailHit> {
        // A ray that starts inside the solid (a mesh cut by the top z = D) is in the detail at
        // once; the surface there is the top plane, as sphere tracing finds it (distance < 0).
        if (origin.z <= meshTopTexels && truth->isInside(origin))
            return DetailHit{0.0, glm::dvec3(0.0, 0.0, 1.0)};
        const std::optional<MeshDistance::RayHit> hit =
            truth->firstHit(origin, direction, maxTravelTexels);
        if (!hit) return std::nullopt;
        return DetailHit{hit->distance, hit->normal};
    };
}

/// The source level set of a tile baked from a .vdb file, placed as recorded, as the material's
/// analytic distance: what the bake resampled (VdbDistance: the file's values, or beyond its band
/// the exact distance to its refined surface), evaluated exactly at any point, periodic in x and
/// y as the tile is sampled.
void attachVdbTruth(Material& material, const std::string& where) {
    const Tile& tile = *material.tile;
    const std::filesystem::path file = recordedSourceFile(tile, where);
    const VdbProvenance recorded = vdbFromProvenance(tile.provenance, where);
    const VdbVolume volume = VdbVolume::read(file, recorded.gridName, recorded.iso);
    const Size3 size = tile.size();
    auto distance = std::make_shared<const VdbDistance>(volume, recorded.placement, size,
                                                        float(std::min(size.depth, 1024)));
    material.analyticDistance = [distance, size](const glm::dvec3& texelPosition) {
        const glm::dvec3 wrapped(
            texelPosition.x - size.width * std::floor(texelPosition.x / size.width),
            texelPosition.y - size.height * std::floor(texelPosition.y / size.height),
            texelPosition.z);
        return distance->distanceTexels(wrapped);
    };
}

}  // namespace

void attachTruth(SceneFile& sceneFile) {
    Scene& scene = sceneFile.scene;
    for (std::size_t index = 0; index < scene.objects.size(); ++index) {
        Material& material = scene.objects[index].material;
        if (!material.tile || material.analyticDistance) continue;
        if (index < sceneFile.placedDetailMeshes.size() && sceneFile.placedDetailMeshes[index]) {
            attachMeshTruth(material, *sceneFile.placedDetailMeshes[index]);
            continue;
        }
        const TileProvenance& provenance = material.tile->provenance;
        const std::string where = "objects[" + std::to_string(index) + "].material.tile";
        if (provenance.source == "mesh" && !provenance.sourceFile.empty()) {
            try {
                attachMeshTruth(material, sourceMeshPlaced(*material.tile, where));
            } catch (const InputError& error) {
                throw InputError(
                    std::string(error.what()) +
                    "; or bake it in the scene with {\"bake\": \"mesh\", \"file\": ...}");
            }
            continue;
        }
        if (provenance.source == "vdb" && !provenance.sourceFile.empty()) {
            attachVdbTruth(material, where);
            continue;
        }
        if (provenance.source != proceduralSourceName(ProceduralKind::Chainmail) &&
            provenance.source != proceduralSourceName(ProceduralKind::Grating)) {
            continue;
        }
        const ProceduralOptions pattern = proceduralFromProvenance(provenance, where);
        try {
            material.analyticDistance =
                proceduralDistance(pattern, material.tile->size()).signedDistanceTexels;
        } catch (const InputError& error) {  // the tile's metadata, not the scene, is wrong
            throw FormatError(where + ": distile:params do not describe a valid pattern (" +
                              error.what() + ")");
        }
    }
}

}  // namespace distile
