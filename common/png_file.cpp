#include "common/detail/png_file.h"

#include <png.h>
#include <tbb/parallel_for.h>
#include <zlib.h>

#include <algorithm>
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

/// The pixels as a PNG's rows hold them without a row filter: per row, the filter type byte (0,
/// none) then the row's codes, 8-bit or 16-bit most significant byte first.
std::vector<unsigned char> storedRows(const Spec& spec, PixelType given, const void* pixels) {
    const std::size_t rowValues = std::size_t(spec.width) * std::size_t(spec.channels);
    const std::size_t bytesPerValue = spec.pixelType == PixelType::UInt8 ? 1 : 2;
    const std::size_t rowBytes = 1 + rowValues * bytesPerValue;
    std::vector<unsigned char> rows(rowBytes * std::size_t(spec.height));
    for (std::size_t y = 0; y < std::size_t(spec.height); ++y) {
        unsigned char* row = rows.data() + y * rowBytes;
        *row++ = 0;
        const std::size_t first = y * rowValues;
        if (given == PixelType::UInt8) {  // stored as given (a render's image): the row as it is
            std::memcpy(row, static_cast<const unsigned char*>(pixels) + first, rowValues);
            continue;
        }
        for (std::size_t i = first; i < first + rowValues; ++i) {
            if (spec.pixelType == PixelType::UInt8) {
                *row++ = (unsigned char)codeOf(static_cast<const float*>(pixels)[i], 255);
                continue;
            }
            const unsigned code = given == PixelType::UInt16
                                      ? static_cast<const std::uint16_t*>(pixels)[i]
                                      : codeOf(static_cast<const float*>(pixels)[i], 65535);
            *row++ = (unsigned char)(code >> 8);
            *row++ = (unsigned char)(code & 0xff);
        }
    }
    return rows;
}

/// Rows per band of a deflate in parallel (deflateInBands).
constexpr std::size_t kBandRows = 32;

/// `data` (the rows of storedRows, `rowBytes` each with their filter byte) as one zlib stream,
/// deflated at `level` in bands of kBandRows rows in parallel: each band a raw deflate primed
/// with the 32 KB before it (the window one stream would have had) and ended by a sync flush,
/// the last by the end of the stream. The bands do not depend on the thread count, nor do the
/// bytes. Empty if zlib fails.
std::vector<unsigned char> deflateInBands(const std::vector<unsigned char>& data,
                                          std::size_t rowBytes, int level) {
    const std::size_t bandBytes = kBandRows * rowBytes;
    const std::size_t bands = (data.size() + bandBytes - 1) / bandBytes;
    std::vector<std::vector<unsigned char>> deflated(bands);
    std::vector<uLong> checksums(bands);
    tbb::parallel_for(std::size_t(0), bands, [&](std::size_t band) {
        const std::size_t begin = band * bandBytes;
        const std::size_t length = std::min(bandBytes, data.size() - begin);
        const bool last = band + 1 == bands;
        checksums[band] = adler32_z(adler32_z(0, nullptr, 0), data.data() + begin, length);
        z_stream stream{};
        if (deflateInit2(&stream, level, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY) != Z_OK) return;
        const std::size_t window = std::min<std::size_t>(begin, 32768);
        bool fine = window == 0 || deflateSetDictionary(&stream, data.data() + begin - window,
                                                        uInt(window)) == Z_OK;
        std::vector<unsigned char>& out = deflated[band];
        out.resize(deflateBound(&stream, uLong(length)) + 64);  // + the sync flush's block
        stream.next_in = const_cast<Bytef*>(data.data() + begin);
        stream.avail_in = uInt(length);
        stream.next_out = out.data();
        stream.avail_out = uInt(out.size());
        const int result = fine ? deflate(&stream, last ? Z_FINISH : Z_SYNC_FLUSH) : Z_STREAM_ERROR;
        fine = stream.avail_in == 0 && (last ? result == Z_STREAM_END : result == Z_OK);
        out.resize(fine ? stream.total_out : 0);
        if (!fine) out.shrink_to_fit();
        deflateEnd(&stream);
    });
    // zlib's header (deflate, 32 KB window, its level flags), the bands, the Adler-32 of all.
    const int levelFlags = level < 2 ? 0 : level < 6 ? 1 : level == 6 ? 2 : 3;
    unsigned header = (0x78u << 8) | unsigned(levelFlags << 6);
    header += 31 - header % 31;
    std::vector<unsigned char> stream = {(unsigned char)(header >> 8),
                                         (unsigned char)(header & 0xff)};
    uLong checksum = adler32_z(0, nullptr, 0);
    for (std::size_t band = 0; band < bands; ++band) {
        if (deflated[band].empty()) return {};
        stream.insert(stream.end(), deflated[band].begin(), deflated[band].end());
        const std::size_t length = std::min(bandBytes, data.size() - band * bandBytes);
        checksum = adler32_combine(checksum, checksums[band], z_off_t(length));
    }
    for (int shift = 24; shift >= 0; shift -= 8)
        stream.push_back((unsigned char)((checksum >> shift) & 0xff));
    return stream;
}

/// What libpng is to write, all of it prepared before its calls begin.
struct PngPlan {
    std::vector<unsigned char> storedRows;  ///< storedRows(): each row's filter byte and codes
    std::vector<png_bytep> rows;            ///< each row's codes in storedRows (past its filter byte)
    /// Without row filters: the image data (all IDAT chunks) deflated in parallel, else empty
    /// (libpng filters and deflates the rows).
    std::vector<unsigned char> imageData;
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
    if (plan.imageData.empty()) {
        png_write_image(png, const_cast<png_bytepp>(plan.rows.data()));
        png_write_end(png, nullptr);
        return;
    }
    static constexpr png_byte kIdat[5] = {'I', 'D', 'A', 'T', '\0'};
    static constexpr png_byte kIend[5] = {'I', 'E', 'N', 'D', '\0'};
    constexpr std::size_t kChunkBytes = std::size_t(1) << 20;
    for (std::size_t at = 0; at < plan.imageData.size(); at += kChunkBytes) {
        png_write_chunk(png, kIdat, plan.imageData.data() + at,
                        std::min(kChunkBytes, plan.imageData.size() - at));
    }
    png_write_chunk(png, kIend, nullptr, 0);
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
    plan.storedRows = storedRows(spec, given, pixels);
    plan.width = png_uint_32(spec.width);
    plan.height = png_uint_32(spec.height);
    plan.bitDepth = spec.pixelType == PixelType::UInt8 ? 8 : 16;
    const std::size_t rowBytes = plan.storedRows.size() / std::size_t(spec.height);
    plan.rows.resize(std::size_t(spec.height));
    for (std::size_t y = 0; y < plan.rows.size(); ++y)
        plan.rows[y] = const_cast<png_bytep>(plan.storedRows.data() + y * rowBytes + 1);
    constexpr int kColorTypes[4] = {PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA,
                                    PNG_COLOR_TYPE_RGB, PNG_COLOR_TYPE_RGB_ALPHA};
    plan.colorType = kColorTypes[spec.channels - 1];
    plan.compressionLevel = std::clamp(integerAttribute(spec, "png:compressionLevel", 6), 0, 9);
    plan.filters = integerAttribute(spec, "png:filter", PNG_ALL_FILTERS);
    // Rows without a filter do not depend on each other: deflated in parallel.
    if (plan.filters == PNG_FILTER_NONE || plan.filters == PNG_NO_FILTERS) {
        plan.imageData = deflateInBands(plan.storedRows, rowBytes, plan.compressionLevel);
        if (plan.imageData.empty()) return "writing failed (zlib could not deflate the pixels)";
    }
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
