/// @file
/// The rendered image: linear RGB floats, row-major, row 0 at the top; and its files. PNG and
/// TIFF hold sRGB-encoded integers, EXR linear floats. Files are written through writeAtomically().
#pragma once

#include <cstdint>
#include <filesystem>
#include <glm/vec3.hpp>
#include <memory>
#include <utility>
#include <vector>

namespace distile {

namespace detail {

/// std::allocator that default-initialises new elements (a glm::vec3 stays uninitialised), so
/// an image's pixels are written once, by the threads that fill it, not zeroed first.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
    template <class U>
    struct rebind {
        using other = DefaultInitAllocator<U>;
    };
    DefaultInitAllocator() = default;
    template <class U>
    DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
    template <class U, class... Arguments>
    void construct(U* element, Arguments&&... arguments) {
        if constexpr (sizeof...(Arguments) == 0) {
            ::new (static_cast<void*>(element)) U;
        } else {
            ::new (static_cast<void*>(element)) U(std::forward<Arguments>(arguments)...);
        }
    }
};

}  // namespace detail

struct Image {
    int width = 0;
    int height = 0;
    /// Linear RGB, row-major, row 0 at the top.
    std::vector<glm::vec3, detail::DefaultInitAllocator<glm::vec3>> rgbLinear;

    Image() = default;
    /// A `widthPixels` x `heightPixels` image filled with `fill` (in parallel). Throws InputError
    /// unless each extent is in [1, 65536] and there are at most 2^28 pixels.
    Image(int widthPixels, int heightPixels, glm::vec3 fill = glm::vec3(0.0f));

    /// Pixel (x, y), x to the right, y down. Preconditions: 0 <= x < width, 0 <= y < height.
    glm::vec3& at(int x, int y) { return rgbLinear[std::size_t(x) + std::size_t(width) * y]; }
    const glm::vec3& at(int x, int y) const {
        return rgbLinear[std::size_t(x) + std::size_t(width) * y];
    }
};

/// The sRGB transfer function (IEC 61966-2-1): linear [0, 1] to encoded [0, 1], and back.
/// Inputs outside [0, 1] are clamped.
float srgbFromLinear(float linear);
float linearFromSrgb(float encoded);
/// The 8-bit code of a finite linear value, lround(srgbFromLinear(linear) * 255), by table
/// (what PNG files are written with): the same codes, without a power per channel.
std::uint8_t srgbCode8(float linear);

/// Writes `image`, choosing the format by extension (case-insensitive):
///   .png         8-bit RGB, sRGB-encoded, each channel clamped to [0, 1];
///   .tif / .tiff 16-bit RGB, sRGB-encoded, clamped, zip-compressed;
///   .exr         32-bit float linear RGB, unclamped, zip-compressed.
/// Throws InputError for another extension, for an image whose pixel count is not
/// width * height, or if the target's folder does not exist; InternalError naming the first NaN
/// or infinite pixel (a renderer bug); std::runtime_error if OpenImageIO fails. Never leaves a
/// partial file at `file`.
void writeImage(const Image& image, const std::filesystem::path& file);

/// Throws InputError naming `file` unless writeImage takes its extension (.png, .exr, .tif,
/// .tiff, any case): for callers that check a target before writing it through a temporary.
void requireImageExtension(const std::filesystem::path& file);

/// Reads any image OpenImageIO reads as linear RGB: float and half pixels as they are; integer
/// pixels sRGB-decoded unless the file says it is linear (or gamma-decoded for a PNG gAMA).
/// One or two channels (grey, grey + alpha) become grey RGB; channels past the third are
/// ignored. Throws InputError if `file` does not exist or is not a regular file; FormatError if
/// it is a broken PNG (checkPngChunks), OpenImageIO cannot read it, it is larger than Image
/// accepts or than kInputMemoryBudgetBytes, or it holds NaN or infinite values.
Image readImage(const std::filesystem::path& file);

}  // namespace distile
