#include "render/image.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/exr_header.h"
#include "common/image_files.h"
#include "common/input_file.h"

namespace distile {

namespace fs = std::filesystem;

namespace {

constexpr int kMaxExtentPixels = 65536;
constexpr std::size_t kMaxPixels = std::size_t(1) << 28;

enum class ImageFormat { Png, Tiff, Exr };

ImageFormat formatFromExtension(const fs::path& file) {
    const std::string extension = lowerExtension(file);
    if (extension == ".png") return ImageFormat::Png;
    if (extension == ".tif" || extension == ".tiff") return ImageFormat::Tiff;
    if (extension == ".exr") return ImageFormat::Exr;
    throw InputError(file.string() + ": image extension '" + file.extension().string() +
                     "' is not accepted; use .png, .exr, .tif or .tiff");
}

std::string pixelText(const glm::vec3& rgb) {
    return "(" + std::to_string(rgb.r) + ", " + std::to_string(rgb.g) + ", " +
           std::to_string(rgb.b) + ")";
}

/// Every channel of `image` as code(value), in parallel.
template <typename Code, class ToCode>
std::vector<Code> encodeChannels(const Image& image, const ToCode& code) {
    std::vector<Code> codes(image.rgbLinear.size() * 3);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, image.rgbLinear.size(), 4096),
                      [&](const tbb::blocked_range<std::size_t>& pixels) {
                          for (std::size_t i = pixels.begin(); i != pixels.end(); ++i) {
                              for (int channel = 0; channel < 3; ++channel) {
                                  codes[3 * i + std::size_t(channel)] =
                                      code(image.rgbLinear[i][channel]);
                              }
                          }
                      });
    return codes;
}

/// A value's sRGB code as `Code` holds it (0 to its maximum), by the transfer function: what
/// 16-bit files hold, and what srgbCode8's table reproduces for 8-bit ones.
template <typename Code>
Code exactSrgbCode(float linear) {
    return Code(std::lround(srgbFromLinear(linear) * float(std::numeric_limits<Code>::max())));
}

/// srgbCode8's table. exactSrgbCode<std::uint8_t> is non-decreasing, and the non-negative floats
/// are ordered as their bit patterns, so code k (1 to 255) starts at the least float that reaches
/// it, found by bisection over the floats in [0, 1]; a value's code is the number of those
/// thresholds at or below it. The code at the start of each bucket of floats with the same top
/// 16 bits is kept, from which the thresholds step a value on by the few codes a bucket spans.
struct SrgbCodes8 {
    static constexpr std::uint32_t kOne = 0x3f800000u;  // the bits of 1.0f
    std::array<float, 257> firstOfCode{};               ///< [0] = 0, [256] = infinity: sentinels
    std::vector<std::uint8_t> bucketStart;  ///< code at the first float of bucket bits >> 16
    std::uint8_t atMostZero = exactSrgbCode<std::uint8_t>(0.0f),
                 atLeastOne = exactSrgbCode<std::uint8_t>(1.0f);  ///< clamped

    SrgbCodes8() : bucketStart(kOne >> 16) {
        for (int code = 1; code <= 255; ++code) {
            std::uint32_t low = 0, high = kOne;  // exactSrgbCode<std::uint8_t>(1.0f) is 255
            while (low < high) {
                const std::uint32_t middle = low + (high - low) / 2;
                if (exactSrgbCode<std::uint8_t>(std::bit_cast<float>(middle)) >= code)
                    high = middle;
                else
                    low = middle + 1;
            }
            firstOfCode[std::size_t(code)] = std::bit_cast<float>(low);
        }
        firstOfCode[256] = std::numeric_limits<float>::infinity();
        for (std::uint32_t bucket = 0; bucket < bucketStart.size(); ++bucket)
            bucketStart[bucket] = exactSrgbCode<std::uint8_t>(std::bit_cast<float>(bucket << 16));
    }

    /// srgbCode8(linear).
    std::uint8_t code(float linear) const {
        if (!(linear > 0.0f)) return atMostZero;
        if (linear >= 1.0f) return atLeastOne;
        const std::uint32_t bits = std::bit_cast<std::uint32_t>(linear);
        unsigned found = bucketStart[bits >> 16];
        // The buckets of 8-bit codes span at most one code each: one step without a branch (as
        // a branch its outcome is a coin flip, and its mispredictions took half of the time),
        // then the loop, which only guards that.
        found += unsigned(linear >= firstOfCode[found + 1]);
        while (linear >= firstOfCode[found + 1]) ++found;
        return std::uint8_t(found);
    }
};

/// The table, built at its first use.
const SrgbCodes8& srgbCodes8() {
    static const SrgbCodes8 table;
    return table;
}

}  // namespace

std::uint8_t srgbCode8(float linear) {
    return srgbCodes8().code(linear);
}

namespace {

bool equalIgnoringCase(std::string_view a, std::string_view b) {
    return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](unsigned char x, unsigned char y) {
        return std::tolower(x) == std::tolower(y);
    });
}

/// How integer pixels of a file are turned into linear values.
enum class Transfer { Linear, Srgb, Gamma };

}  // namespace

Image::Image(int widthPixels, int heightPixels, glm::vec3 fill) {
    if (widthPixels < 1 || heightPixels < 1 || widthPixels > kMaxExtentPixels ||
        heightPixels > kMaxExtentPixels ||
        std::size_t(widthPixels) * std::size_t(heightPixels) > kMaxPixels) {
        throw InputError("image: size " + std::to_string(widthPixels) + "x" +
                         std::to_string(heightPixels) +
                         " is not accepted; each extent must be in [1, 65536], at most 2^28 "
                         "pixels");
    }
    width = widthPixels;
    height = heightPixels;
    rgbLinear.resize(std::size_t(width) * std::size_t(height));  // uninitialised
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rgbLinear.size()),
                      [&](const tbb::blocked_range<std::size_t>& pixels) {
                          std::fill(rgbLinear.begin() + std::ptrdiff_t(pixels.begin()),
                                    rgbLinear.begin() + std::ptrdiff_t(pixels.end()), fill);
                      });
}

float srgbFromLinear(float linear) {
    const float clamped = std::clamp(linear, 0.0f, 1.0f);
    return clamped <= 0.0031308f ? 12.92f * clamped
                                 : 1.055f * std::pow(clamped, 1.0f / 2.4f) - 0.055f;
}

float linearFromSrgb(float encoded) {
    const float clamped = std::clamp(encoded, 0.0f, 1.0f);
    return clamped <= 0.04045f ? clamped / 12.92f : std::pow((clamped + 0.055f) / 1.055f, 2.4f);
}

void writeImage(const Image& image, const fs::path& file) {
    const ImageFormat format = formatFromExtension(file);
    if (image.width < 1 || image.height < 1 ||
        image.rgbLinear.size() != std::size_t(image.width) * std::size_t(image.height)) {
        throw InputError(file.string() + ": image is " + std::to_string(image.width) + "x" +
                         std::to_string(image.height) + " but holds " +
                         std::to_string(image.rgbLinear.size()) +
                         " pixels; a non-empty image holds exactly width * height pixels");
    }
    // The first pixel that is not finite, if any (in parallel: on one thread this check was a
    // tenth of the time of writing a PNG).
    const std::size_t firstNotFinite = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, image.rgbLinear.size(), 16384), image.rgbLinear.size(),
        [&](const tbb::blocked_range<std::size_t>& pixels, std::size_t found) {
            for (std::size_t i = pixels.begin(); i != pixels.end() && i < found; ++i) {
                const glm::vec3& rgb = image.rgbLinear[i];
                if (!std::isfinite(rgb.r) || !std::isfinite(rgb.g) || !std::isfinite(rgb.b))
                    return i;
            }
            return found;
        },
        [](std::size_t a, std::size_t b) { return std::min(a, b); });
    if (firstNotFinite < image.rgbLinear.size()) {
        const std::size_t i = firstNotFinite;
        throw InternalError(
            file.string() + ": pixel (" + std::to_string(i % std::size_t(image.width)) + ", " +
            std::to_string(i / std::size_t(image.width)) + ") is " + pixelText(image.rgbLinear[i]) +
            "; rendered pixels must be finite (this is a renderer bug)");
    }

    using image_files::PixelType;
    image_files::Spec spec;
    spec.width = image.width;
    spec.height = image.height;
    spec.channels = 3;
    if (format == ImageFormat::Png) {
        // zlib's fastest level: the same pixels; a render's file is hardly larger (detail leaves
        // little for the slower levels to find), and level 6's deflate was a tenth of the CPU of
        // a whole `distile render` of 1280 x 1024 without shadows. No row filter: libpng's
        // default tries all five on every row, a third of the time of writing the demo's image,
        // and the file came out 15% larger with them (detail is noise to a row predictor).
        spec.pixelType = PixelType::UInt8;
        spec.attributes = {{"oiio:ColorSpace", std::string("sRGB")},
                           {"png:compressionLevel", 1},
                           {"png:filter", 8}};  // PNG_FILTER_NONE
        // The table's lookup inlined in the loop (as a call per value it was 20 ms of the demo's
        // 1280 x 1024 image on two threads).
        const SrgbCodes8& table = srgbCodes8();
        const std::vector<std::uint8_t> codes = encodeChannels<std::uint8_t>(
            image, [&table](float linear) { return table.code(linear); });
        writeAtomically(file, [&](const fs::path& temporary) {
            image_files::write(temporary, file, spec, PixelType::UInt8, codes.data());
        });
    } else if (format == ImageFormat::Tiff) {
        spec.pixelType = PixelType::UInt16;
        spec.attributes = {{"oiio:ColorSpace", std::string("sRGB")},
                           {"compression", std::string("zip")}};
        const std::vector<std::uint16_t> codes =
            encodeChannels<std::uint16_t>(image, exactSrgbCode<std::uint16_t>);
        writeAtomically(file, [&](const fs::path& temporary) {
            image_files::write(temporary, file, spec, PixelType::UInt16, codes.data());
        });
    } else {
        spec.pixelType = PixelType::Float;
        spec.attributes = {{"oiio:ColorSpace", std::string("Linear")},
                           {"compression", std::string("zip")}};
        writeAtomically(file, [&](const fs::path& temporary) {
            image_files::write(temporary, file, spec, PixelType::Float, image.rgbLinear.data());
        });
    }
}

void requireImageExtension(const fs::path& file) {
    formatFromExtension(file);
}

Image readImage(const fs::path& file) {
    requireRegularFile(file, "an image file");
    const auto input = image_files::open(file);
    const image_files::Spec& spec = input->spec();
    if (spec.channels < 1 || spec.depth != 1 || spec.deep) {
        throw FormatError(file.string() + ": has " + std::to_string(spec.channels) +
                          " channel(s), depth " + std::to_string(spec.depth) +
                          (spec.deep ? ", deep" : "") +
                          "; a flat 2D image with at least one channel is accepted");
    }
    // The pixels as read (up to 3 float channels) and as kept (3 floats).
    requireWithinMemoryBudget(
        file, "an image of " + std::to_string(spec.width) + "x" + std::to_string(spec.height),
        saturatingProduct(
            std::uint64_t(std::max(spec.width, 0)) * std::uint64_t(std::max(spec.height, 0)),
            6 * sizeof(float)));
    Image image;
    try {
        image = Image(spec.width, spec.height);
    } catch (const InputError& error) {
        throw FormatError(file.string() + ": " + error.what());
    }

    const int channels = std::min(spec.channels, 3);
    std::vector<float> values(image.rgbLinear.size() * std::size_t(channels));
    if (const std::string problem = input->readFloats(channels, values); !problem.empty()) {
        throw FormatError(file.string() + ": cannot read the pixels (" + problem +
                          "); the file is truncated or corrupted");
    }

    const std::string colorSpace = spec.text("oiio:ColorSpace");
    const image_files::Attribute* gammaEntry = spec.find("oiio:Gamma");
    const float* gammaValue = gammaEntry ? std::get_if<float>(&gammaEntry->value) : nullptr;
    const float gamma = gammaValue ? *gammaValue : 1.0f;
    Transfer transfer = Transfer::Linear;
    const bool floatingPoint = spec.pixelType == image_files::PixelType::Half ||
                               spec.pixelType == image_files::PixelType::Float;
    if (!floatingPoint) {
        if (equalIgnoringCase(colorSpace, "GammaCorrected") && gamma > 0.0f) {
            transfer = Transfer::Gamma;
        } else if (!equalIgnoringCase(colorSpace, "Linear")) {
            transfer = Transfer::Srgb;
        }
    }
    auto decode = [&](float value) {
        switch (transfer) {
            case Transfer::Srgb:
                return linearFromSrgb(value);
            case Transfer::Gamma:
                return std::pow(std::max(value, 0.0f), gamma);
            case Transfer::Linear:
                break;
        }
        return value;
    };

    for (std::size_t i = 0; i < image.rgbLinear.size(); ++i) {
        const float* pixel = values.data() + i * std::size_t(channels);
        glm::vec3 rgb =
            channels >= 3 ? glm::vec3(pixel[0], pixel[1], pixel[2]) : glm::vec3(pixel[0]);
        if (!std::isfinite(rgb.r) || !std::isfinite(rgb.g) || !std::isfinite(rgb.b)) {
            throw FormatError(file.string() + ": pixel (" +
                              std::to_string(i % std::size_t(image.width)) + ", " +
                              std::to_string(i / std::size_t(image.width)) + ") is " +
                              pixelText(rgb) + "; only finite pixel values are accepted");
        }
        image.rgbLinear[i] = glm::vec3(decode(rgb.r), decode(rgb.g), decode(rgb.b));
    }
    return image;
}

}  // namespace distile
