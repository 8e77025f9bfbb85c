#include "common/detail/png_file.h"

#include <png.h>

#include <cerrno>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string_view>
#include <vector>

namespace distile::image_files::detail {

namespace {

/// Where libpng's error handler jumps back to, and its message (libpng reports errors by longjmp).
struct PngErrors {
    std::jmp_buf jump;
    char message[256] = "";
};

[[noreturn]] void onPngError(png_structp png, png_const_charp message) {
    auto* errors = static_cast<PngErrors*>(png_get_error_ptr(png));
    std::snprintf(errors->message, sizeof errors->message, "%s",
                  message && *message ? message : "unknown libpng error");
    std::longjmp(errors->jump, 1);
}

void onPngWarning(png_structp, png_const_charp) {}  // a writer's warnings change nothing written

/// A float in [0, 1] as a code of `maxCode` (clamped, rounded to nearest; NaN is 0).
unsigned codeOf(float value, unsigned maxCode) {
    if (!(value > 0.0f)) return 0;
    if (value >= 1.0f) return maxCode;
    return unsigned(value * float(maxCode) + 0.5f);
}

/// The pixels as the file stores them: 8-bit codes, or 16-bit codes most significant byte first.
std::vector<unsigned char> storedBytes(const Spec& spec, PixelType given, const void* pixels) {
    const std::size_t values =
        std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(spec.channels);
    if (spec.pixelType == PixelType::UInt8) {
        if (given == PixelType::UInt8) {
            const auto* codes = static_cast<const unsigned char*>(pixels);
            return std::vector<unsigned char>(codes, codes + values);
        }
        std::vector<unsigned char> bytes(values);
        const auto* floats = static_cast<const float*>(pixels);
        for (std::size_t i = 0; i < values; ++i) bytes[i] = (unsigned char)codeOf(floats[i], 255);
        return bytes;
    }
    std::vector<unsigned char> bytes(2 * values);
    for (std::size_t i = 0; i < values; ++i) {
        const unsigned code = given == PixelType::UInt16
                                  ? static_cast<const std::uint16_t*>(pixels)[i]
                                  : codeOf(static_cast<const float*>(pixels)[i], 65535);
        bytes[2 * i] = (unsigned char)(code >> 8);
        bytes[2 * i + 1] = (unsigned char)(code & 0xff);
    }
    return bytes;
}

/// What libpng is to write, all of it prepared before its calls begin.
struct PngPlan {
    std::vector<unsigned char> bytes;
    std::vector<png_bytep> rows;
    png_uint_32 width = 0, height = 0;
    int bitDepth = 8, colorType = PNG_COLOR_TYPE_RGB;
    int compressionLevel = 6, filters = PNG_ALL_FILTERS;
    bool srgb = false, linear = false;
    std::vector<png_text> texts;
};

/// libpng's calls writing `plan` to `out`. An error jumps back here and leaves its message in
/// `errors`; this frame holds nothing to destroy.
void writeGuarded(png_structp png, png_infop info, std::FILE* out, const PngPlan& plan,
                  PngErrors& errors) {
    if (setjmp(errors.jump) != 0) return;
    png_init_io(png, out);
    png_set_IHDR(png, info, plan.width, plan.height, plan.bitDepth, plan.colorType,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    if (plan.srgb) {
        png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_ABSOLUTE);
    } else if (plan.linear) {
        png_set_gAMA(png, info, 1.0);
    }
    if (!plan.texts.empty())
        png_set_text(png, info, plan.texts.data(), int(plan.texts.size()));
    png_set_compression_level(png, plan.compressionLevel);
    png_set_filter(png, PNG_FILTER_TYPE_BASE, plan.filters);
    png_write_info(png, info);
    png_write_image(png, const_cast<png_bytepp>(plan.rows.data()));
    png_write_end(png, nullptr);
}

/// The integer attribute `name` of `spec`, or `fallback`.
int integerAttribute(const Spec& spec, std::string_view name, int fallback) {
    const Attribute* attribute = spec.find(name);
    const int* value = attribute ? std::get_if<int>(&attribute->value) : nullptr;
    return value ? *value : fallback;
}

}  // namespace

std::string writePng(const std::filesystem::path& file, const Spec& spec, PixelType given,
                     const void* pixels) {
    if (spec.channels < 1 || spec.channels > 4)
        return "a PNG holds 1 to 4 channels, not " + std::to_string(spec.channels);
    if (spec.pixelType != PixelType::UInt8 && spec.pixelType != PixelType::UInt16)
        return "a PNG stores 8- or 16-bit codes, not half or float values";
    if (given != spec.pixelType && given != PixelType::Float)
        return "pixels given as 8-bit codes are stored as 8-bit codes, 16-bit as 16-bit";
    if (spec.width < 1 || spec.height < 1)
        return "an image of " + std::to_string(spec.width) + "x" + std::to_string(spec.height) +
               " pixels has none";

    PngPlan plan;
    plan.bytes = storedBytes(spec, given, pixels);
    plan.width = png_uint_32(spec.width);
    plan.height = png_uint_32(spec.height);
    plan.bitDepth = spec.pixelType == PixelType::UInt8 ? 8 : 16;
    const std::size_t rowBytes =
        std::size_t(spec.width) * std::size_t(spec.channels) * std::size_t(plan.bitDepth / 8);
    plan.rows.resize(std::size_t(spec.height));
    for (std::size_t y = 0; y < plan.rows.size(); ++y)
        plan.rows[y] = const_cast<png_bytep>(plan.bytes.data() + y * rowBytes);
    constexpr int kColorTypes[4] = {PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA,
                                    PNG_COLOR_TYPE_RGB, PNG_COLOR_TYPE_RGB_ALPHA};
    plan.colorType = kColorTypes[spec.channels - 1];
    plan.compressionLevel = integerAttribute(spec, "png:compressionLevel", 6);
    plan.filters = integerAttribute(spec, "png:filter", PNG_ALL_FILTERS);
    for (const Attribute& attribute : spec.attributes) {
        if (const auto* text = std::get_if<std::string>(&attribute.value)) {
            png_text chunk{};
            chunk.compression = PNG_TEXT_COMPRESSION_NONE;
            chunk.key = const_cast<png_charp>(attribute.name.c_str());
            chunk.text = const_cast<png_charp>(text->c_str());
            chunk.text_length = text->size();
            plan.texts.push_back(chunk);
        }
    }
    const std::string colorSpace = spec.text("oiio:ColorSpace");
    plan.srgb = colorSpace == "sRGB";
    plan.linear = colorSpace == "Linear";

    std::FILE* out = std::fopen(file.c_str(), "wb");
    if (!out) return std::string("cannot create it (") + std::strerror(errno) + ")";
    PngErrors errors;
    png_structp png =
        png_create_write_struct(PNG_LIBPNG_VER_STRING, &errors, onPngError, onPngWarning);
    png_infop info = png ? png_create_info_struct(png) : nullptr;
    if (!info) {
        std::snprintf(errors.message, sizeof errors.message, "out of memory");
    } else {
        writeGuarded(png, info, out, plan, errors);
    }
    png_destroy_write_struct(png ? &png : nullptr, info ? &info : nullptr);
    const bool closed = std::fclose(out) == 0;
    if (errors.message[0]) return std::string("writing failed (libpng: ") + errors.message + ")";
    if (!closed) return std::string("writing failed (") + std::strerror(errno) + ")";
    return {};
}

}  // namespace distile::image_files::detail
