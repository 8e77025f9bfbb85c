// Fuzz target: scenes rendered. A scene file is loaded as fuzz/scene_json.cpp loads it (the tiles
// kept across inputs, so a recipe bakes once per process), then rendered at most 16x12 pixels, 2
// samples per pixel, on one thread; every pixel of the image and of the AOVs must be finite.
// Refusals (InputError, FormatError) are expected outcomes; a non-finite pixel traps.
//
// The render options come from the input too: an optional "render_options" object beside the
// scene's keys, removed before the scene is loaded, holds what `distile render` takes on its
// command line, under its flags' names ("width", "height", "spp", "iterations", "epsilon",
// "march", "relaxation", "filter", "normal_filter", "shell", "shadows", "no_skip": [names],
// "aovs", "reference": "analytic"), and the RenderOptions members the command line does not set
// ("self_shadows", "shadow_iterations", "shadow_map_resolution", "relief_linear_share"). They are
// applied as the command applies its flags, and the library checks them (renderScene) as it
// checks the command's; a value the command line would not read (an unknown name, a number that
// is not an integer) is refused here. Without "render_options" the options are the command's
// defaults, with AOVs.
//
// The work per input is bounded before loading (a render is ~35 ms under the sanitizers, a new
// bake a few hundred; the slowest campaign input, three folding tori with three new bakes, 6 s):
// inputs that ask for more are skipped, not loaded. Only what a fuzz input can carry is rendered:
// built-in meshes, procedural recipes (chainmail, grating) and colours as numbers; files (mesh,
// tile, texture, recipe files) are the readers' targets. At most kMaxObjects objects, kMaxLights
// lights, and recipes of at most kMaxRecipeTexels texels (each given with its "size": the default
// 256x256x16 bakes for seconds). A scene's image larger than kMaxWidth x kMaxHeight x
// kMaxSamplesPerPixel is rendered at that size; render options asking for more are skipped, as
// are shadow maps of more than kMaxShadowMapResolution texels a side and world references
// (`--reference world` meshed the detail of an 8x6 render of one chain-mail plane for 4 s;
// world-levelset builds a level set for minutes). An input within these bounds that takes longer
// than libFuzzer's -timeout is a finding.
//
// A structure-aware mutator (LLVMFuzzerCustomMutator) keeps most inputs JSON, so that most reach
// the renderer, and sets render options to the values the library names and to the edges of
// their ranges; the dictionary scene_render.dict helps the byte-level mutations it falls back on.
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "common/size3.h"
#include "fuzz/fuzz_reader.h"
#include "render/renderer.h"
#include "scene/scene_file.h"

namespace {

using json = nlohmann::json;

constexpr std::size_t kMaxObjects = 4;
constexpr std::size_t kMaxLights = 6;
constexpr double kMaxRecipeTexels = 64.0 * 64.0 * 16.0;
constexpr int kMaxWidth = 16;
constexpr int kMaxHeight = 12;
constexpr int kMaxSamplesPerPixel = 2;
constexpr double kMaxShadowMapResolution = 512.0;

/// The key of the input's render options.
constexpr const char* kRenderOptionsKey = "render_options";

/// The texels of a recipe's "size" ("WxHxD" or [W, H, D]); 0 when it is not one (the loader
/// refuses it), infinity when it is absent (the default size is too large here).
double recipeTexels(const json& recipe) {
    if (!recipe.contains("size")) return INFINITY;
    const json& size = recipe["size"];
    if (size.is_string()) {
        try {
            const distile::Size3 parsed = distile::parseSize3(size.get<std::string>(), "size");
            return double(parsed.width) * double(parsed.height) * double(parsed.depth);
        } catch (const distile::InputError&) {
            return 0.0;
        }
    }
    if (!size.is_array() || size.size() != 3) return 0.0;
    double texels = 1.0;
    for (const json& extent : size) {
        if (!extent.is_number()) return 0.0;
        texels *= std::fabs(extent.get<double>());
    }
    return std::isnan(texels) ? INFINITY : texels;
}

/// Whether render options, as JSON, stay within the bounds above; the rest is left to the
/// options' checks.
bool renderOptionsWithinBounds(const json& options) {
    if (!options.is_object()) return true;
    const std::pair<const char*, int> largest[] = {
        {"width", kMaxWidth}, {"height", kMaxHeight}, {"spp", kMaxSamplesPerPixel}};
    for (const auto& [key, bound] : largest) {
        if (options.contains(key) && options[key].is_number() &&
            options[key].get<double>() > double(bound))
            return false;
    }
    if (options.contains("reference") &&
        (options["reference"] == "world" || options["reference"] == "world-levelset"))
        return false;
    if (options.contains("shadow_map_resolution") && options["shadow_map_resolution"].is_number() &&
        options["shadow_map_resolution"].get<double>() > kMaxShadowMapResolution)
        return false;
    return true;
}

/// Whether an input, as JSON, stays within the bounds above; text that is not JSON, or not a
/// scene, is left to the loader to refuse.
bool withinBounds(const json& input) {
    if (input.is_discarded() || !input.is_object()) return true;
    if (input.contains(kRenderOptionsKey) && !renderOptionsWithinBounds(input[kRenderOptionsKey]))
        return false;
    if (input.contains("lights") && input["lights"].is_array() &&
        input["lights"].size() > kMaxLights)
        return false;
    if (!input.contains("objects") || !input["objects"].is_array()) return true;
    const json& objects = input["objects"];
    if (objects.size() > kMaxObjects) return false;
    for (const json& object : objects) {
        if (!object.is_object()) continue;
        if (object.contains("mesh") && object["mesh"].is_string()) {
            const std::string mesh = object["mesh"].get<std::string>();
            if (mesh != "plane" && mesh != "sphere" && mesh != "torus") return false;  // a file
        }
        if (!object.contains("material") || !object["material"].is_object()) continue;
        const json& material = object["material"];
        if (material.contains("color") && material["color"].is_string()) return false;
        if (!material.contains("tile")) continue;
        const json& tile = material["tile"];
        if (tile.is_string()) return false;  // a tile file
        if (!tile.is_object() || !tile.contains("bake")) continue;
        if (tile["bake"] != "chainmail" && tile["bake"] != "grating") return false;  // a file
        if (recipeTexels(tile) > kMaxRecipeTexels) return false;
    }
    return true;
}

/// The names of `values` (named by `nameOf`) and one the library does not know.
template <class Value, std::size_t N>
json namesOf(const Value (&values)[N], const char* (*nameOf)(Value)) {
    json names = json::array();
    for (const Value value : values) names.push_back(nameOf(value));
    names.push_back("unknown");
    return names;
}

/// The render options an input may give, each with the values the mutator sets it to: every name
/// the library accepts (and one it does not), numbers in, at the edges of and beyond the accepted
/// ranges.
const json& renderOptionValues() {
    static const json values = [] {
        json table;
        table["width"] = {-1, 0, 1, 3, 16};
        table["height"] = {-1, 0, 1, 2, 12};
        table["spp"] = {-1, 0, 1, 2};
        table["iterations"] = {0, 1, 2, 7, 64, 512, 4096, 4097};
        table["shadow_iterations"] = table["iterations"];
        table["epsilon"] = {0.0, 1e-6, 1e-5, 1e-3, 0.02, 0.3, 1.0, 1.0000001};
        table["relaxation"] = {0.9999999, 1.0, 1.2, 1.6, 1.9999999, 2.0};
        table["relief_linear_share"] = {0.0, 1e-3, 0.1, 0.75, 1.0, 1.0000001};
        table["shadow_map_resolution"] = {0, 1, 15, 16, 64, 256, 512};
        table["march"] = namesOf(distile::kMarchMethods, distile::marchMethodName);
        table["filter"] = namesOf(distile::kFilterKinds, distile::filterKindName);
        table["normal_filter"] = table["filter"];
        table["shell"] = namesOf(distile::kShellMappings, distile::shellMappingName);
        table["shadows"] = namesOf(distile::kShadowFilters, distile::shadowFilterName);
        table["reference"] = {"analytic", "unknown"};
        table["aovs"] = {true, false};
        table["self_shadows"] = {true, false};
        table["no_skip"] = json::array();
        for (const distile::RenderSkipSwitch& skip : distile::kRenderSkipSwitches)
            table["no_skip"].push_back(skip.name);
        return table;
    }();
    return values;
}

/// An InputError naming the render option `key`, as the command line refuses a flag's value.
distile::InputError refusedOption(const std::string& key, const std::string& problem) {
    return distile::InputError::inField(std::string(kRenderOptionsKey) + "." + key, problem);
}

/// `options[key]` as an int, when present: an integer in int's range, as the command line reads
/// an integer flag.
std::optional<int> integerOption(const json& options, const char* key) {
    if (!options.contains(key)) return std::nullopt;
    const json& value = options[key];
    if (value.is_number_unsigned() &&
        value.get<std::uint64_t>() <= std::uint64_t(std::numeric_limits<int>::max()))
        return int(value.get<std::uint64_t>());
    if (value.is_number_integer() && !value.is_number_unsigned() &&
        value.get<std::int64_t>() >= std::numeric_limits<int>::min() &&
        value.get<std::int64_t>() <= std::numeric_limits<int>::max())
        return int(value.get<std::int64_t>());
    throw refusedOption(key, "not an integer in int's range");
}

/// `options[key]` as a float, when present (infinite beyond float's range: the options' checks
/// refuse it).
std::optional<float> floatOption(const json& options, const char* key) {
    if (!options.contains(key)) return std::nullopt;
    const json& value = options[key];
    if (!value.is_number()) throw refusedOption(key, "not a number");
    const double number = value.get<double>();
    if (std::fabs(number) > double(std::numeric_limits<float>::max()))
        return number > 0 ? INFINITY : -INFINITY;
    return float(number);
}

std::optional<bool> boolOption(const json& options, const char* key) {
    if (!options.contains(key)) return std::nullopt;
    if (!options[key].is_boolean()) throw refusedOption(key, "not true or false");
    return options[key].get<bool>();
}

/// `options[key]` as the library's value of that name among `values` (named by `nameOf`), when
/// present.
template <class Value, std::size_t N>
std::optional<Value> namedOption(const json& options, const char* key, const Value (&values)[N],
                                 const char* (*nameOf)(Value)) {
    if (!options.contains(key)) return std::nullopt;
    for (const Value value : values) {
        if (options[key] == nameOf(value)) return value;
    }
    throw refusedOption(key, "not a name the command line accepts");
}

/// The render `given` (the input's "render_options", null when it has none, within
/// renderOptionsWithinBounds) asks for, of a scene whose image settings are `image`.
distile::RenderOptions requestedRender(const json& given, const distile::ImageSettings& image) {
    const json& options = given.is_null() ? json::object() : given;
    if (!options.is_object()) throw refusedOption("", "not an object");
    for (const auto& [key, value] : options.items()) {
        if (!renderOptionValues().contains(key)) throw refusedOption(key, "not an option");
    }
    distile::RenderOptions rendered;
    rendered.outputAovs = boolOption(options, "aovs").value_or(true);
    // The scene's image shrunk to the bounds; the options' (within them) as given.
    rendered.width = integerOption(options, "width").value_or(std::min(image.width, kMaxWidth));
    rendered.height = integerOption(options, "height").value_or(std::min(image.height, kMaxHeight));
    rendered.samplesPerPixel = integerOption(options, "spp")
                                   .value_or(std::min(image.samplesPerPixel, kMaxSamplesPerPixel));
    distile::MarchSettings& march = rendered.march;
    march.maxIterations = integerOption(options, "iterations").value_or(march.maxIterations);
    march.epsilonTexels = floatOption(options, "epsilon").value_or(march.epsilonTexels);
    march.method = namedOption(options, "march", distile::kMarchMethods, distile::marchMethodName)
                       .value_or(march.method);
    march.relaxation = floatOption(options, "relaxation").value_or(march.relaxation);
    march.reliefLinearShare =
        floatOption(options, "relief_linear_share").value_or(march.reliefLinearShare);
    rendered.filter = namedOption(options, "filter", distile::kFilterKinds, distile::filterKindName)
                          .value_or(rendered.filter);
    rendered.normalFilter =
        namedOption(options, "normal_filter", distile::kFilterKinds, distile::filterKindName)
            .value_or(rendered.normalFilter);
    rendered.shellMapping =
        namedOption(options, "shell", distile::kShellMappings, distile::shellMappingName)
            .value_or(rendered.shellMapping);
    rendered.shadowFilter =
        namedOption(options, "shadows", distile::kShadowFilters, distile::shadowFilterName)
            .value_or(rendered.shadowFilter);
    if (options.contains("no_skip")) {
        if (!options["no_skip"].is_array()) throw refusedOption("no_skip", "not an array");
        for (const json& name : options["no_skip"]) {
            const auto skip = std::find_if(
                std::begin(distile::kRenderSkipSwitches), std::end(distile::kRenderSkipSwitches),
                [&](const distile::RenderSkipSwitch& known) { return name == known.name; });
            if (skip == std::end(distile::kRenderSkipSwitches))
                throw refusedOption("no_skip", "not a name the command line accepts");
            rendered.skips.*skip->enabled = false;
        }
    }
    // As the command line: self-shadows with shadows, none without.
    rendered.selfShadows = boolOption(options, "self_shadows")
                               .value_or(rendered.shadowFilter != distile::ShadowFilter::None);
    rendered.shadowIterations =
        integerOption(options, "shadow_iterations").value_or(rendered.shadowIterations);
    rendered.shadowMapResolution =
        integerOption(options, "shadow_map_resolution").value_or(rendered.shadowMapResolution);
    if (options.contains("reference")) {
        if (options["reference"] != "analytic") throw refusedOption("reference", "not analytic");
        rendered.reference = true;
    }
    return rendered;
}

/// Traps unless every pixel of `image` is finite.
void requireFinite(const distile::Image& image) {
    for (const glm::vec3& pixel : image.rgbLinear) {
        if (!(std::isfinite(pixel.x) && std::isfinite(pixel.y) && std::isfinite(pixel.z)))
            __builtin_trap();
    }
}

/// Numbers at the edges of what the reader accepts and of single precision.
constexpr double kEdgeNumbers[] = {0.0,  -0.0, 1e-45,  1e-38, 1e-30, 1e-12, 1e-9, 1e-7, 1e-3,
                                   0.5,  1.0,  2.0,    60.0,  89.0,  179.0, 1e6,  1e9,  1e12,
                                   1e18, 1e30, -1e-30, -1e-9, -1.0,  -1e9,  -1e30};

/// Every number in `value`, depth first.
void collectNumbers(json& value, std::vector<json*>& numbers) {
    if (value.is_number()) numbers.push_back(&value);
    if (value.is_structured()) {
        for (json& child : value) collectNumbers(child, numbers);
    }
}

/// Sets, or removes, one render option of `input` (a JSON object); "no_skip" gains or loses one
/// name.
void mutateRenderOption(json& input, std::minstd_rand& random) {
    json& options = input[kRenderOptionsKey];
    if (!options.is_object()) options = json::object();
    const json& table = renderOptionValues();
    auto entry = table.begin();
    std::advance(entry, random() % table.size());
    const std::string& key = entry.key();
    if (random() % 4 == 0) {
        options.erase(key);
    } else if (key == "no_skip") {
        json& names = options[key];
        if (!names.is_array()) names = json::array();
        const json& name = entry.value()[random() % entry.value().size()];
        const auto found = std::find(names.begin(), names.end(), name);
        if (found == names.end()) {
            names.push_back(name);
        } else {
            names.erase(found);
        }
    } else {
        options[key] = entry.value()[random() % entry.value().size()];
    }
    if (options.empty()) input.erase(kRenderOptionsKey);
}

}  // namespace

/// libFuzzer's own byte-level mutations, for the inputs that are not JSON and one in four others.
extern "C" std::size_t LLVMFuzzerMutate(std::uint8_t* data, std::size_t size, std::size_t maxSize);

/// Structure-aware mutation: most byte-level mutations of a scene break its JSON, so the renderer
/// would see few inputs. Here a number of a scene that parses is replaced (by an edge value,
/// scaled by a power of ten, negated, nudged by a few ulps or by one), an array element
/// (an object, a light) is duplicated or removed, or a render option is set or removed; the
/// input is written back as JSON.
extern "C" std::size_t LLVMFuzzerCustomMutator(std::uint8_t* data, std::size_t size,
                                               std::size_t maxSize, unsigned int seed) {
    std::minstd_rand random(seed);
    json scene = json::parse(data, data + size, nullptr, false);
    if (scene.is_discarded() || random() % 4 == 0) return LLVMFuzzerMutate(data, size, maxSize);
    std::vector<json*> numbers;
    collectNumbers(scene, numbers);
    const unsigned choice = random() % 9;
    if (choice == 8 && scene.is_object()) {
        mutateRenderOption(scene, random);
    } else if (choice == 7 && scene.is_object() && scene.contains("objects") &&
               scene["objects"].is_array() && !scene["objects"].empty()) {
        const bool lights = random() % 2 == 0 && scene.contains("lights") &&
                            scene["lights"].is_array() && !scene["lights"].empty();
        json& elements = scene[lights ? "lights" : "objects"];
        const std::size_t index = random() % elements.size();
        if (random() % 2 == 0) {
            elements.push_back(elements[index]);
        } else {
            elements.erase(index);
        }
    } else if (!numbers.empty()) {
        json& number = *numbers[random() % numbers.size()];
        double value = number.get<double>();
        switch (choice) {
            case 0:
            case 1:
                value = kEdgeNumbers[random() % std::size(kEdgeNumbers)];
                break;
            case 2:
                value *= std::pow(10.0, double(int(random() % 25) - 12));
                break;
            case 3:
                value = -value;
                break;
            case 4: {
                const float toward = random() % 2 ? INFINITY : -INFINITY;
                for (unsigned ulps = 1 + random() % 4; ulps > 0; --ulps)
                    value = double(std::nextafter(float(value), toward));
                break;
            }
            case 5:
                value += random() % 2 ? 1.0 : -1.0;
                break;
            default:
                value = double(random() % 2001) / 1000.0 - 1.0;
        }
        if (number.is_number_integer() && std::isfinite(value) && std::fabs(value) < 1e15) {
            number = std::int64_t(std::llround(value));
        } else {
            number = value;
        }
    } else {
        return LLVMFuzzerMutate(data, size, maxSize);
    }
    const std::string text = scene.dump();
    if (text.size() > maxSize) return LLVMFuzzerMutate(data, size, maxSize);
    std::copy(text.begin(), text.end(), data);
    return text.size();
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    json input = json::parse(data, data + size, nullptr, false);
    if (!withinBounds(input)) return 0;
    // The scene file is the input without its render options (the input itself without them, so
    // that the loader reads the bytes as given).
    json renderOptions;
    std::string sceneText(reinterpret_cast<const char*>(data), size);
    if (input.is_object() && input.contains(kRenderOptionsKey)) {
        renderOptions = std::move(input[kRenderOptionsKey]);
        input.erase(kRenderOptionsKey);
        sceneText = input.dump();
    }
    // One thread: the image does not depend on the thread count, and a campaign's workers
    // already use every core.
    static tbb::global_control oneThread(tbb::global_control::max_allowed_parallelism, 1);
    return distile::fuzz::readAsFile(
        reinterpret_cast<const std::uint8_t*>(sceneText.data()), sceneText.size(), "scene.json",
        [&](const std::filesystem::path& file) {
            static distile::TileCache tiles;
            if (tiles.size() > 32) tiles.clear();  // bounded memory over a long campaign
            distile::SceneFile scene = distile::loadSceneFile(file, tiles);
            const distile::RenderOptions options = requestedRender(renderOptions, scene.image);
            if (options.reference) distile::attachTruth(scene);  // as `distile render` does
            const distile::RenderResult result = distile::renderScene(scene.scene, options);
            requireFinite(result.image);
            if (!result.aovs) return;
            const distile::RenderAovs& aovs = *result.aovs;
            for (const distile::Image* image :
                 {&aovs.depth, &aovs.normal, &aovs.iterations, &aovs.shadowSamples,
                  &aovs.shadowMapSamples, &aovs.curvature, &aovs.texelScale})
                requireFinite(*image);
        });
}
