#include "view/contact_sheet.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/common.hpp>
#include <stdexcept>
#include <vector>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/image_files.h"
#include "sampler/tile_io.h"

namespace distile {

namespace fs = std::filesystem;

namespace {

constexpr glm::vec3 kBackground{0.12f, 0.12f, 0.13f};
constexpr glm::vec3 kTextColor{0.92f, 0.92f, 0.92f};
constexpr const char* kFont = "DejaVuSans";
constexpr int kFontPixels = 14;

/// "-1.5", "0", "16": a tick label with at most three significant digits.
std::string texelLabel(float value) {
    char text[32];
    std::snprintf(text, sizeof text, "%.3g", double(value));
    return text;
}

}  // namespace

glm::vec3 divergingColor(float value) {
    // Ends and middle of a blue-white-red map (sRGB); equal lightness steps on both sides.
    constexpr glm::vec3 kInside{0.13f, 0.31f, 0.72f};
    constexpr glm::vec3 kZero{0.97f, 0.97f, 0.97f};
    constexpr glm::vec3 kOutside{0.75f, 0.10f, 0.12f};
    const float t = std::isnan(value) ? 0.0f : std::clamp(value, -1.0f, 1.0f);
    return t < 0.0f ? glm::mix(kZero, kInside, -t) : glm::mix(kZero, kOutside, t);
}

ContactSheetLayout::ContactSheetLayout(const Size3& fieldSize) : size(fieldSize) {
    const AtlasGrid grid = atlasGrid(size.depth);
    cols = grid.cols;
    rows = grid.rows;
    const int longer = std::max(size.width, size.height);
    if (longer <= kCellTargetPixels) {
        magnify = std::max(1, kCellTargetPixels / longer);
    } else {
        stride = (longer + kCellTargetPixels - 1) / kCellTargetPixels;
    }
    cellWidth = (size.width + stride - 1) / stride * magnify;
    cellHeight = (size.height + stride - 1) / stride * magnify;
    width = margin + cols * (cellWidth + margin) + barWidth + barLabelWidth;
    height = margin + rows * (labelHeight + cellHeight + margin);
}

int ContactSheetLayout::cellLeft(int slice) const {
    return margin + (slice % cols) * (cellWidth + margin);
}

int ContactSheetLayout::cellTop(int slice) const {
    return margin + (slice / cols) * (labelHeight + cellHeight + margin) + labelHeight;
}

int ContactSheetLayout::barLeft() const {
    return margin + cols * (cellWidth + margin) + margin;
}

int ContactSheetLayout::barTop() const {
    return margin + labelHeight;
}

int ContactSheetLayout::barBottom() const {
    return height - margin - 1;
}

bool writeContactSheet(std::span<const float> values, const Size3& size,
                       const ContactSheetOptions& options, const fs::path& file) {
    std::string extension = file.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    if (extension != ".png") {
        throw InputError(file.string() + ": extension '" + file.extension().string() +
                         "' is not accepted for a contact sheet; use .png");
    }
    if (values.size() != size.texelCount()) {
        throw InputError("values: " + std::to_string(values.size()) + " values for a " +
                         std::to_string(size.width) + "x" + std::to_string(size.height) + "x" +
                         std::to_string(size.depth) + " field; it needs one per texel");
    }
    const std::span<const float> contour =
        options.contourField.empty() ? values : options.contourField;
    if (contour.size() != values.size()) {
        throw InputError("contourField: " + std::to_string(contour.size()) +
                         " values; it needs one per texel, as values");
    }
    if (!(std::isfinite(options.rangeTexels) && options.rangeTexels > 0.0f)) {
        throw InputError("rangeTexels = " + numberText(options.rangeTexels) +
                         " is not accepted; it must be finite and > 0");
    }
    const ContactSheetLayout layout(size);
    std::vector<glm::vec3> picture(std::size_t(layout.width) * std::size_t(layout.height),
                                   kBackground);
    auto put = [&](int x, int y, const glm::vec3& color) {
        picture[std::size_t(x) + std::size_t(layout.width) * std::size_t(y)] = color;
    };
    auto at = [&](std::span<const float> field, int x, int y, int z) {
        x = (x % size.width + size.width) % size.width;  // periodic neighbours
        y = (y % size.height + size.height) % size.height;
        return field[std::size_t(x) +
                     std::size_t(size.width) * (std::size_t(y) + std::size_t(size.height) * z)];
    };
    for (int z = 0; z < size.depth; ++z) {
        for (int y = 0; y < size.height; y += layout.stride) {
            for (int x = 0; x < size.width; x += layout.stride) {
                const bool inside = at(contour, x, y, z) < 0.0f;
                // A contour texel: inside, with a neighbour outside (one line, on the inner side).
                const bool onContour =
                    inside &&
                    (!(at(contour, x + 1, y, z) < 0.0f) || !(at(contour, x - 1, y, z) < 0.0f) ||
                     !(at(contour, x, y + 1, z) < 0.0f) || !(at(contour, x, y - 1, z) < 0.0f));
                const glm::vec3 color =
                    onContour ? kContourColor
                              : divergingColor(at(values, x, y, z) / options.rangeTexels);
                const int left = layout.pixelX(z, x), top = layout.pixelY(z, y);
                for (int dy = 0; dy < layout.magnify; ++dy)
                    for (int dx = 0; dx < layout.magnify; ++dx) put(left + dx, top + dy, color);
            }
        }
    }
    // The colour bar: +range at the top, -range at the bottom.
    const int barRows = layout.barBottom() - layout.barTop();
    for (int row = 0; row <= barRows; ++row) {
        const float value = 1.0f - 2.0f * float(row) / float(barRows);
        for (int x = 0; x < layout.barWidth; ++x)
            put(layout.barLeft() + x, layout.barTop() + row, divergingColor(value));
    }
    // Labels: each slice's z, the bar's title and ticks.
    bool labelled = true;
    auto text = [&](int x, int baseline, const std::string& words) {
        const float color[3] = {kTextColor.r, kTextColor.g, kTextColor.b};
        labelled =
            labelled &&
            image_files::drawText(std::span<float>(&picture[0].x, picture.size() * 3), layout.width,
                                  layout.height, x, baseline, words, kFontPixels, kFont, color);
    };
    for (int z = 0; z < size.depth && labelled; ++z)
        text(layout.cellLeft(z), layout.cellTop(z) - 4, "z = " + texelLabel(float(z) + 0.5f));
    const int tickX = layout.barLeft() + layout.barWidth + 4;
    if (labelled) {
        text(layout.barLeft(), layout.barTop() - 4, options.barTitle);
        text(tickX, layout.barTop() + kFontPixels, "+" + texelLabel(options.rangeTexels));
        text(tickX, (layout.barTop() + layout.barBottom()) / 2 + kFontPixels / 2, "0");
        text(tickX, layout.barBottom(), "-" + texelLabel(options.rangeTexels));
    }
    image_files::Spec spec;
    spec.width = layout.width;
    spec.height = layout.height;
    spec.channels = 3;
    spec.pixelType = image_files::PixelType::UInt8;
    spec.set("oiio:ColorSpace", std::string("sRGB"));
    writeAtomically(file, [&](const fs::path& temporary) {
        image_files::write(temporary, file, spec, image_files::PixelType::Float, picture.data());
    });
    return labelled;
}

bool writeTilePreview(const Tile& tile, const fs::path& file) {
    ContactSheetOptions options;
    options.rangeTexels = signedPngRangeTexels(tile);  // the largest |distance| (1 for zeros)
    options.barTitle = "distance, texels";
    return writeContactSheet(tile.distancesTexels(), tile.size(), options, file);
}

bool writeTileErrorPlot(const Tile& tile, const std::function<double(const glm::dvec3&)>& truth,
                        double truthClampTexels, const fs::path& file) {
    const Size3& size = tile.size();
    std::vector<float> errors(size.texelCount());
    std::vector<float> truths(size.texelCount());
    float largest = 0.0f;
    std::size_t index = 0;
    for (int z = 0; z < size.depth; ++z) {
        for (int y = 0; y < size.height; ++y) {
            for (int x = 0; x < size.width; ++x, ++index) {
                const double exact = truth({x + 0.5, y + 0.5, z + 0.5});
                if (std::isnan(exact)) {
                    throw std::runtime_error("the truth is NaN at texel (" + std::to_string(x) +
                                             ", " + std::to_string(y) + ", " + std::to_string(z) +
                                             ")");
                }
                truths[index] = float(exact);
                const double clamped = std::clamp(exact, -truthClampTexels, truthClampTexels);
                errors[index] = float(double(tile.at(x, y, z)) - clamped);
                largest = std::max(largest, std::abs(errors[index]));
            }
        }
    }
    ContactSheetOptions options;
    options.rangeTexels = largest > 0.0f ? largest : 1.0f;
    options.barTitle = "tile - truth, texels";
    options.contourField = truths;
    return writeContactSheet(errors, size, options, file);
}

}  // namespace distile
