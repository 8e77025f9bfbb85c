#include "render/compare.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/error.h"
#include "render/renderer.h"

namespace distile {

namespace {

constexpr double kPi = 3.14159265358979323846;

void requireSize(const Image& layer, const Image& image, const char* which, const char* layerName) {
    if (layer.width == image.width && layer.height == image.height &&
        layer.rgbLinear.size() == std::size_t(image.width) * std::size_t(image.height)) {
        return;
    }
    throw InputError(std::string("compare: ") + which + "'s " + layerName + " layer is " +
                     std::to_string(layer.width) + "x" + std::to_string(layer.height) +
                     " but the images are " + std::to_string(image.width) + "x" +
                     std::to_string(image.height) +
                     "; only renders of the same size with all AOVs can be compared");
}

void requireLayers(const RenderLayersView& layers, const Image& reference, const char* which) {
    requireSize(layers.image, reference, which, "image");
    requireSize(layers.depth, reference, which, "depth");
    requireSize(layers.normal, reference, which, "normal");
    requireSize(layers.texelScale, reference, which, "texel_scale");
}

glm::dvec3 decodeNormal(const glm::vec3& encoded) {
    return glm::dvec3(encoded) * 2.0 - 1.0;
}

glm::vec3 encoded(const glm::vec3& linear) {
    return {srgbFromLinear(linear.x), srgbFromLinear(linear.y), srgbFromLinear(linear.z)};
}

/// Texels per world unit along the ray at (x, y): A's scale, B's where A's is 0; 0 when neither
/// render hit a tile there.
float texelsPerWorldAt(const RenderLayersView& a, const RenderLayersView& b, int x, int y) {
    const float scaleA = a.texelScale.at(x, y).x;
    return scaleA > 0.0f ? scaleA : b.texelScale.at(x, y).x;
}

/// Whether both-hit pixel (x, y) is a silhouette pixel (compare.h): in either render a neighbour
/// inside the image misses or lies across a depth jump.
bool isSilhouette(const Image& depthA, const Image& depthB, int x, int y, double texelsPerWorld) {
    const int width = depthA.width;
    const int height = depthA.height;
    const auto inside = [&](int px, int py) {
        return px >= 0 && py >= 0 && px < width && py < height;
    };
    for (const Image* depth : {&depthA, &depthB}) {
        // The depth at (px, py) when that pixel is inside the image and hits, else 0.
        const auto hitDepth = [&](int px, int py) {
            return inside(px, py) ? double(depth->at(px, py).x) : 0.0;
        };
        const double here = depth->at(x, y).x;
        for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
                if ((dx == 0 && dy == 0) || !inside(x + dx, y + dy)) continue;
                const double neighbour = hitDepth(x + dx, y + dy);
                if (neighbour <= 0.0) return true;
                const double step = (neighbour - here) * texelsPerWorld;  // signed, texels
                if (std::abs(step) <= kDepthJumpFloorTexels) continue;
                // The steps beside this one on the same line, where both their pixels hit. One
                // explains it as a slope when it goes the same way and is at least
                // 1 / kDepthJumpRatio of it; one the other way makes a spike (a pixel that sees
                // through a gap or hits a thin wire), no slope.
                const double before = hitDepth(x - dx, y - dy);
                const double after = hitDepth(x + 2 * dx, y + 2 * dy);
                if (before <= 0.0 && after <= 0.0) continue;  // no line to judge the step by
                const auto slopesOn = [&](double besideStep) {
                    return besideStep * step > 0.0 &&
                           std::abs(step) <= kDepthJumpRatio * std::abs(besideStep);
                };
                const bool slope = (before > 0.0 && slopesOn((here - before) * texelsPerWorld)) ||
                                   (after > 0.0 && slopesOn((after - neighbour) * texelsPerWorld));
                if (!slope) return true;
            }
        }
    }
    return false;
}

/// Accumulates one class of both-hit pixels.
struct ClassErrors {
    std::uint64_t pixels = 0;
    std::vector<double> hitErrorsTexels;
    double normalErrorSumDeg = 0.0;
};

/// The number, mean, 99th percentile (nearest rank: the smallest error at or above 99% of the
/// samples) and maximum of `errors`; leaves the figures as they are when there are none.
/// Reorders `errors`.
void summariseHitErrors(std::vector<double>& errors, std::uint64_t& samples, double& mean,
                        double& p99, double& max) {
    samples = errors.size();
    if (errors.empty()) return;
    double sum = 0.0;
    for (const double error : errors) sum += error;
    mean = sum / double(errors.size());
    max = *std::max_element(errors.begin(), errors.end());
    const std::size_t rank = std::size_t(std::ceil(0.99 * double(errors.size()))) - 1;
    std::nth_element(errors.begin(), errors.begin() + std::ptrdiff_t(rank), errors.end());
    p99 = errors[rank];
}

HitErrorSummary summarise(ClassErrors& errors) {
    HitErrorSummary summary;
    summary.pixels = errors.pixels;
    summary.meanNormalErrorDeg =
        errors.pixels ? errors.normalErrorSumDeg / double(errors.pixels) : 0.0;
    summariseHitErrors(errors.hitErrorsTexels, summary.hitErrorSamples, summary.meanHitErrorTexels,
                       summary.p99HitErrorTexels, summary.maxHitErrorTexels);
    return summary;
}

// The heat map's colour bar and its labels, in a 3 x 5 pixel font (digits, '.', and the letters
// of "texels") drawn at twice that size.
constexpr int kGlyphScale = 2;
constexpr int kGlyphAdvance = 4 * kGlyphScale;  // 3 columns and one of space

/// Rows of the glyph of `character`, top first, bit 2 the leftmost column; all zero if the
/// font has no such glyph.
std::array<std::uint8_t, 5> glyphRows(char character) {
    switch (character) {
        case '0':
            return {7, 5, 5, 5, 7};
        case '1':
            return {2, 6, 2, 2, 7};
        case '2':
            return {7, 1, 7, 4, 7};
        case '3':
            return {7, 1, 7, 1, 7};
        case '4':
            return {5, 5, 7, 1, 1};
        case '5':
            return {7, 4, 7, 1, 7};
        case '6':
            return {7, 4, 7, 5, 7};
        case '7':
            return {7, 1, 1, 1, 1};
        case '8':
            return {7, 5, 7, 5, 7};
        case '9':
            return {7, 5, 7, 1, 7};
        case '.':
            return {0, 0, 0, 0, 2};
        case 't':
            return {2, 7, 2, 2, 3};
        case 'e':
            return {0, 7, 7, 4, 7};
        case 'x':
            return {0, 5, 2, 2, 5};
        case 'l':
            return {6, 2, 2, 2, 7};
        case 's':
            return {0, 3, 6, 1, 6};
        default:
            return {0, 0, 0, 0, 0};
    }
}

int textWidth(const std::string& text) {
    return text.empty() ? 0 : int(text.size()) * kGlyphAdvance - kGlyphScale;
}

/// Draws `text` with its top-left corner at (left, top), clipped to the image.
void drawText(Image& image, const std::string& text, int left, int top, const glm::vec3& color) {
    for (std::size_t index = 0; index < text.size(); ++index) {
        const std::array<std::uint8_t, 5> rows = glyphRows(text[index]);
        const int glyphLeft = left + int(index) * kGlyphAdvance;
        for (int row = 0; row < 5 * kGlyphScale; ++row) {
            for (int column = 0; column < 3 * kGlyphScale; ++column) {
                if (!(rows[std::size_t(row / kGlyphScale)] & (4 >> (column / kGlyphScale))))
                    continue;
                const int x = glyphLeft + column;
                const int y = top + row;
                if (x >= 0 && y >= 0 && x < image.width && y < image.height) image.at(x, y) = color;
            }
        }
    }
}

/// Draws the colour bar into the kHeatMapBarHeight rows from `top` (black already): the scale
/// from kHeatMapMinTexels on the left to kHeatMapMaxTexels on the right, a tick and a label at
/// each power of ten, and the unit to the right.
void drawColourBar(Image& image, int top) {
    const glm::vec3 white(1.0f);
    const std::string unit = "texels";
    const int unitLeft = image.width - 8 - textWidth(unit);
    const int barLeft = 16;
    const int barRight = std::max(barLeft + 1, unitLeft - 8 - textWidth("100") / 2 - 2);
    const int barTop = top + 4;
    const int barBottom = barTop + 10;  // exclusive
    const double decades = std::log10(kHeatMapMaxTexels / kHeatMapMinTexels);
    for (int x = barLeft; x <= barRight && x < image.width; ++x) {
        const float t = float(x - barLeft) / float(barRight - barLeft);
        for (int y = barTop; y < barBottom; ++y) image.at(x, y) = heatColor(t);
    }
    const int labelTop = barBottom + 5;
    for (int decade = 0; decade <= int(std::lround(decades)); ++decade) {
        const double texels = kHeatMapMinTexels * std::pow(10.0, decade);
        const int x = barLeft + int(std::lround(double(barRight - barLeft) * decade / decades));
        if (x >= image.width) break;
        for (int y = barBottom; y < barBottom + 3; ++y) image.at(x, y) = white;
        char label[16];
        std::snprintf(label, sizeof label, "%g", texels);
        drawText(image, label, x - textWidth(label) / 2, labelTop, white);
    }
    drawText(image, unit, unitLeft, labelTop, white);
}

}  // namespace

glm::vec3 hitErrorColor(double errorTexels) {
    if (!(errorTexels > kHeatMapMinTexels)) return heatColor(0.0f);
    const double t = std::log10(errorTexels / kHeatMapMinTexels) /
                     std::log10(kHeatMapMaxTexels / kHeatMapMinTexels);
    return heatColor(float(std::min(t, 1.0)));
}

RenderComparison compareRenders(const RenderLayersView& a, const RenderLayersView& b,
                                Image* difference, Image* hitErrorMap) {
    requireLayers(a, a.image, "A");
    requireLayers(b, a.image, "B");
    RenderComparison result;
    result.width = a.image.width;
    result.height = a.image.height;
    result.pixels = std::uint64_t(result.width) * std::uint64_t(result.height);
    if (difference) *difference = Image(result.width, result.height);
    if (hitErrorMap) *hitErrorMap = Image(result.width, result.height + kHeatMapBarHeight);
    const glm::vec3 magenta(1.0f, 0.0f, 1.0f);
    const glm::vec3 bothMissColor(0.02f);  // dark grey
    const glm::vec3 noScaleColor(0.2f);    // mid grey

    ClassErrors interior, silhouette;
    double squaredErrorSum = 0.0;
    for (int y = 0; y < result.height; ++y) {
        for (int x = 0; x < result.width; ++x) {
            const float depthA = a.depth.at(x, y).x;
            const float depthB = b.depth.at(x, y).x;
            const bool hitA = depthA > 0.0f;
            const bool hitB = depthB > 0.0f;
            const glm::vec3 shadedA = encoded(a.image.at(x, y));
            const glm::vec3 shadedB = encoded(b.image.at(x, y));
            const glm::vec3 shadedDifference = glm::abs(shadedA - shadedB);
            squaredErrorSum += double(glm::dot(shadedDifference, shadedDifference));
            if (difference) {
                const float largest =
                    std::max({shadedDifference.x, shadedDifference.y, shadedDifference.z});
                difference->at(x, y) = hitA != hitB ? magenta : heatColor(4.0f * largest);
            }
            if (hitA != hitB) {
                ++result.coverageMismatches;
                if (hitErrorMap) hitErrorMap->at(x, y) = magenta;
                continue;
            }
            if (!hitA) {
                if (hitErrorMap) hitErrorMap->at(x, y) = bothMissColor;
                continue;
            }
            const float texelsPerWorld = texelsPerWorldAt(a, b, x, y);
            ClassErrors& errors =
                isSilhouette(a.depth, b.depth, x, y, texelsPerWorld) ? silhouette : interior;
            ++errors.pixels;
            if (texelsPerWorld > 0.0f) {
                const double errorTexels =
                    std::abs(double(depthA) - double(depthB)) * texelsPerWorld;
                errors.hitErrorsTexels.push_back(errorTexels);
                if (hitErrorMap) hitErrorMap->at(x, y) = hitErrorColor(errorTexels);
            } else if (hitErrorMap) {
                hitErrorMap->at(x, y) = noScaleColor;
            }
            const glm::dvec3 normalA = decodeNormal(a.normal.at(x, y));
            const glm::dvec3 normalB = decodeNormal(b.normal.at(x, y));
            const double lengths = glm::length(normalA) * glm::length(normalB);
            if (lengths > 0.0) {
                errors.normalErrorSumDeg +=
                    std::acos(std::clamp(glm::dot(normalA, normalB) / lengths, -1.0, 1.0)) * 180.0 /
                    kPi;
            }
        }
    }
    if (hitErrorMap) drawColourBar(*hitErrorMap, result.height);

    result.coverageMismatchShare =
        result.pixels ? double(result.coverageMismatches) / double(result.pixels) : 0.0;
    result.bothHit = interior.pixels + silhouette.pixels;
    result.meanNormalErrorDeg =
        result.bothHit
            ? (interior.normalErrorSumDeg + silhouette.normalErrorSumDeg) / double(result.bothHit)
            : 0.0;
    std::vector<double> allErrors = interior.hitErrorsTexels;
    allErrors.insert(allErrors.end(), silhouette.hitErrorsTexels.begin(),
                     silhouette.hitErrorsTexels.end());
    summariseHitErrors(allErrors, result.hitErrorSamples, result.meanHitErrorTexels,
                       result.p99HitErrorTexels, result.maxHitErrorTexels);
    result.interior = summarise(interior);
    result.silhouette = summarise(silhouette);
    const double meanSquaredError = squaredErrorSum / (3.0 * double(result.pixels));
    result.psnrDb = meanSquaredError > 0.0 ? 10.0 * std::log10(1.0 / meanSquaredError)
                                           : std::numeric_limits<double>::infinity();
    return result;
}

CodeDifference codeDifference(const Image& a, const Image& b) {
    if (a.width != b.width || a.height != b.height)
        throw std::logic_error("codeDifference: images of different sizes");
    CodeDifference difference;
    std::size_t differing = 0;
    for (std::size_t i = 0; i < a.rgbLinear.size(); ++i) {
        int pixelMax = 0;
        for (int channel = 0; channel < 3; ++channel) {
            const float valueA = a.rgbLinear[i][channel];
            const float valueB = b.rgbLinear[i][channel];
            difference.bitIdentical = difference.bitIdentical && valueA == valueB;
            pixelMax =
                std::max(pixelMax, std::abs(int(srgbCode8(valueA)) - int(srgbCode8(valueB))));
        }
        differing += pixelMax > 1 ? 1 : 0;
        difference.maxCodes = std::max(difference.maxCodes, pixelMax);
    }
    difference.differingShare =
        a.rgbLinear.empty() ? 0.0 : double(differing) / double(a.rgbLinear.size());
    return difference;
}

}  // namespace distile
