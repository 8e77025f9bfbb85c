#include "render/bvh.h"

#include <algorithm>
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>

namespace distile {

namespace {

constexpr std::uint32_t kLeafSize = 4;
constexpr int kMaxDepth = 48;

glm::vec3 centroid(const std::vector<glm::vec3>& corners, std::uint32_t triangle) {
    return (corners[3 * triangle] + corners[3 * triangle + 1] + corners[3 * triangle + 2]) / 3.0f;
}

/// Slab test; true when the ray enters the box before `maxDistance`, with `enter` where
/// (at least minDistance).
[[gnu::always_inline]] inline bool hitsBox(const glm::vec3& boundsMin, const glm::vec3& boundsMax,
                                           const glm::vec3& origin,
                                           const glm::vec3& inverseDirection, float minDistance,
                                           float maxDistance, float& enter) {
    const glm::vec3 t0 = (boundsMin - origin) * inverseDirection;
    const glm::vec3 t1 = (boundsMax - origin) * inverseDirection;
    const glm::vec3 near = glm::min(t0, t1);
    const glm::vec3 far = glm::max(t0, t1);
    enter = std::max({near.x, near.y, near.z, minDistance});
    // Widen the exit slightly so a ray grazing a flat box (a plane's zero-thickness bounds) hits.
    const float exit = std::min({far.x, far.y, far.z, maxDistance}) * 1.00001f + 1e-7f;
    return enter <= exit;
}

}  // namespace

TriangleBvh::TriangleBvh(std::vector<glm::vec3> corners) : corners_(std::move(corners)) {
    const auto count = std::uint32_t(corners_.size() / 3);
    order_.resize(count);
    for (std::uint32_t i = 0; i < count; ++i) order_[i] = i;
    if (count > 0) {
        std::vector<glm::vec3> centroids(count);
        for (std::uint32_t i = 0; i < count; ++i) centroids[i] = centroid(corners_, i);
        nodes_.reserve(2 * count);
        build(centroids, 0, count, 0);
    }
}

std::uint32_t TriangleBvh::build(const std::vector<glm::vec3>& centroids, std::uint32_t first,
                                 std::uint32_t count, int depth) {
    const auto nodeIndex = std::uint32_t(nodes_.size());
    nodes_.push_back({});
    glm::vec3 boundsMin(std::numeric_limits<float>::max());
    glm::vec3 boundsMax(-std::numeric_limits<float>::max());
    glm::vec3 centroidMin = boundsMin;
    glm::vec3 centroidMax = boundsMax;
    for (std::uint32_t i = first; i < first + count; ++i) {
        for (int corner = 0; corner < 3; ++corner) {
            boundsMin = glm::min(boundsMin, corners_[3 * order_[i] + corner]);
            boundsMax = glm::max(boundsMax, corners_[3 * order_[i] + corner]);
        }
        const glm::vec3 c = centroids[order_[i]];
        centroidMin = glm::min(centroidMin, c);
        centroidMax = glm::max(centroidMax, c);
    }
    nodes_[nodeIndex].boundsMin = boundsMin;
    nodes_[nodeIndex].boundsMax = boundsMax;
    const glm::vec3 extent = centroidMax - centroidMin;
    if (count <= kLeafSize || depth >= kMaxDepth ||
        glm::max(extent.x, glm::max(extent.y, extent.z)) <= 0.0f) {
        nodes_[nodeIndex].first = first;
        nodes_[nodeIndex].count = count;
        return nodeIndex;
    }
    // Median split along the longest centroid axis: balanced, simple, fine for base meshes.
    const int axis =
        extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    const std::uint32_t half = count / 2;
    std::nth_element(order_.begin() + first, order_.begin() + first + half,
                     order_.begin() + first + count, [&](std::uint32_t a, std::uint32_t b) {
                         return centroids[a][axis] < centroids[b][axis];
                     });
    build(centroids, first, half, depth + 1);
    const std::uint32_t right = build(centroids, first + half, count - half, depth + 1);
    nodes_[nodeIndex].first = right;
    nodes_[nodeIndex].count = 0;
    return nodeIndex;
}

bool TriangleBvh::intersect(const Ray& ray, float minDistance, float maxDistance,
                            TriangleHit& hit) const {
    if (nodes_.empty()) return false;
    const glm::vec3 inverseDirection = 1.0f / ray.direction;
    bool found = false;
    double nearest = maxDistance;
    // Among hits at exactly the same distance (a ray through an edge two triangles share) the one
    // first in order_ wins, whatever order the nodes are visited in.
    std::uint32_t nearestOrder = 0;
    float enter = 0.0f;
    if (!hitsBox(nodes_[0].boundsMin, nodes_[0].boundsMax, ray.origin, inverseDirection,
                 minDistance, maxDistance, enter)) {
        return false;
    }
    // Nearer child first, so the nearest hit is found early and prunes the farther boxes.
    std::uint32_t stack[2 * kMaxDepth + 2];
    int stackSize = 0;
    stack[stackSize++] = 0;
    while (stackSize > 0) {
        const std::uint32_t nodeIndex = stack[--stackSize];
        const Node& node = nodes_[nodeIndex];
        if (node.count == 0) {
            const std::uint32_t left = nodeIndex + 1, right = node.first;
            float enterLeft = 0.0f, enterRight = 0.0f;
            const bool hitsLeft =
                hitsBox(nodes_[left].boundsMin, nodes_[left].boundsMax, ray.origin,
                        inverseDirection, minDistance, float(nearest), enterLeft);
            const bool hitsRight =
                hitsBox(nodes_[right].boundsMin, nodes_[right].boundsMax, ray.origin,
                        inverseDirection, minDistance, float(nearest), enterRight);
            if (hitsLeft && hitsRight) {
                const bool leftFirst = enterLeft <= enterRight;
                stack[stackSize++] = leftFirst ? right : left;
                stack[stackSize++] = leftFirst ? left : right;
            } else if (hitsLeft) {
                stack[stackSize++] = left;
            } else if (hitsRight) {
                stack[stackSize++] = right;
            }
            continue;
        }
        // A leaf pushed before a nearer hit was found: its box may now lie beyond it.
        if (found && !hitsBox(node.boundsMin, node.boundsMax, ray.origin, inverseDirection,
                              minDistance, float(nearest), enter)) {
            continue;
        }
        for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
            const std::uint32_t triangle = order_[i];
            const double limit =
                found && i < nearestOrder
                    ? std::nextafter(nearest, std::numeric_limits<double>::infinity())
                    : nearest;
            double distance = 0.0, b1 = 0.0, b2 = 0.0;
            if (!intersectTriangle(ray, corners_[3 * triangle], corners_[3 * triangle + 1],
                                   corners_[3 * triangle + 2], minDistance, limit, distance, b1,
                                   b2)) {
                continue;
            }
            nearest = distance;
            nearestOrder = i;
            hit = {triangle, float(distance), float(b1), float(b2)};
            found = true;
        }
    }
    return found;
}

}  // namespace distile
