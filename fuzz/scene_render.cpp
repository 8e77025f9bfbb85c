// Fuzz target: scenes rendered. A scene file is loaded as fuzz/scene_json.cpp loads it (the tiles
// kept across inputs, so a recipe bakes once per process), then rendered at most 16x12 pixels, 2
// samples per pixel, with its AOVs, on one thread; every pixel of the image and of the AOVs must
// be finite. Refusals (InputError, FormatError) are expected outcomes; a non-finite pixel traps.
//
// The work per input is bounded before loading (a render is ~35 ms under the sanitizers, a new
// bake a few hundred; the slowest campaign input, three folding tori with three new bakes, 6 s):
// inputs that ask for more are skipped, not loaded. Only what a fuzz input can carry is rendered:
// built-in meshes, procedural recipes (chainmail, grating) and colours as numbers; files (mesh,
// tile, texture, recipe files) are the readers' targets. At most kMaxObjects objects, kMaxLights
// lights, and recipes of at most kMaxRecipeTexels texels (each given with its "size": the default
// 256x256x16 bakes for seconds). An input within these bounds that takes longer than libFuzzer's
// -timeout is a finding.
//
// A structure-aware mutator (LLVMFuzzerCustomMutator) keeps most inputs JSON, so that most reach
// the renderer; the dictionary scene_render.dict helps the byte-level mutations it falls back on.
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <nlohmann/json.hpp>
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

/// Whether a scene, as JSON, stays within the bounds above; text that is not JSON, or not a
/// scene, is left to the loader to refuse.
bool withinBounds(const std::uint8_t* data, std::size_t size) {
    const json scene = json::parse(data, data + size, nullptr, false);
    if (scene.is_discarded() || !scene.is_object()) return true;
    if (scene.contains("lights") && scene["lights"].is_array() &&
        scene["lights"].size() > kMaxLights)
        return false;
    if (!scene.contains("objects") || !scene["objects"].is_array()) return true;
    const json& objects = scene["objects"];
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

}  // namespace

/// libFuzzer's own byte-level mutations, for the inputs that are not JSON and one in four others.
extern "C" std::size_t LLVMFuzzerMutate(std::uint8_t* data, std::size_t size, std::size_t maxSize);

/// Structure-aware mutation: most byte-level mutations of a scene break its JSON, so the renderer
/// would see few inputs. Here a number of a scene that parses is replaced (by an edge value,
/// scaled by a power of ten, negated, nudged by a few ulps or by one), or an array element
/// (an object, a light) is duplicated or removed; the scene is written back as JSON.
extern "C" std::size_t LLVMFuzzerCustomMutator(std::uint8_t* data, std::size_t size,
                                               std::size_t maxSize, unsigned int seed) {
    std::minstd_rand random(seed);
    json scene = json::parse(data, data + size, nullptr, false);
    if (scene.is_discarded() || random() % 4 == 0) return LLVMFuzzerMutate(data, size, maxSize);
    std::vector<json*> numbers;
    collectNumbers(scene, numbers);
    const unsigned choice = random() % 8;
    if (choice == 7 && scene.is_object() && scene.contains("objects") &&
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
    if (!withinBounds(data, size)) return 0;
    // One thread: the image does not depend on the thread count, and a campaign's workers
    // already use every core.
    static tbb::global_control oneThread(tbb::global_control::max_allowed_parallelism, 1);
    return distile::fuzz::readAsFile(
        data, size, "scene.json", [](const std::filesystem::path& file) {
            static distile::TileCache tiles;
            if (tiles.size() > 32) tiles.clear();  // bounded memory over a long campaign
            const distile::SceneFile scene = distile::loadSceneFile(file, tiles);
            distile::RenderOptions options;
            options.width = std::min(scene.image.width, kMaxWidth);
            options.height = std::min(scene.image.height, kMaxHeight);
            options.samplesPerPixel = std::min(scene.image.samplesPerPixel, kMaxSamplesPerPixel);
            options.outputAovs = true;
            const distile::RenderResult result = distile::renderScene(scene.scene, options);
            const auto requireFinite = [](const distile::Image& image) {
                for (const glm::vec3& pixel : image.rgbLinear) {
                    if (!(std::isfinite(pixel.x) && std::isfinite(pixel.y) &&
                          std::isfinite(pixel.z)))
                        __builtin_trap();
                }
            };
            requireFinite(result.image);
            const distile::RenderAovs& aovs = *result.aovs;
            for (const distile::Image* image :
                 {&aovs.depth, &aovs.normal, &aovs.iterations, &aovs.shadowSamples,
                  &aovs.shadowMapSamples, &aovs.curvature, &aovs.texelScale})
                requireFinite(*image);
        });
}
