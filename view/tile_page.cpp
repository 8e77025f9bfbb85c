#include "view/tile_page.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "common/atomic_file.h"
#include "common/error.h"
#include "sampler/occupancy.h"
#include "sampler/tile_io.h"

namespace distile {

namespace fs = std::filesystem;

namespace {

/// The march's hit threshold in shaders/distile_march.glsl (the renderer's default).
constexpr float kShaderEpsilonTexels = 0.02f;

std::string base64(const std::uint8_t* bytes, std::size_t count) {
    static constexpr char kDigits[] =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string text;
    text.reserve((count + 2) / 3 * 4);
    for (std::size_t i = 0; i < count; i += 3) {
        const std::uint32_t group = std::uint32_t(bytes[i]) << 16 |
                                    (i + 1 < count ? std::uint32_t(bytes[i + 1]) << 8 : 0u) |
                                    (i + 2 < count ? std::uint32_t(bytes[i + 2]) : 0u);
        text += kDigits[group >> 18 & 63];
        text += kDigits[group >> 12 & 63];
        text += i + 1 < count ? kDigits[group >> 6 & 63] : '=';
        text += i + 2 < count ? kDigits[group & 63] : '=';
    }
    return text;
}

std::string htmlEscaped(const std::string& text) {
    std::string escaped;
    for (char c : text) {
        switch (c) {
            case '<':
                escaped += "&lt;";
                break;
            case '>':
                escaped += "&gt;";
                break;
            case '&':
                escaped += "&amp;";
                break;
            case '"':
                escaped += "&quot;";
                break;
            default:
                escaped += c;
        }
    }
    return escaped;
}

/// JSON that may stand inside a <script> element: "</" cannot end it early.
std::string scriptJson(const nlohmann::json& value) {
    std::string text = value.dump();
    for (std::size_t at = text.find("</"); at != std::string::npos; at = text.find("</", at + 3))
        text.replace(at, 2, "<\\/");
    return text;
}

void replaceMarker(std::string& page, const std::string& marker, const std::string& text) {
    for (std::size_t at = page.find(marker); at != std::string::npos;
         at = page.find(marker, at + text.size())) {
        page.replace(at, marker.size(), text);
    }
}

void requireFinite(const std::string& field, std::initializer_list<float> values) {
    for (float value : values) {
        if (!std::isfinite(value))
            throw InputError::inField(field, "a component is not finite; it must be a number");
    }
}

/// Throws InputError::inField unless `value` is in (0, `most`] (`most` and `why` say the bound).
void requirePositive(const std::string& field, float value, float most = HUGE_VALF,
                     const char* why = "") {
    if (!(std::isfinite(value) && value > 0.0f)) {
        throw InputError::inField(
            field, numberText(value) + " is not accepted; it must be finite and > 0");
    }
    if (value > most)
        throw InputError::inField(field, numberText(value) + " is not accepted; at most " +
                                             numberText(most) + " (" + why + ")");
}

/// The most tile repeats across an object: the page's shader computes uv x repeats in float,
/// whose 24 bits keep 8 for the place within a tile at 2^16 repeats.
constexpr float kMaxUvRepeats = 65536.0f;

void validateView(const TilePageView& view) {
    if (view.object != "plane" && view.object != "sphere") {
        throw InputError::inField("object",
                                  "'" + view.object + "' is not accepted; use plane or sphere");
    }
    requireFinite("eye", {view.eye.x, view.eye.y, view.eye.z});
    requireFinite("target", {view.target.x, view.target.y, view.target.z});
    requireFinite("up", {view.up.x, view.up.y, view.up.z});
    requireFinite("lightDirection",
                  {view.lightDirection.x, view.lightDirection.y, view.lightDirection.z});
    requireFinite("color", {view.color.r, view.color.g, view.color.b});
    if (!(view.fovDeg > 0.0f && view.fovDeg < 180.0f)) {
        throw InputError::inField(
            "fovDeg", numberText(view.fovDeg) + " is not accepted; it must be in (0, 180)");
    }
    requirePositive("planeSizeWorld", view.planeSizeWorld);
    const char* repeatsWhy = "the page's shader resolves a tile's texels up to 2^16 repeats";
    requirePositive("uvScale.x", view.uvScale.x, kMaxUvRepeats, repeatsWhy);
    requirePositive("uvScale.y", view.uvScale.y, kMaxUvRepeats, repeatsWhy);
    requirePositive("depthWorld", view.depthWorld, view.planeSizeWorld,
                    "the plane's size: a shell deeper than the plane is wide");
    requirePositive("sphereUvScale.x", view.sphereUvScale.x, kMaxUvRepeats, repeatsWhy);
    requirePositive("sphereUvScale.y", view.sphereUvScale.y, kMaxUvRepeats, repeatsWhy);
    requirePositive("sphereDepthWorld", view.sphereDepthWorld, 1.0f,
                    "the sphere's radius: a deeper shell folds through its centre");
}

nlohmann::json vector3(const glm::vec3& v) {
    return {v.x, v.y, v.z};
}

}  // namespace

std::string tilePageHtml(const Tile& tile, const std::string& title, const TilePageView& view) {
    validateView(view);
    const std::span<const float> distances = tile.distancesTexels();
    for (std::size_t i = 0; i < distances.size(); ++i) {
        if (!(std::abs(distances[i]) <= 65504.0f)) {
            throw InputError("tile: distance " + std::to_string(distances[i]) + " at texel " +
                             std::to_string(i) +
                             " does not fit in a half float; the page takes |distance| <= 65504 "
                             "texels");
        }
    }
    std::vector<std::uint8_t> bytes(distances.size() * 2);
    for (std::size_t i = 0; i < distances.size(); ++i) {  // little endian, as Uint16Array reads it
        const std::uint16_t half = halfBitsAtMost(distances[i]);
        bytes[2 * i] = std::uint8_t(half & 0xff);
        bytes[2 * i + 1] = std::uint8_t(half >> 8);
    }
    const Size3& size = tile.size();
    // The march starts at the highest top of the detail, as the renderer's trilinear march does.
    const TileOccupancy occupancy(tile, kShaderEpsilonTexels);
    const float highestTop =
        occupancy.hasEmptySpace() ? occupancy.highestTopTexels() : float(size.depth);
    const nlohmann::json tileJson = {{"size", {size.width, size.height, size.depth}},
                                     {"highestTopTexels", highestTop},
                                     {"signedRangeTexels", signedPngRangeTexels(tile)},
                                     {"halfFloatsBase64", base64(bytes.data(), bytes.size())}};
    const nlohmann::json viewJson = {
        {"object", view.object},
        {"eye", vector3(view.eye)},
        {"target", vector3(view.target)},
        {"up", vector3(view.up)},
        {"fovDeg", view.fovDeg},
        {"planeSizeWorld", view.planeSizeWorld},
        {"uvScale", {view.uvScale.x, view.uvScale.y}},
        {"depthWorld", view.depthWorld},
        {"sphereUvScale", {view.sphereUvScale.x, view.sphereUvScale.y}},
        {"sphereDepthWorld", view.sphereDepthWorld},
        {"light", vector3(view.lightDirection)},
        {"albedo", vector3(view.color)},
        {"floor", view.solidFloor ? "solid" : "open"}};
    std::string page = tilePageTemplate();
    // Data first: the shader and the title hold no markers, the base64 none either.
    replaceMarker(page, "@MARCH_GLSL@", referenceShaderSource());
    replaceMarker(page, "@TILE_JSON@", scriptJson(tileJson));
    replaceMarker(page, "@VIEW_JSON@", scriptJson(viewJson));
    replaceMarker(page, "@SIZE@",
                  std::to_string(size.width) + "x" + std::to_string(size.height) + "x" +
                      std::to_string(size.depth));
    replaceMarker(page, "@TITLE@", htmlEscaped(title));
    return page;
}

void writeTilePage(const Tile& tile, const std::string& title, const TilePageView& view,
                   const fs::path& file) {
    const std::string page = tilePageHtml(tile, title, view);
    writeAtomically(file, [&](const fs::path& temporary) {
        std::ofstream out(temporary, std::ios::binary);
        out << page;
        out.close();
        if (!out) throw InputError(file.string() + ": cannot write the page (disk full?)");
    });
}

}  // namespace distile
