#include "render/bvh.h"

#include <immintrin.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>

namespace distile {

namespace {

constexpr std::uint32_t kLeafSize = 4;
constexpr int kMaxDepth = 48;
/// Nodes over at least this many triangles, and no deeper than kParallelBuildDepth, build their
/// two sides in parallel (deeper, 2^depth tasks keep any machine busy, and each level copies the
/// right sides' nodes once more).
constexpr std::uint32_t kParallelBuildTriangles = 4096;
constexpr int kParallelBuildDepth = 6;

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

/// 1 / direction for hitsBox, each component at least 1e-30 in magnitude first (its sign kept):
/// with an infinite inverse, a ray that does not move along an axis and starts exactly on a box
/// face across it (a ray in the plane of a grid line of a mesh) made 0 x infinity = NaN and missed
/// the box, and every triangle in it. Within the slab, 0 x 1e30 = 0 keeps it; outside, the travel
/// is still out of reach (1e30 x the gap, or infinity).
glm::vec3 slabInverse(const glm::vec3& direction) {
    glm::vec3 inverse;
    for (int axis = 0; axis < 3; ++axis) {
        const float along = direction[axis];
        inverse[axis] = 1.0f / (std::abs(along) < 1e-30f ? std::copysign(1e-30f, along) : along);
    }
    return inverse;
}

}  // namespace

TriangleBvh::TriangleBvh(std::vector<glm::vec3> corners) : corners_(std::move(corners)) {
    const auto count = std::uint32_t(corners_.size() / 3);
    order_.resize(count);
    for (std::uint32_t i = 0; i < count; ++i) order_[i] = i;
    if (count > 0) {
        std::vector<TriangleBox> boxes(count);
        for (std::uint32_t i = 0; i < count; ++i) {
            TriangleBox& box = boxes[i];
            box.low = glm::vec3(std::numeric_limits<float>::max());
            box.high = glm::vec3(-std::numeric_limits<float>::max());
            for (int corner = 0; corner < 3; ++corner) {
                box.low = glm::min(box.low, corners_[3 * i + corner]);
                box.high = glm::max(box.high, corners_[3 * i + corner]);
            }
            box.centroid = centroid(corners_, i);
        }
        nodes_.reserve(2 * count);
        build(boxes, 0, count, 0, nodes_);
    }
    // The corners in leaf order, as the ray tests take them: a leaf's triangles side by side.
    std::vector<glm::vec3> leafCorners(corners_.size());
    for (std::uint32_t i = 0; i < count; ++i)
        for (int corner = 0; corner < 3; ++corner)
            leafCorners[3 * i + corner] = corners_[3 * order_[i] + corner];
    corners_ = std::move(leafCorners);
}

std::uint32_t TriangleBvh::build(const std::vector<TriangleBox>& boxes, std::uint32_t first,
                                 std::uint32_t count, int depth, std::vector<Node>& nodes) {
    const auto nodeIndex = std::uint32_t(nodes.size());
    nodes.push_back({});
    glm::vec3 boundsMin(std::numeric_limits<float>::max());
    glm::vec3 boundsMax(-std::numeric_limits<float>::max());
    glm::vec3 centroidMin = boundsMin;
    glm::vec3 centroidMax = boundsMax;
    for (std::uint32_t i = first; i < first + count; ++i) {
        const TriangleBox& box = boxes[order_[i]];
        boundsMin = glm::min(boundsMin, box.low);
        boundsMax = glm::max(boundsMax, box.high);
        centroidMin = glm::min(centroidMin, box.centroid);
        centroidMax = glm::max(centroidMax, box.centroid);
    }
    nodes[nodeIndex].boundsMin = boundsMin;
    nodes[nodeIndex].boundsMax = boundsMax;
    const glm::vec3 extent = centroidMax - centroidMin;
    if (count <= kLeafSize || depth >= kMaxDepth ||
        glm::max(extent.x, glm::max(extent.y, extent.z)) <= 0.0f) {
        nodes[nodeIndex].first = first;
        nodes[nodeIndex].count = count;
        return nodeIndex;
    }
    // The split of least cost by the surface area heuristic over kBins bins of the centroids
    // along each axis (Wald 2007): the two sides' box areas times their triangle counts. A few
    // triangles much larger than the rest (a floor under a finely meshed object) are split off
    // near the root; a median split would put them in leaves among small ones, and every box
    // above those leaves would span the floor.
    constexpr int kBins = 16;
    struct Bin {
        std::uint32_t count = 0;
        glm::vec3 boundsMin{std::numeric_limits<float>::max()};
        glm::vec3 boundsMax{-std::numeric_limits<float>::max()};
    };
    const auto halfArea = [](const glm::vec3& low, const glm::vec3& high) {
        const glm::vec3 size = glm::max(high - low, glm::vec3(0.0f));
        return double(size.x) * size.y + double(size.y) * size.z + double(size.z) * size.x;
    };
    const auto binOf = [&](std::uint32_t triangle, int axis) {
        const float position = (boxes[triangle].centroid[axis] - centroidMin[axis]) / extent[axis];
        return std::clamp(int(position * float(kBins)), 0, kBins - 1);
    };
    double bestCost = std::numeric_limits<double>::infinity();
    int bestAxis = -1, bestBin = 0;
    for (int axis = 0; axis < 3; ++axis) {
        if (!(extent[axis] > 0.0f)) continue;
        Bin bins[kBins];
        for (std::uint32_t i = first; i < first + count; ++i) {
            Bin& bin = bins[binOf(order_[i], axis)];
            ++bin.count;
            bin.boundsMin = glm::min(bin.boundsMin, boxes[order_[i]].low);
            bin.boundsMax = glm::max(bin.boundsMax, boxes[order_[i]].high);
        }
        // Costs of splitting after bin k: the left side's from a sweep up, the right's down.
        double leftCost[kBins];
        Bin left;
        for (int k = 0; k < kBins - 1; ++k) {
            left.count += bins[k].count;
            left.boundsMin = glm::min(left.boundsMin, bins[k].boundsMin);
            left.boundsMax = glm::max(left.boundsMax, bins[k].boundsMax);
            leftCost[k] =
                left.count == 0 ? 0.0 : halfArea(left.boundsMin, left.boundsMax) * left.count;
        }
        Bin right;
        for (int k = kBins - 1; k > 0; --k) {
            right.count += bins[k].count;
            right.boundsMin = glm::min(right.boundsMin, bins[k].boundsMin);
            right.boundsMax = glm::max(right.boundsMax, bins[k].boundsMax);
            if (right.count == 0 || right.count == count) continue;
            const double cost =
                leftCost[k - 1] + halfArea(right.boundsMin, right.boundsMax) * right.count;
            if (cost < bestCost) {
                bestCost = cost;
                bestAxis = axis;
                bestBin = k - 1;
            }
        }
    }
    std::uint32_t half = count / 2;
    if (bestAxis >= 0) {
        const auto middle = std::partition(
            order_.begin() + first, order_.begin() + first + count,
            [&](std::uint32_t triangle) { return binOf(triangle, bestAxis) <= bestBin; });
        half = std::uint32_t(middle - (order_.begin() + first));
    } else {
        // Every centroid in one bin along every axis: the median along the longest.
        const int axis =
            extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
        std::nth_element(order_.begin() + first, order_.begin() + first + half,
                         order_.begin() + first + count, [&](std::uint32_t a, std::uint32_t b) {
                             return boxes[a].centroid[axis] < boxes[b].centroid[axis];
                         });
    }
    std::uint32_t right = 0;
    if (count < kParallelBuildTriangles || depth >= kParallelBuildDepth) {
        build(boxes, first, half, depth + 1, nodes);
        right = build(boxes, first + half, count - half, depth + 1, nodes);
    } else {
        // The two sides at once (their triangles are disjoint ranges of order_): the left one
        // into `nodes` after this node, the right one into nodes of its own, appended after the
        // left's with their child indices moved. The nodes come out in the same order as one
        // after the other, so the tree is the same on any number of threads.
        std::vector<Node> rightNodes;
        tbb::parallel_invoke([&] { build(boxes, first, half, depth + 1, nodes); },
                             [&] {
                                 rightNodes.reserve(2 * std::size_t(count - half));
                                 build(boxes, first + half, count - half, depth + 1, rightNodes);
                             });
        right = std::uint32_t(nodes.size());
        for (Node node : rightNodes) {
            if (node.count == 0) node.first += right;  // an inner node's right child
            nodes.push_back(node);
        }
    }
    nodes[nodeIndex].first = right;
    nodes[nodeIndex].count = 0;
    return nodeIndex;
}

bool TriangleBvh::intersect(const Ray& ray, float minDistance, float maxDistance,
                            TriangleHit& hit) const {
    if (nodes_.empty()) return false;
    const glm::vec3 inverseDirection = slabInverse(ray.direction);
    bool found = false;
    double nearest = maxDistance;
    // Among hits at exactly the same distance (a ray through an edge two triangles share) the
    // triangle of the lowest index wins, whatever the tree and the order its nodes are visited in.
    std::uint32_t nearestTriangle = 0;
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
                found && triangle < nearestTriangle
                    ? std::nextafter(nearest, std::numeric_limits<double>::infinity())
                    : nearest;
            double distance = 0.0, b1 = 0.0, b2 = 0.0;
            if (!intersectTriangle(ray, corners_[3 * i], corners_[3 * i + 1], corners_[3 * i + 2],
                                   minDistance, limit, distance, b1, b2)) {
                continue;
            }
            nearest = distance;
            nearestTriangle = triangle;
            hit = {triangle, float(distance), b1, b2};
            found = true;
        }
    }
    return found;
}

void TriangleBvh::intersectParallel(std::span<const Ray> rays, std::span<const float> minDistances,
                                    float maxDistance, std::span<TriangleHit> hits,
                                    std::span<bool> found) const {
    constexpr int kLanes = int(kPacketRays);
    const int count = int(rays.size());
    for (int k = 0; k < count; ++k) found[std::size_t(k)] = false;
    if (nodes_.empty() || count == 0) return;
    const glm::vec3 inverseDirection = slabInverse(rays[0].direction);
    // The lanes' state, one array per quantity (the box tests run across lanes). Lanes past
    // `count` start with an empty interval and never hit.
    alignas(64) float originX[kLanes], originY[kLanes], originZ[kLanes];
    alignas(64) float lowest[kLanes], highest[kLanes];
    double nearest[kLanes];
    std::uint32_t nearestTriangle[kLanes];
    for (int k = 0; k < kLanes; ++k) {
        const Ray& ray = rays[std::size_t(std::min(k, count - 1))];
        originX[k] = ray.origin.x;
        originY[k] = ray.origin.y;
        originZ[k] = ray.origin.z;
        lowest[k] = k < count ? minDistances[std::size_t(k)] : 1.0f;
        highest[k] = k < count ? maxDistance : 0.0f;
        nearest[k] = maxDistance;
        nearestTriangle[k] = 0;
    }
    // hitsBox for every lane: the lanes whose ray enters the box before its nearest hit, and
    // where each enters. Four lanes per SSE register; std::min(a, b) is _mm_min_ps(b, a) and
    // std::max(a, b) _mm_max_ps(b, a), so every lane computes exactly what hitsBox does.
    const auto boxLanes = [&](const Node& node, float enter[kLanes]) {
        const auto min = [](__m128 a, __m128 b) { return _mm_min_ps(b, a); };
        const auto max = [](__m128 a, __m128 b) { return _mm_max_ps(b, a); };
        const __m128 lowX = _mm_set1_ps(node.boundsMin.x), highX = _mm_set1_ps(node.boundsMax.x);
        const __m128 lowY = _mm_set1_ps(node.boundsMin.y), highY = _mm_set1_ps(node.boundsMax.y);
        const __m128 lowZ = _mm_set1_ps(node.boundsMin.z), highZ = _mm_set1_ps(node.boundsMax.z);
        const __m128 inverseX = _mm_set1_ps(inverseDirection.x);
        const __m128 inverseY = _mm_set1_ps(inverseDirection.y);
        const __m128 inverseZ = _mm_set1_ps(inverseDirection.z);
        std::uint32_t mask = 0;
        for (int k = 0; k < kLanes; k += 4) {
            const __m128 x = _mm_load_ps(originX + k), y = _mm_load_ps(originY + k),
                         z = _mm_load_ps(originZ + k);
            const __m128 x0 = _mm_mul_ps(_mm_sub_ps(lowX, x), inverseX);
            const __m128 x1 = _mm_mul_ps(_mm_sub_ps(highX, x), inverseX);
            const __m128 y0 = _mm_mul_ps(_mm_sub_ps(lowY, y), inverseY);
            const __m128 y1 = _mm_mul_ps(_mm_sub_ps(highY, y), inverseY);
            const __m128 z0 = _mm_mul_ps(_mm_sub_ps(lowZ, z), inverseZ);
            const __m128 z1 = _mm_mul_ps(_mm_sub_ps(highZ, z), inverseZ);
            const __m128 in =
                max(max(max(min(x0, x1), min(y0, y1)), min(z0, z1)), _mm_load_ps(lowest + k));
            const __m128 out = _mm_add_ps(
                _mm_mul_ps(
                    min(min(min(max(x0, x1), max(y0, y1)), max(z0, z1)), _mm_load_ps(highest + k)),
                    _mm_set1_ps(1.00001f)),
                _mm_set1_ps(1e-7f));
            _mm_store_ps(enter + k, in);
            mask |= std::uint32_t(_mm_movemask_ps(_mm_cmple_ps(in, out))) << k;
        }
        return mask;
    };
    alignas(16) float enter[kLanes], enterLeft[kLanes], enterRight[kLanes];
    std::uint32_t rootLanes = boxLanes(nodes_[0], enter);
    if (rootLanes == 0) return;
    struct Entry {
        std::uint32_t node, lanes;
    };
    Entry stack[2 * kMaxDepth + 2];
    int stackSize = 0;
    stack[stackSize++] = {0, rootLanes};
    std::uint32_t foundLanes = 0;
    while (stackSize > 0) {
        const Entry entry = stack[--stackSize];
        const Node& node = nodes_[entry.node];
        if (node.count == 0) {
            const std::uint32_t left = entry.node + 1, right = node.first;
            const std::uint32_t leftLanes = boxLanes(nodes_[left], enterLeft) & entry.lanes;
            const std::uint32_t rightLanes = boxLanes(nodes_[right], enterRight) & entry.lanes;
            if (leftLanes && rightLanes) {
                // Nearer child first for most of the lanes that enter both.
                float lead = 0.0f;
                for (int k = 0; k < kLanes; ++k)
                    if ((leftLanes & rightLanes) >> k & 1u) lead += enterLeft[k] - enterRight[k];
                const bool leftFirst = lead <= 0.0f;
                stack[stackSize++] = leftFirst ? Entry{right, rightLanes} : Entry{left, leftLanes};
                stack[stackSize++] = leftFirst ? Entry{left, leftLanes} : Entry{right, rightLanes};
            } else if (leftLanes) {
                stack[stackSize++] = {left, leftLanes};
            } else if (rightLanes) {
                stack[stackSize++] = {right, rightLanes};
            }
            continue;
        }
        std::uint32_t lanes = entry.lanes;
        // Lanes that found a nearer hit since the leaf was pushed: its box may lie beyond it.
        if (lanes & foundLanes) lanes &= boxLanes(node, enter) | ~foundLanes;
        if (lanes == 0) continue;
        // Triangle by triangle, each lane's in the order intersect takes them.
        for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
            const std::uint32_t triangle = order_[i];
            const DoubleTriangle corners(corners_[3 * i], corners_[3 * i + 1], corners_[3 * i + 2]);
            const TriangleAlong along(rays[0].direction, corners);
            for (std::uint32_t pending = lanes; pending != 0; pending &= pending - 1) {
                const int k = std::countr_zero(pending);
                const double limit =
                    (foundLanes >> k & 1u) && triangle < nearestTriangle[k]
                        ? std::nextafter(nearest[k], std::numeric_limits<double>::infinity())
                        : nearest[k];
                double distance = 0.0, b1 = 0.0, b2 = 0.0;
                if (!along.intersect(rays[std::size_t(k)].origin, lowest[k], limit, distance, b1,
                                     b2)) {
                    continue;
                }
                nearest[k] = distance;
                nearestTriangle[k] = triangle;
                highest[k] = float(distance);
                hits[std::size_t(k)] = {triangle, float(distance), b1, b2};
                foundLanes |= 1u << k;
            }
        }
    }
    for (int k = 0; k < count; ++k) found[std::size_t(k)] = foundLanes >> k & 1u;
}

}  // namespace distile
