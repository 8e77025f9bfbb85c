#include "render/compare.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
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

}  // namespace

RenderComparison compareRenders(const RenderLayersView& a, const RenderLayersView& b,
                                Image* difference) {
    requireLayers(a, a.image, "A");
    requireLayers(b, a.image, "B");
    RenderComparison result;
    result.width = a.image.width;
    result.height = a.image.height;
    result.pixels = std::uint64_t(result.width) * std::uint64_t(result.height);
    if (difference) *difference = Image(result.width, result.height);

    std::vector<double> hitErrors;
    double normalErrorSum = 0.0;
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
                difference->at(x, y) =
                    hitA != hitB ? glm::vec3(1.0f, 0.0f, 1.0f) : heatColor(4.0f * largest);
            }
            if (hitA != hitB) {
                ++result.coverageMismatches;
                continue;
            }
            if (!hitA) continue;
            ++result.bothHit;
            const float scaleA = a.texelScale.at(x, y).x;
            const float texelsPerWorld = scaleA > 0.0f ? scaleA : b.texelScale.at(x, y).x;
            if (texelsPerWorld > 0.0f)
                hitErrors.push_back(std::abs(double(depthA) - double(depthB)) * texelsPerWorld);
            const glm::dvec3 normalA = decodeNormal(a.normal.at(x, y));
            const glm::dvec3 normalB = decodeNormal(b.normal.at(x, y));
            const double lengths = glm::length(normalA) * glm::length(normalB);
            if (lengths > 0.0) {
                normalErrorSum +=
                    std::acos(std::clamp(glm::dot(normalA, normalB) / lengths, -1.0, 1.0)) * 180.0 /
                    kPi;
            }
        }
    }
    result.coverageMismatchShare =
        result.pixels ? double(result.coverageMismatches) / double(result.pixels) : 0.0;
    result.meanNormalErrorDeg = result.bothHit ? normalErrorSum / double(result.bothHit) : 0.0;
    result.hitErrorSamples = hitErrors.size();
    if (!hitErrors.empty()) {
        double sum = 0.0;
        for (const double error : hitErrors) sum += error;
        result.meanHitErrorTexels = sum / double(hitErrors.size());
        result.maxHitErrorTexels = *std::max_element(hitErrors.begin(), hitErrors.end());
        // Nearest rank: the smallest error at or above 99% of the samples.
        const std::size_t rank = std::size_t(std::ceil(0.99 * double(hitErrors.size()))) - 1;
        std::nth_element(hitErrors.begin(), hitErrors.begin() + std::ptrdiff_t(rank),
                         hitErrors.end());
        result.p99HitErrorTexels = hitErrors[rank];
    }
    const double meanSquaredError = squaredErrorSum / (3.0 * double(result.pixels));
    result.psnrDb = meanSquaredError > 0.0 ? 10.0 * std::log10(1.0 / meanSquaredError)
                                           : std::numeric_limits<double>::infinity();
    return result;
}

}  // namespace distile
