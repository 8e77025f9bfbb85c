#include "common/shell_map.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace distile {

ShellPrism ShellPrism::make(const glm::vec3 corners[3], const glm::vec3 normals[3],
                            const glm::vec2 uvs[3], const glm::vec2& uvScale, int width, int height,
                            int depthTexels, double depthWorld) {
    ShellPrism prism;
    prism.corner0 = glm::dvec3(corners[0]);
    prism.edge1 = glm::dvec3(corners[1]) - prism.corner0;
    prism.edge2 = glm::dvec3(corners[2]) - prism.corner0;
    prism.normal0 = glm::dvec3(normals[0]);
    prism.normalDelta1 = glm::dvec3(normals[1]) - prism.normal0;
    prism.normalDelta2 = glm::dvec3(normals[2]) - prism.normal0;
    prism.depthWorld = depthWorld;
    prism.depthTexels = depthTexels;
    prism.texelsPerDepthWorld = depthTexels / depthWorld;
    const glm::dvec2 texelsPerUv(double(uvScale.x) * width, double(uvScale.y) * height);
    const glm::dvec2 origin = glm::dvec2(uvs[0]) * texelsPerUv;
    prism.texelOrigin = {origin.x - std::floor(origin.x / width) * width,
                         origin.y - std::floor(origin.y / height) * height};
    prism.texelEdge1 = (glm::dvec2(uvs[1]) - glm::dvec2(uvs[0])) * texelsPerUv;
    prism.texelEdge2 = (glm::dvec2(uvs[2]) - glm::dvec2(uvs[0])) * texelsPerUv;
    return prism;
}

PrismPoint ShellPrism::pointAtTexel(const glm::dvec3& texel) const {
    const glm::dvec2 relative = glm::dvec2(texel) - texelOrigin;
    const double determinant = texelEdge1.x * texelEdge2.y - texelEdge2.x * texelEdge1.y;
    PrismPoint point;
    point.b1 = (relative.x * texelEdge2.y - texelEdge2.x * relative.y) / determinant;
    point.b2 = (texelEdge1.x * relative.y - relative.x * texelEdge1.y) / determinant;
    point.depthWorld = depthWorld * (1.0 - texel.z / depthTexels);
    return point;
}

double ShellPrism::foldDepthWorld() const {
    // det J(b, h) is a quadratic in h for fixed b: fitted through h = 0, +-depthWorld, then its
    // smallest positive root where the sign leaves that of the top.
    constexpr double kSamples[7][2] = {
        {0, 0}, {1, 0}, {0, 1}, {0.5, 0}, {0.5, 0.5}, {0, 0.5}, {1.0 / 3, 1.0 / 3}};
    const double limit = 1e6 * depthWorld;
    double fold = std::numeric_limits<double>::infinity();
    for (const auto& sample : kSamples) {
        auto atDepth = [&](double depth) { return determinantAt({sample[0], sample[1], depth}); };
        const double top = atDepth(0.0);
        const double up = atDepth(-depthWorld);
        const double down = atDepth(depthWorld);
        const double a =
            0.5 * (up + down) / (depthWorld * depthWorld) - top / (depthWorld * depthWorld);
        const double b = 0.5 * (down - up) / depthWorld;
        const double c = top;
        double roots[2];
        int count = 0;
        if (std::abs(a) < 1e-300 || std::abs(a * limit) < 1e-12 * std::abs(b)) {
            if (b != 0.0) roots[count++] = -c / b;
        } else {
            const double discriminant = b * b - 4.0 * a * c;
            if (discriminant >= 0.0) {
                const double root = std::sqrt(discriminant);
                roots[count++] = (-b - root) / (2.0 * a);
                roots[count++] = (-b + root) / (2.0 * a);
            }
        }
        for (int index = 0; index < count; ++index)
            if (roots[index] > 0.0 && roots[index] < limit) fold = std::min(fold, roots[index]);
    }
    return fold;
}

}  // namespace distile
