#include "bake/height_image.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include "common/error.h"
#include "common/exr_header.h"
#include "common/image_files.h"
#include "common/input_file.h"

namespace distile {

namespace fs = std::filesystem;

namespace {

int wrap(int index, int count) {
    const int r = index % count;
    return r < 0 ? r + count : r;
}

}  // namespace

HeightImage readHeightImage(const fs::path& file) {
    requireRegularFile(file, "a height map image (.png, .exr)");
    // By content, not name: OpenImageIO would read any of its ~100 formats (a 38-byte WebP
    // declaring 66 million pixels, named .png, decoded).
    if (!startsAsPng(file) && !startsAsExr(file)) {
        std::ifstream in(file, std::ios::binary);
        char start[8] = {};
        in.read(start, sizeof start);
        throw FormatError(file.string() + ": not a PNG or OpenEXR file (it starts with '" +
                          quotedInput(std::string_view(start, std::size_t(in.gcount()))) +
                          "'); a height map must be an 8/16-bit PNG or an EXR");
    }
    const auto input = image_files::open(file, "; a height map must be an 8/16-bit PNG or an EXR");
    const image_files::Spec& spec = input->spec();
    const long long pixels = (long long)spec.width * (long long)spec.height;
    if (spec.width <= 0 || spec.height <= 0 || spec.channels <= 0 || spec.depth > 1 ||
        pixels > kMaxHeightImagePixels) {
        std::ostringstream message;
        message << file.string() << ": image of " << spec.width << "x" << spec.height
                << " pixels and " << spec.channels
                << " channel(s) is not accepted; a height map has 1 to " << kMaxHeightImagePixels
                << " pixels in one 2D image";
        throw FormatError(message.str());
    }
    const int channels = spec.channels;
    requireWithinMemoryBudget(
        file, "a height map of " + std::to_string(pixels) + " pixels",
        saturatingProduct(std::uint64_t(pixels), (std::uint64_t(channels) + 1) * sizeof(float)));
    std::vector<float> all(std::size_t(pixels) * std::size_t(channels));
    if (const std::string problem = input->readFloats(channels, all); !problem.empty()) {
        throw FormatError(file.string() + ": cannot read the pixels (" + problem +
                          "); the file is truncated or corrupted");
    }
    HeightImage image;
    image.width = spec.width;
    image.height = spec.height;
    image.values.resize(std::size_t(pixels));
    for (std::size_t n = 0; n < image.values.size(); ++n) {
        const float* pixel = &all[n * std::size_t(channels)];
        const float grey =
            channels >= 3 ? 0.2126f * pixel[0] + 0.7152f * pixel[1] + 0.0722f * pixel[2] : pixel[0];
        if (!(std::isfinite(grey) && grey >= 0.0f && grey <= 1.0f)) {
            std::ostringstream message;
            message << file.string() << ": height " << grey << " at pixel ("
                    << n % std::size_t(image.width) << ", " << n / std::size_t(image.width)
                    << ") is not accepted; heights must be finite and in [0, 1]";
            throw FormatError(message.str());
        }
        image.values[n] = grey;
    }
    return image;
}

HeightField heightFieldFromImage(const HeightImage& image, const Size3& tile, double heightTexels) {
    validateTileSize(tile, "size");
    if (!(std::isfinite(heightTexels) && heightTexels > 0.0 &&
          heightTexels <= double(tile.depth))) {
        std::ostringstream problem;
        problem << heightTexels << " is not accepted; it must be > 0 and at most the tile depth "
                << tile.depth;
        throw InputError::inField("heightTexels", problem.str());
    }
    if (image.width <= 0 || image.height <= 0 ||
        image.values.size() != std::size_t(image.width) * std::size_t(image.height)) {
        throw InputError(
            "height map: the image is empty or its size does not match its pixel count");
    }
    const auto pixel = [&](int c, int r) {
        return double(image.values[std::size_t(wrap(c, image.width)) +
                                   std::size_t(wrap(r, image.height)) * std::size_t(image.width)]);
    };
    HeightField field;
    field.width = tile.width;
    field.height = tile.height;
    field.heightsTexels.resize(std::size_t(tile.width) * std::size_t(tile.height));
    for (int j = 0; j < tile.height; ++j) {
        // Pixel coordinates of the node, pixel centres at integers.
        const double v = (j + 0.5) / tile.height * image.height - 0.5;
        const double r0 = std::floor(v), fy = v - r0;
        for (int i = 0; i < tile.width; ++i) {
            const double u = (i + 0.5) / tile.width * image.width - 0.5;
            const double c0 = std::floor(u), fx = u - c0;
            const int c = int(c0), r = int(r0);
            const double grey = (1.0 - fy) * ((1.0 - fx) * pixel(c, r) + fx * pixel(c + 1, r)) +
                                fy * ((1.0 - fx) * pixel(c, r + 1) + fx * pixel(c + 1, r + 1));
            field.heightsTexels[std::size_t(i) + std::size_t(j) * std::size_t(tile.width)] =
                std::clamp(grey, 0.0, 1.0) * heightTexels;
        }
    }
    return field;
}

}  // namespace distile
