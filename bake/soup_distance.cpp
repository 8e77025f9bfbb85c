#include "bake/soup_distance.h"

#include <emmintrin.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <mutex>
#include <numbers>
#include <utility>

namespace distile {

namespace {

constexpr std::uint32_t kLeafTriangles = 2;
/// The winding number's exact near field takes clusters of up to this many triangles whole (its
/// far field is tuned with them).
constexpr std::uint32_t kWindingLeafTriangles = 4;
/// Deeper than any median-split hierarchy of 2^32 triangles needs (two entries per level; four
/// per level of the wide one, which has half as many).
constexpr int kStackSize = 128;
constexpr double kFourPi = 4.0 * std::numbers::pi;
/// Ranges of more triangles than this build their two halves in parallel.
constexpr std::uint32_t kParallelBuildTriangles = 8192;

/// Node counts of the median-split hierarchies of n and n + 1 triangles (n / 2 and n - n / 2 in
/// the children, leaves of at most kLeafTriangles): the children of a node of n triangles hold
/// n / 2 and n / 2 + 1 or n / 2 twice, so both counts follow from those of n / 2.
std::pair<std::uint32_t, std::uint32_t> subtreeNodeCounts(std::uint32_t n) {
    if (n + 1 <= kLeafTriangles) return {1, 1};
    const std::uint32_t half = n / 2;
    const auto [ofHalf, ofHalfPlusOne] = subtreeNodeCounts(half);
    const auto count = [&, ofHalf = ofHalf, ofHalfPlusOne = ofHalfPlusOne](std::uint32_t m) {
        if (m <= kLeafTriangles) return std::uint32_t(1);
        const auto of = [&](std::uint32_t size) { return size == half ? ofHalf : ofHalfPlusOne; };
        return 1 + of(m / 2) + of(m - m / 2);
    };
    return {count(n), count(n + 1)};
}

float roundedDown(double value) {
    const float rounded = float(value);
    return double(rounded) > value ? std::nextafter(rounded, -HUGE_VALF) : rounded;
}
float roundedUp(double value) {
    const float rounded = float(value);
    return double(rounded) < value ? std::nextafter(rounded, HUGE_VALF) : rounded;
}

/// Bound on how much the float box arithmetic of a query at `point` can understate a distance:
/// the point rounded to float moves by at most 2^-24 |p| per axis (sqrt 3 of that in all).
double floatPointError(const glm::dvec3& point) {
    return (std::max({std::abs(point.x), std::abs(point.y), std::abs(point.z)}) + 1.0) * 0x1p-21;
}

/// The squared distance a float box distance must reach for the box to be skipped when the best
/// so far is sqrt(bestSquared): the box arithmetic's relative error (a few 2^-24) and the point's
/// rounding `pointError` are added, so a skipped box is never nearer than the best.
float skipThreshold(double bestSquared, double pointError) {
    const double reach = std::sqrt(bestSquared) + pointError;
    return float(reach * reach * (1.0 + 0x1p-20));
}

/// Where on a triangle its point nearest to a point lies.
enum class TriangleFeature : std::uint8_t {
    Face,
    EdgeAB,
    EdgeBC,
    EdgeCA,
    CornerA,
    CornerB,
    CornerC
};
struct NearestPoint {
    glm::dvec3 point{0.0};
    TriangleFeature feature = TriangleFeature::Face;
};

/// Squared distance from the points (x, y, z) of one vertical line to the triangle abc
/// (Ericson, Real-Time Collision Detection, 5.1.5): the parts of its dot products that do not
/// depend on z are computed once per triangle. Optionally also the nearest point and the part of
/// the triangle it lies on.
class LineTriangleDistance {
  public:
    using Nearest = NearestPoint;
    using Feature = TriangleFeature;

    LineTriangleDistance(const glm::dvec2& xy, const glm::dvec3& a, const glm::dvec3& b,
                         const glm::dvec3& c)
        : xy_(xy), a_(a), b_(b), c_(c), ab_(b - a), ac_(c - a) {
        const glm::dvec2 ap = xy - glm::dvec2(a), bp = xy - glm::dvec2(b), cp = xy - glm::dvec2(c);
        d1_ = ab_.x * ap.x + ab_.y * ap.y;
        d2_ = ac_.x * ap.x + ac_.y * ap.y;
        d3_ = ab_.x * bp.x + ab_.y * bp.y;
        d4_ = ac_.x * bp.x + ac_.y * bp.y;
        d5_ = ab_.x * cp.x + ab_.y * cp.y;
        d6_ = ac_.x * cp.x + ac_.y * cp.y;
    }

    /// The squared distance to (x, y, z); `nearest`, when given, gets the nearest point.
    double operator()(double z, Nearest* nearest = nullptr) const {
        const glm::dvec3 p(xy_.x, xy_.y, z);
        const auto at = [&p, nearest](const glm::dvec3& q, Feature feature) {
            if (nearest) *nearest = {q, feature};
            return glm::dot(p - q, p - q);
        };
        const double apz = z - a_.z;
        const double d1 = d1_ + ab_.z * apz, d2 = d2_ + ac_.z * apz;
        if (d1 <= 0.0 && d2 <= 0.0) return at(a_, Feature::CornerA);
        const double bpz = z - b_.z;
        const double d3 = d3_ + ab_.z * bpz, d4 = d4_ + ac_.z * bpz;
        if (d3 >= 0.0 && d4 <= d3) return at(b_, Feature::CornerB);
        const double vc = d1 * d4 - d3 * d2;
        if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0)
            return at(a_ + ab_ * (d1 / (d1 - d3)), Feature::EdgeAB);
        const double cpz = z - c_.z;
        const double d5 = d5_ + ab_.z * cpz, d6 = d6_ + ac_.z * cpz;
        if (d6 >= 0.0 && d5 <= d6) return at(c_, Feature::CornerC);
        const double vb = d5 * d2 - d1 * d6;
        if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0)
            return at(a_ + ac_ * (d2 / (d2 - d6)), Feature::EdgeCA);
        const double va = d3 * d6 - d5 * d4;
        if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
            return at(b_ + (c_ - b_) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))), Feature::EdgeBC);
        }
        const double denominator = 1.0 / (va + vb + vc);
        if (!std::isfinite(denominator)) {
            // No area (corners that coincide): the nearest corner.
            const double toA = glm::dot(p - a_, p - a_), toB = glm::dot(p - b_, p - b_),
                         toC = glm::dot(p - c_, p - c_);
            if (toA <= toB && toA <= toC) return at(a_, Feature::CornerA);
            return toB <= toC ? at(b_, Feature::CornerB) : at(c_, Feature::CornerC);
        }
        return at(a_ + ab_ * (vb * denominator) + ac_ * (vc * denominator), Feature::Face);
    }

  private:
    glm::dvec2 xy_;
    const glm::dvec3 &a_, &b_, &c_;  ///< the corners, not copied (they outlive this)
    glm::dvec3 ab_, ac_;
    double d1_, d2_, d3_, d4_, d5_, d6_;  ///< x and y parts of the dot products d1 ... d6
};

/// Signed solid angle of the triangle abc seen from p (Van Oosterom and Strackee 1983):
/// positive when p is behind the triangle (on the side its counter-clockwise normal leaves).
double solidAngle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                  const glm::dvec3& c) {
    const glm::dvec3 pa = a - p, pb = b - p, pc = c - p;
    const double la = glm::length(pa), lb = glm::length(pb), lc = glm::length(pc);
    const double determinant = glm::dot(pa, glm::cross(pb, pc));
    const double divisor =
        la * lb * lc + glm::dot(pa, pb) * lc + glm::dot(pb, pc) * la + glm::dot(pc, pa) * lb;
    return 2.0 * std::atan2(determinant, divisor);
}

}  // namespace

SoupDistance::Triangle SoupDistance::asSegmentIfSliver(const Triangle& triangle) {
    const glm::dvec3 ab = triangle.b - triangle.a, ac = triangle.c - triangle.a;
    const glm::dvec3 normal = glm::cross(ab, ac);
    // Collinear to within 1e-10 of the sine of the angle at a (a zero-length edge included).
    if (glm::dot(normal, normal) > 1e-20 * glm::dot(ab, ab) * glm::dot(ac, ac)) return triangle;
    const double ab2 = glm::dot(ab, ab), ac2 = glm::dot(ac, ac);
    const glm::dvec3 bc = triangle.c - triangle.b;
    if (ab2 >= ac2 && ab2 >= glm::dot(bc, bc)) return {triangle.a, triangle.b, triangle.b};
    if (ac2 >= glm::dot(bc, bc)) return {triangle.a, triangle.c, triangle.c};
    return {triangle.b, triangle.c, triangle.c};
}

namespace {

/// The unbalanced edges of `soup` with its corners numbered by `idOf(vertex)` (ids below `ids`,
/// corners with equal ids at `positionOfId(id)`), in the order of their ids.
template <class IdOf, class PositionOfId>
std::vector<UnbalancedEdge> unbalancedEdgesById(const TriangleSoup& soup, std::size_t ids,
                                                const IdOf& idOf,
                                                const PositionOfId& positionOfId) {
    // Each edge under its lower id, with its higher id and +1 where it is used from the lower to
    // the higher, -1 the other way (a counting sort by the lower id): an edge is unbalanced where
    // its uses do not sum to 0.
    std::vector<std::uint32_t> bucketStart(ids + 1, 0);
    const auto forEachEdge = [&](auto&& visit) {
        for (const glm::uvec3& t : soup.triangles) {
            for (int c = 0; c < 3; ++c) {
                const std::uint32_t from = idOf(t[c]), to = idOf(t[(c + 1) % 3]);
                if (from != to) visit(from, to);
            }
        }
    };
    forEachEdge(
        [&](std::uint32_t from, std::uint32_t to) { ++bucketStart[std::min(from, to) + 1]; });
    for (std::size_t id = 0; id < ids; ++id) bucketStart[id + 1] += bucketStart[id];
    // The higher id, its top bit set for uses from the higher id to the lower.
    constexpr std::uint32_t kDownward = 0x80000000u;
    std::vector<std::uint32_t> higher(bucketStart[ids]);
    std::vector<std::uint32_t> filled(bucketStart.begin(), bucketStart.end() - 1);
    forEachEdge([&](std::uint32_t from, std::uint32_t to) {
        higher[filled[std::min(from, to)]++] = from < to ? to : (from | kDownward);
    });
    assert(ids < kDownward);
    // Blocks of ids in parallel, each block's edges in id order.
    constexpr std::size_t kBlockIds = 4096;
    std::vector<std::vector<UnbalancedEdge>> found((ids + kBlockIds - 1) / kBlockIds);
    tbb::parallel_for(std::size_t(0), found.size(), [&](std::size_t block) {
        for (std::size_t id = block * kBlockIds; id < std::min(ids, (block + 1) * kBlockIds);
             ++id) {
            const auto begin = higher.begin() + bucketStart[id];
            const auto end = higher.begin() + bucketStart[id + 1];
            std::sort(begin, end, [](std::uint32_t l, std::uint32_t r) {
                return (l & ~kDownward) < (r & ~kDownward);
            });
            for (auto edge = begin; edge != end;) {
                const std::uint32_t other = *edge & ~kDownward;
                int uses = 0;
                for (; edge != end && (*edge & ~kDownward) == other; ++edge)
                    uses += (*edge & kDownward) ? -1 : 1;
                if (uses != 0)
                    found[block].push_back({positionOfId(std::uint32_t(id)), positionOfId(other)});
            }
        }
    });
    std::vector<UnbalancedEdge> edges;
    for (const std::vector<UnbalancedEdge>& ofBlock : found)
        edges.insert(edges.end(), ofBlock.begin(), ofBlock.end());
    return edges;
}

}  // namespace

std::vector<UnbalancedEdge> unbalancedEdges(const TriangleSoup& soup) {
    // Balanced by vertex index is balanced by position: merging corners at equal positions adds
    // their edges' uses together, and drops zero-length edges with their reverses. So a welded
    // closed mesh needs no position ids.
    if (unbalancedEdgesById(
            soup, soup.positions.size(), [](std::uint32_t vertex) { return vertex; },
            [&soup](std::uint32_t vertex) { return soup.positions[vertex]; })
            .empty())
        return {};
    // Position ids: equal positions (-0.0 and +0.0 alike) get one id, by sorting.
    struct Corner {
        glm::dvec3 position;
        std::uint32_t index;
    };
    std::vector<Corner> byPosition(soup.positions.size());
    for (std::uint32_t v = 0; v < byPosition.size(); ++v) byPosition[v] = {soup.positions[v], v};
    const auto less = [](const glm::dvec3& a, const glm::dvec3& b) {
        return a.x < b.x || (a.x == b.x && (a.y < b.y || (a.y == b.y && a.z < b.z)));
    };
    tbb::parallel_sort(
        byPosition.begin(), byPosition.end(),
        [&less](const Corner& l, const Corner& r) { return less(l.position, r.position); });
    std::vector<std::uint32_t> idOf(soup.positions.size());
    std::vector<glm::dvec3> positionOfId;
    for (std::size_t n = 0; n < byPosition.size(); ++n) {
        if (n == 0 || less(byPosition[n - 1].position, byPosition[n].position))
            positionOfId.push_back(byPosition[n].position);
        idOf[byPosition[n].index] = std::uint32_t(positionOfId.size() - 1);
    }
    return unbalancedEdgesById(
        soup, positionOfId.size(), [&idOf](std::uint32_t vertex) { return idOf[vertex]; },
        [&positionOfId](std::uint32_t id) { return positionOfId[id]; });
}

SoupDistance::SoupDistance(const TriangleSoup& soupTexels, const Size3& tile)
    : tile_(tile), bounds_(boundsOf(soupTexels)) {
    const std::size_t count = soupTexels.triangles.size();
    const auto corners = [&soupTexels](std::size_t n) {
        const glm::uvec3& t = soupTexels.triangles[n];
        return Triangle{soupTexels.positions[t.x], soupTexels.positions[t.y],
                        soupTexels.positions[t.z]};
    };
    UninitializedVector<BuildItem> items(count);
    tbb::parallel_for(std::size_t(0), count, [&](std::size_t n) {
        const Triangle triangle = corners(n);
        items[n] = {glm::vec3(triangle.a + triangle.b + triangle.c), std::uint32_t(n)};
    });
    const std::uint32_t nodeCount = subtreeNodeCounts(std::uint32_t(count)).first;
    nodes_.resize(nodeCount);
    tbb::parallel_invoke([&] { split(0, 0, std::uint32_t(count), items); },
                         [&] { windingPiecewiseConstant_ = unbalancedEdges(soupTexels).empty(); });
    // Leaves hold consecutive triangles: the split's final order.
    triangles_.resize(count);
    tbb::parallel_for(std::size_t(0), count, [&](std::size_t n) {
        triangles_[n] = asSegmentIfSliver(corners(items[n].triangle));
    });
    boxes_.resize(nodeCount);
    boxOf(0);
    wideNodes_.reserve(nodeCount / 3 + 1);
    collapse(0);
}

void SoupDistance::boxOf(std::uint32_t index) {
    const Node& node = nodes_[index];
    if (node.count > 0) {
        glm::dvec3 boxMin(HUGE_VAL), boxMax(-HUGE_VAL);
        for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
            const Triangle& t = triangles_[i];
            boxMin = glm::min(boxMin, glm::min(t.a, glm::min(t.b, t.c)));
            boxMax = glm::max(boxMax, glm::max(t.a, glm::max(t.b, t.c)));
        }
        boxes_[index] = {{roundedDown(boxMin.x), roundedDown(boxMin.y), roundedDown(boxMin.z)},
                         {roundedUp(boxMax.x), roundedUp(boxMax.y), roundedUp(boxMax.z)}};
        return;
    }
    const std::uint32_t first = index + 1, second = node.first;
    if (node.triangleCount > kParallelBuildTriangles) {
        tbb::parallel_invoke([&] { boxOf(first); }, [&] { boxOf(second); });
    } else {
        boxOf(first);
        boxOf(second);
    }
    boxes_[index] = {glm::min(boxes_[first].min, boxes_[second].min),
                     glm::max(boxes_[first].max, boxes_[second].max)};
}

const SoupDistance::Dipole& SoupDistance::dipole(std::uint32_t index) const {
    // Built on the first winding number asked for: meshes signed by crossing counts alone
    // never need them.
    std::call_once(*dipolesBuilt_, [this] {
        dipoles_.resize(nodes_.size());
        // Isolated: while waiting for its own tasks this thread must not take up another query
        // that would wait for this same build.
        tbb::this_task_arena::isolate([this] { dipoleOf(0); });
    });
    return dipoles_[index];
}

void SoupDistance::split(std::uint32_t index, std::uint32_t begin, std::uint32_t end,
                         UninitializedVector<BuildItem>& items) {
    Node node{};
    node.firstTriangle = begin;
    node.triangleCount = end - begin;
    if (end - begin <= kLeafTriangles) {
        node.first = begin;  // the triangles are stored in the final order
        node.count = end - begin;
        nodes_[index] = node;
        return;
    }
    // Median split of the centroids along the longest axis of their box.
    glm::vec3 centroidMin(HUGE_VALF), centroidMax(-HUGE_VALF);
    for (std::uint32_t i = begin; i < end; ++i) {
        centroidMin = glm::min(centroidMin, items[i].cornerSum);
        centroidMax = glm::max(centroidMax, items[i].cornerSum);
    }
    const glm::vec3 spread = centroidMax - centroidMin;
    const int axis =
        spread.x >= spread.y && spread.x >= spread.z ? 0 : (spread.y >= spread.z ? 1 : 2);
    const std::uint32_t middle = begin + (end - begin) / 2;
    std::nth_element(items.begin() + begin, items.begin() + middle, items.begin() + end,
                     [axis](const BuildItem& l, const BuildItem& r) {
                         return l.cornerSum[axis] < r.cornerSum[axis] ||
                                (l.cornerSum[axis] == r.cornerSum[axis] && l.triangle < r.triangle);
                     });
    // Depth-first numbering: the second child follows the first child's subtree.
    const std::uint32_t first = index + 1;
    const std::uint32_t second = index + 1 + subtreeNodeCounts(middle - begin).first;
    node.first = second;
    node.count = 0;
    nodes_[index] = node;
    const auto splitFirst = [&] { split(first, begin, middle, items); };
    const auto splitSecond = [&] { split(second, middle, end, items); };
    if (end - begin > kParallelBuildTriangles) {
        tbb::parallel_invoke(splitFirst, splitSecond);
    } else {
        splitFirst();
        splitSecond();
    }
}

SoupDistance::Bound SoupDistance::dipoleOf(std::uint32_t index) const {
    const Node& node = nodes_[index];
    Bound result{};  // zeros
    Dipole& dipole = result.dipole;
    if (node.count > 0) {
        // The leaf's dipole from its triangles; the radius reaches its farthest corner.
        glm::dvec3 boxMin(HUGE_VAL), boxMax(-HUGE_VAL);
        glm::dvec3 weightedCentre(0.0);
        for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
            const Triangle& t = triangles_[i];
            boxMin = glm::min(boxMin, glm::min(t.a, glm::min(t.b, t.c)));
            boxMax = glm::max(boxMax, glm::max(t.a, glm::max(t.b, t.c)));
            const glm::dvec3 vectorArea = 0.5 * glm::cross(t.b - t.a, t.c - t.a);
            const double triangleArea = glm::length(vectorArea);
            dipole.vectorArea += vectorArea;
            weightedCentre += triangleArea * ((t.a + t.b + t.c) / 3.0);
            result.area += triangleArea;
        }
        dipole.centre = result.area > 0.0 ? weightedCentre / result.area : 0.5 * (boxMin + boxMax);
        double radiusSquared = 0.0;
        for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
            const Triangle& t = triangles_[i];
            for (const glm::dvec3& corner : {t.a, t.b, t.c}) {
                const glm::dvec3 offset = corner - dipole.centre;
                radiusSquared = std::max(radiusSquared, glm::dot(offset, offset));
            }
        }
        dipole.radius = std::sqrt(radiusSquared);
    } else {
        const std::uint32_t first = index + 1, second = node.first;
        Bound one, two;
        const auto boundFirst = [&] { one = dipoleOf(first); };
        const auto boundSecond = [&] { two = dipoleOf(second); };
        if (node.triangleCount > kParallelBuildTriangles) {
            tbb::parallel_invoke(boundFirst, boundSecond);
        } else {
            boundFirst();
            boundSecond();
        }
        // The centre is the children's area-weighted mean, the radius reaches both children's
        // spheres (an upper bound of the farthest corner, which keeps the far field at least as
        // far as the corners require).
        result.area = one.area + two.area;
        dipole.vectorArea = one.dipole.vectorArea + two.dipole.vectorArea;
        dipole.centre =
            result.area > 0.0
                ? (one.area * one.dipole.centre + two.area * two.dipole.centre) / result.area
                : 0.5 * (glm::dvec3(boxes_[index].min) + glm::dvec3(boxes_[index].max));
        dipole.radius =
            std::max(glm::length(one.dipole.centre - dipole.centre) + one.dipole.radius,
                     glm::length(two.dipole.centre - dipole.centre) + two.dipole.radius);
    }
    dipoles_[index] = dipole;
    return result;
}

std::uint32_t SoupDistance::collapse(std::uint32_t binaryIndex) {
    const UninitializedVector<FloatBox>& boxes = boxes_;
    // Up to four descendants: open the inner one with the largest box surface until there are
    // four or only leaves.
    std::array<std::uint32_t, 4> children{};
    int childCount = 0;
    if (nodes_[binaryIndex].count > 0) {
        children[childCount++] = binaryIndex;  // a root that is a leaf (the soup is not empty)
    } else {
        children[childCount++] = binaryIndex + 1;
        children[childCount++] = nodes_[binaryIndex].first;
    }
    const auto surface = [&](std::uint32_t index) {
        const glm::dvec3 extent = glm::dvec3(boxes[index].max) - glm::dvec3(boxes[index].min);
        return extent.x * extent.y + extent.y * extent.z + extent.z * extent.x;
    };
    while (childCount < 4) {
        int widest = -1;
        for (int c = 0; c < childCount; ++c) {
            if (nodes_[children[c]].count == 0 &&
                (widest < 0 || surface(children[c]) > surface(children[widest])))
                widest = c;
        }
        if (widest < 0) break;
        const std::uint32_t opened = children[widest];
        children[widest] = opened + 1;
        children[childCount++] = nodes_[opened].first;
    }
    const std::uint32_t index = std::uint32_t(wideNodes_.size());
    wideNodes_.emplace_back();
    WideNode wide;
    for (int c = 0; c < 4; ++c) {
        wide.minX[c] = wide.minY[c] = wide.minZ[c] = HUGE_VALF;
        wide.maxX[c] = wide.maxY[c] = wide.maxZ[c] = -HUGE_VALF;
        wide.child[c] = 0;
        wide.count[c] = 0;
    }
    for (int c = 0; c < childCount; ++c) {
        const FloatBox& box = boxes[children[c]];
        wide.minX[c] = box.min.x;
        wide.minY[c] = box.min.y;
        wide.minZ[c] = box.min.z;
        wide.maxX[c] = box.max.x;
        wide.maxY[c] = box.max.y;
        wide.maxZ[c] = box.max.z;
        const Node& node = nodes_[children[c]];
        if (node.count > 0) {
            wide.child[c] = node.first;
            wide.count[c] = node.count;
        } else {
            wide.child[c] = collapse(children[c]);
        }
    }
    wideNodes_[index] = wide;
    return index;
}

void SoupDistance::closestSquaredOnLine(const glm::dvec2& xy, std::span<const double> z, int copyX,
                                        int copyY, std::span<LineLaneNearest> lanesNearest) const {
    static_assert(kLineLanes % 4 == 0 && kLineLanes <= 32, "lanes in 4-wide vectors, an int mask");
    const int lanes = int(z.size());
    assert(lanes >= 1 && lanes <= kLineLanes);
    const int vectors = (lanes + 3) / 4;
    // Per lane: its z in float, its squared float threshold and the bound on its point's float
    // rounding; unused lanes have a threshold no box distance is below.
    alignas(16) float laneZ[kLineLanes], threshold[kLineLanes];
    std::array<double, kLineLanes> pointError;
    for (int lane = 0; lane < vectors * 4; ++lane) {
        laneZ[lane] = float(z[lane < lanes ? lane : 0]);
        if (lane >= lanes) {
            threshold[lane] = -1.0f;
            continue;
        }
        pointError[lane] = floatPointError({xy.x, xy.y, z[lane]});
        threshold[lane] = skipThreshold(lanesNearest[lane].bestSquared, pointError[lane]);
    }
    const __m128 px = _mm_set1_ps(float(xy.x)), py = _mm_set1_ps(float(xy.y));
    const __m128 zero = _mm_setzero_ps();
    const auto outside = [&zero](__m128 lo, __m128 hi, __m128 p) {
        const __m128 d = _mm_max_ps(_mm_max_ps(_mm_sub_ps(lo, p), _mm_sub_ps(p, hi)), zero);
        return _mm_mul_ps(d, d);
    };
    std::array<std::uint32_t, kStackSize> stack;
    int size = 0;
    stack[size++] = 0u;
    while (size > 0) {
        const WideNode& node = wideNodes_[stack[--size]];
        // The four children's squared distances in x and y (shared by the lanes), then each
        // lane's with its z: a mask of the lanes each child is nearer to than their best.
        alignas(16) float acrossSquared[4];
        _mm_store_ps(acrossSquared,
                     _mm_add_ps(outside(_mm_load_ps(node.minX), _mm_load_ps(node.maxX), px),
                                outside(_mm_load_ps(node.minY), _mm_load_ps(node.maxY), py)));
        alignas(16) float boxSquared[4][kLineLanes];
        std::array<int, 4> near{};
        for (int c = 0; c < 4; ++c) {
            const __m128 across = _mm_set1_ps(acrossSquared[c]);
            const __m128 lo = _mm_set1_ps(node.minZ[c]), hi = _mm_set1_ps(node.maxZ[c]);
            for (int v = 0; v < vectors; ++v) {
                const __m128 squared =
                    _mm_add_ps(across, outside(lo, hi, _mm_load_ps(laneZ + 4 * v)));
                _mm_store_ps(boxSquared[c] + 4 * v, squared);
                near[c] |= _mm_movemask_ps(_mm_cmplt_ps(squared, _mm_load_ps(threshold + 4 * v)))
                           << (4 * v);
            }
        }
        // Leaves at once, for each lane they are (still) nearer to; inner children pushed with
        // the nearest to the first lane last, so it is visited next: without a hint, that finds
        // a near triangle early. With hints the order barely matters.
        int nearest = -1;
        float nearestSquared = HUGE_VALF;
        for (int c = 0; c < 4; ++c) {
            if (near[c] == 0) continue;
            if (node.count[c] == 0) {
                if (boxSquared[c][0] < nearestSquared) {
                    nearest = c;
                    nearestSquared = boxSquared[c][0];
                }
                continue;
            }
            for (std::uint32_t t = node.child[c]; t < node.child[c] + node.count[c]; ++t) {
                const Triangle& triangle = triangles_[t];
                const LineTriangleDistance distanceSquared(xy, triangle.a, triangle.b, triangle.c);
                for (int todo = near[c]; todo != 0; todo &= todo - 1) {
                    const int lane = std::countr_zero(unsigned(todo));
                    if (!(boxSquared[c][lane] < threshold[lane])) continue;
                    const double squared = distanceSquared(z[lane]);
                    LineLaneNearest& found = lanesNearest[lane];
                    const NearestHint id{t, copyX, copyY};
                    if (squared < found.bestSquared) {
                        found.thirdSquared = found.secondSquared;
                        found.secondSquared = found.bestSquared;
                        found.second = found.best;
                        found.bestSquared = squared;
                        found.best = id;
                        threshold[lane] = skipThreshold(squared, pointError[lane]);
                    } else if (squared <= found.bestSquared * (1.0 + kTieRelative) &&
                               squared < found.thirdSquared && id != found.best &&
                               id != found.second) {
                        // Only ties are kept: one farther now is farther than the final best.
                        // A hint's triangle comes again with its own distance: not a second.
                        if (squared < found.secondSquared) {
                            found.thirdSquared = found.secondSquared;
                            found.secondSquared = squared;
                            found.second = id;
                        } else {
                            found.thirdSquared = squared;
                        }
                    }
                }
            }
        }
        assert(size + 4 <= kStackSize);
        for (int c = 0; c < 4; ++c) {
            if (near[c] != 0 && node.count[c] == 0 && c != nearest) stack[size++] = node.child[c];
        }
        if (nearest >= 0) stack[size++] = node.child[nearest];
    }
}

void SoupDistance::unsignedDistancesOnLine(const glm::dvec2& xy, std::span<const double> z,
                                           double cutoffTexels, std::span<NearestHint> hints,
                                           std::span<double> distances,
                                           std::span<NearestHint> ties) const {
    assert(hints.size() == z.size() && distances.size() == z.size());
    assert(ties.empty() || ties.size() == z.size());
    for (std::size_t first = 0; first < z.size(); first += kLineLanes) {
        const std::size_t lanes = std::min<std::size_t>(kLineLanes, z.size() - first);
        std::array<LineLaneNearest, kLineLanes> nearest;
        double reach = 0.0;
        for (std::size_t lane = 0; lane < lanes; ++lane) {
            // The hint's triangle is one of the candidates the search compares anyway (the same
            // arithmetic on the same shifted point), so starting from it gives the same minimum.
            const NearestHint& hint = hints[first + lane];
            LineLaneNearest& found = nearest[lane];
            found.bestSquared = cutoffTexels * cutoffTexels;
            if (hint.triangle != UINT32_MAX) {
                const Triangle& triangle = triangles_[hint.triangle];
                const double squared =
                    LineTriangleDistance(xy - glm::dvec2(double(hint.copyX) * tile_.width,
                                                         double(hint.copyY) * tile_.height),
                                         triangle.a, triangle.b, triangle.c)(z[first + lane]);
                if (squared < found.bestSquared) {
                    found.bestSquared = squared;
                    found.best = hint;
                }
            }
            reach = std::max(reach, std::sqrt(found.bestSquared));
        }
        // The copies any lane can reach (a lane that cannot reach one finds nothing in it).
        const PeriodicShifts shifts = periodicShifts({xy.x, xy.y, z[first]}, bounds_, tile_, reach);
        for (int n = shifts.yBegin; n <= shifts.yEnd; ++n) {
            for (int m = shifts.xBegin; m <= shifts.xEnd; ++m) {
                const glm::dvec2 shift(double(m) * tile_.width, double(n) * tile_.height);
                closestSquaredOnLine(xy - shift, z.subspan(first, lanes), m, n,
                                     std::span(nearest).first(lanes));
            }
        }
        for (std::size_t lane = 0; lane < lanes; ++lane) {
            const LineLaneNearest& found = nearest[lane];
            distances[first + lane] = std::sqrt(found.bestSquared);
            if (found.best.triangle != UINT32_MAX) hints[first + lane] = found.best;
            if (ties.empty()) continue;
            // Others within kTieRelative of the nearest: the walk compared every triangle that
            // near (its boxes are skipped only beyond the best by more than that).
            const double tieSquared = found.bestSquared * (1.0 + kTieRelative);
            NearestHint& tie = ties[first + lane];
            tie = {};
            if (found.best.triangle == UINT32_MAX || !(found.secondSquared <= tieSquared)) continue;
            tie = found.second;
            if (found.thirdSquared <= tieSquared || tie.triangle == UINT32_MAX)
                tie.triangle = kSeveralTriangles;
        }
    }
}

double SoupDistance::unsignedDistance(const glm::dvec3& texelPosition, double cutoffTexels) const {
    NearestHint none;
    return unsignedDistance(texelPosition, cutoffTexels, none);
}

double SoupDistance::unsignedDistance(const glm::dvec3& texelPosition, double cutoffTexels,
                                      NearestHint& hint) const {
    double distance = 0.0;
    unsignedDistancesOnLine(glm::dvec2(texelPosition), std::span(&texelPosition.z, 1), cutoffTexels,
                            std::span(&hint, 1), std::span(&distance, 1));
    return distance;
}

namespace {

/// How the segment pq meets the triangle abc: Misses only when it provably misses it (both ends
/// strictly on one side of its plane, or its line strictly outside one of its edges), a crossing
/// only when it provably passes through its interior (its line strictly inside all three edges,
/// its ends strictly on either side), with a margin far above the rounding of the triple
/// products.
enum class SegmentMeeting { Misses, FrontToBack, BackToFront, Unclear };

SegmentMeeting segmentMeeting(const glm::dvec3& p, const glm::dvec3& q, const glm::dvec3& a,
                              const glm::dvec3& b, const glm::dvec3& c) {
    constexpr double kRelativeMargin = 1e-9;
    const glm::dvec3 normal = glm::cross(b - a, c - a);
    const double sideP = glm::dot(p - a, normal), sideQ = glm::dot(q - a, normal);
    const double normalLength = glm::length(normal);
    const double marginP = kRelativeMargin * glm::length(p - a) * normalLength;
    const double marginQ = kRelativeMargin * glm::length(q - a) * normalLength;
    if ((sideP > marginP && sideQ > marginQ) || (sideP < -marginP && sideQ < -marginQ))
        return SegmentMeeting::Misses;
    const glm::dvec3 u = q - p, pa = a - p, pb = b - p, pc = c - p;
    const double uLength = glm::length(u);
    const double la = glm::length(pa), lb = glm::length(pb), lc = glm::length(pc);
    const std::array<double, 3> sides{glm::dot(u, glm::cross(pa, pb)),
                                      glm::dot(u, glm::cross(pb, pc)),
                                      glm::dot(u, glm::cross(pc, pa))};
    const std::array<double, 3> margins{kRelativeMargin * uLength * la * lb,
                                        kRelativeMargin * uLength * lb * lc,
                                        kRelativeMargin * uLength * lc * la};
    int positive = 0, negative = 0;
    for (int e = 0; e < 3; ++e) {
        positive += sides[e] > margins[e];
        negative += sides[e] < -margins[e];
    }
    if (positive > 0 && negative > 0) return SegmentMeeting::Misses;  // the line passes beside
    // Through the interior: the line strictly inside all three edges, the ends strictly apart.
    if ((positive == 3 || negative == 3) && sideP > marginP && sideQ < -marginQ)
        return SegmentMeeting::FrontToBack;
    if ((positive == 3 || negative == 3) && sideP < -marginP && sideQ > marginQ)
        return SegmentMeeting::BackToFront;
    return SegmentMeeting::Unclear;
}

/// segmentMeeting for a segment from p parallel to axis `axis` (0, 1, 2) to where that coordinate
/// is `end`: 2D orientation tests of p against the triangle's shadow along the axis, then the
/// plane's coordinate there, each with a margin far above its rounding (1e-12 of the products'
/// magnitudes; the error bound is ~3.3e-16).
SegmentMeeting axisSegmentMeeting(const glm::dvec3& p, int axis, double end, const glm::dvec3& a,
                                  const glm::dvec3& b, const glm::dvec3& c) {
    constexpr double kRelativeMargin = 1e-12;
    // The other two axes in cyclic order, so that a triangle counter-clockwise in them has its
    // normal along +axis.
    const int first = (axis + 1) % 3, second = (axis + 2) % 3;
    // Twice the signed area of (p, u, v) in the shadow, and its margin.
    const auto orientation = [&](const glm::dvec3& u, const glm::dvec3& v, double& margin) {
        const double u1 = u[first] - p[first], u2 = u[second] - p[second];
        const double v1 = v[first] - p[first], v2 = v[second] - p[second];
        margin = kRelativeMargin * (std::abs(u1 * v2) + std::abs(u2 * v1));
        return u1 * v2 - u2 * v1;
    };
    double marginA, marginB, marginC;
    const double weightA = orientation(b, c, marginA);  // opposite a
    const double weightB = orientation(c, a, marginB);
    const double weightC = orientation(a, b, marginC);
    const int positive = (weightA > marginA) + (weightB > marginB) + (weightC > marginC);
    const int negative = (weightA < -marginA) + (weightB < -marginB) + (weightC < -marginC);
    if (positive > 0 && negative > 0) return SegmentMeeting::Misses;     // outside the shadow
    if (positive != 3 && negative != 3) return SegmentMeeting::Unclear;  // on its border
    // Strictly inside the shadow: the plane's coordinate over p, a convex combination of the
    // corners'.
    const double sum = weightA + weightB + weightC;
    const double weightMargins = marginA + marginB + marginC;
    if (!(std::abs(sum) > 2.0 * weightMargins)) return SegmentMeeting::Unclear;
    const double plane = (weightA * a[axis] + weightB * b[axis] + weightC * c[axis]) / sum;
    const double range =
        std::max({a[axis], b[axis], c[axis]}) - std::min({a[axis], b[axis], c[axis]});
    const double planeMargin = weightMargins / (std::abs(sum) - weightMargins) * range +
                               kRelativeMargin * (std::abs(plane) + 1.0);
    const double start = p[axis];
    const bool forward = end >= start;
    const double low = forward ? start : end, high = forward ? end : start;
    if (plane < low - planeMargin || plane > high + planeMargin) return SegmentMeeting::Misses;
    if (!(plane > low + planeMargin && plane < high - planeMargin)) return SegmentMeeting::Unclear;
    // Counter-clockwise in the shadow: the normal points along +axis, so going that way passes
    // from its back to its front.
    return (positive == 3) == forward ? SegmentMeeting::BackToFront : SegmentMeeting::FrontToBack;
}

}  // namespace

template <class Visit>
bool SoupDistance::everyTriangleNearSegment(const glm::dvec3& from, const glm::dvec3& to,
                                            Visit&& visit) const {
    const double pointError = std::max(floatPointError(from), floatPointError(to));
    const glm::dvec3 lo = glm::min(from, to) - pointError, hi = glm::max(from, to) + pointError;
    const __m128 loX = _mm_set1_ps(roundedDown(lo.x)), loY = _mm_set1_ps(roundedDown(lo.y)),
                 loZ = _mm_set1_ps(roundedDown(lo.z));
    const __m128 hiX = _mm_set1_ps(roundedUp(hi.x)), hiY = _mm_set1_ps(roundedUp(hi.y)),
                 hiZ = _mm_set1_ps(roundedUp(hi.z));
    std::array<std::uint32_t, kStackSize> stack;
    int size = 0;
    stack[size++] = 0;
    while (size > 0) {
        const WideNode& node = wideNodes_[stack[--size]];
        const __m128 overlapX = _mm_and_ps(_mm_cmple_ps(_mm_load_ps(node.minX), hiX),
                                           _mm_cmpge_ps(_mm_load_ps(node.maxX), loX));
        const __m128 overlapY = _mm_and_ps(_mm_cmple_ps(_mm_load_ps(node.minY), hiY),
                                           _mm_cmpge_ps(_mm_load_ps(node.maxY), loY));
        const __m128 overlapZ = _mm_and_ps(_mm_cmple_ps(_mm_load_ps(node.minZ), hiZ),
                                           _mm_cmpge_ps(_mm_load_ps(node.maxZ), loZ));
        const int overlaps = _mm_movemask_ps(_mm_and_ps(_mm_and_ps(overlapX, overlapY), overlapZ));
        for (int c = 0; c < 4; ++c) {
            if (!(overlaps & (1 << c))) continue;
            if (node.count[c] == 0) {
                assert(size < kStackSize);
                stack[size++] = node.child[c];
                continue;
            }
            for (std::uint32_t t = node.child[c]; t < node.child[c] + node.count[c]; ++t) {
                if (!visit(triangles_[t])) return false;
            }
        }
    }
    return true;
}

std::optional<int> SoupDistance::windingNumberByCrossings(const glm::dvec3& texelPosition) const {
    assert(windingPiecewiseConstant_);
    // Out of the bounds by the nearer way, up or down, where the winding number is 0: it drops
    // by 1 across a triangle passed from back to front and rises by 1 the other way.
    const bool up = bounds_.max.z - texelPosition.z <= texelPosition.z - bounds_.min.z;
    const double endZ = up ? bounds_.max.z + 1.0 : bounds_.min.z - 1.0;
    const PeriodicShifts shifts = periodicShifts(texelPosition, bounds_, tile_, 0.0);
    int winding = 0;
    for (int row = shifts.yBegin; row <= shifts.yEnd; ++row) {
        for (int column = shifts.xBegin; column <= shifts.xEnd; ++column) {
            const glm::dvec3 from = texelPosition - glm::dvec3(double(column) * tile_.width,
                                                               double(row) * tile_.height, 0.0);
            const bool clear = everyTriangleNearSegment(
                from, glm::dvec3(from.x, from.y, endZ), [&](const Triangle& t) {
                    switch (axisSegmentMeeting(from, 2, endZ, t.a, t.b, t.c)) {
                        case SegmentMeeting::Misses:
                            return true;
                        case SegmentMeeting::BackToFront:
                            ++winding;
                            return true;
                        case SegmentMeeting::FrontToBack:
                            --winding;
                            return true;
                        case SegmentMeeting::Unclear:
                            return false;
                    }
                    return false;
                });
            if (!clear) return std::nullopt;
        }
    }
    return winding;
}

bool SoupDistance::facesOutsideAtCentroid(const glm::dvec3& a, const glm::dvec3& b,
                                          const glm::dvec3& c) const {
    const glm::dvec3 normal = glm::cross(b - a, c - a);
    const double area = glm::length(normal);
    if (!(area > 0.0)) return true;  // no sides; changes no distance
    const double longest = std::max({glm::length(b - a), glm::length(c - b), glm::length(a - c)});
    const glm::dvec3 front = (a + b + c) / 3.0 + (1e-5 * longest / area) * normal;
    return std::abs(countedWindingNumber(front)) < 0.5;
}

bool SoupDistance::facesOutsideAtCentroid(std::uint32_t triangle) const {
    const Triangle& t = triangles_[triangle];
    return facesOutsideAtCentroid(t.a, t.b, t.c);
}

double SoupDistance::countedWindingNumber(const glm::dvec3& texelPosition) const {
    if (windingPiecewiseConstant_) {
        if (const std::optional<int> crossings = windingNumberByCrossings(texelPosition))
            return double(*crossings);
    }
    return windingNumber(texelPosition);
}

int SoupDistance::sideOfNearestPoint(const glm::dvec3& texelPosition, const NearestHint& nearest,
                                     const NearestHint& tie) const {
    assert(nearest.triangle < triangles_.size());
    if (tie.triangle == kSeveralTriangles) return 0;
    const glm::dvec3 shift(double(nearest.copyX) * tile_.width,
                           double(nearest.copyY) * tile_.height, 0.0);
    const Triangle& t = triangles_[nearest.triangle];
    NearestPoint found;
    const glm::dvec3 p = texelPosition - shift;
    LineTriangleDistance(glm::dvec2(p), t.a, t.b, t.c)(p.z, &found);
    const glm::dvec3 away = p - found.point;
    // The side of the surface p lies on, along `normal`: clear when within 60 degrees of it.
    const auto side = [&away](const glm::dvec3& normal) {
        const double along = glm::dot(away, normal);
        return along * along > 0.25 * glm::dot(away, away) * glm::dot(normal, normal)
                   ? (along > 0.0 ? 1 : -1)
                   : 0;
    };
    const glm::dvec3 normal = glm::cross(t.b - t.a, t.c - t.a);
    if (!(glm::dot(normal, normal) > 0.0)) return 0;  // a sliver, measured as a segment
    if (found.feature == TriangleFeature::Face) {
        // Any other triangle through that point would be as near: a tie.
        if (tie.triangle != UINT32_MAX) return 0;
        return side(normal);
    } else {
        // On an edge: its one neighbour must be the tie, using the edge the other way round;
        // then the angle-weighted normal there, the sum of theirs, tells the sides apart
        // (Baerentzen and Aanaes 2005). A corner's fan is not known here.
        if (tie.triangle >= triangles_.size()) return 0;
        glm::dvec3 from, to;
        switch (found.feature) {
            case TriangleFeature::EdgeAB:
                from = t.a, to = t.b;
                break;
            case TriangleFeature::EdgeBC:
                from = t.b, to = t.c;
                break;
            case TriangleFeature::EdgeCA:
                from = t.c, to = t.a;
                break;
            default:
                return 0;
        }
        const Triangle& u = triangles_[tie.triangle];
        const glm::dvec3 toTie(double(tie.copyX - nearest.copyX) * tile_.width,
                               double(tie.copyY - nearest.copyY) * tile_.height, 0.0);
        const std::array<glm::dvec3, 3> corners = {u.a + toTie, u.b + toTie, u.c + toTie};
        bool reversed = false;
        for (int k = 0; k < 3; ++k)
            reversed = reversed || (corners[k] == to && corners[(k + 1) % 3] == from);
        if (!reversed) return 0;
        const glm::dvec3 tieNormal = glm::cross(corners[1] - corners[0], corners[2] - corners[0]);
        if (!(glm::dot(tieNormal, tieNormal) > 0.0)) return 0;
        return side(glm::normalize(normal) + glm::normalize(tieNormal));
    }
}

bool SoupDistance::segmentTouchesNoTriangleOfCopy(const glm::dvec3& from,
                                                  const glm::dvec3& to) const {
    // Parallel to an axis (as between neighbouring voxels): the cheaper test along it.
    const int differing = (from.x != to.x) + (from.y != to.y) + (from.z != to.z);
    const int axis = from.x != to.x ? 0 : (from.y != to.y ? 1 : 2);
    return everyTriangleNearSegment(from, to, [&](const Triangle& triangle) {
        const SegmentMeeting meeting =
            differing <= 1
                ? axisSegmentMeeting(from, axis, to[axis], triangle.a, triangle.b, triangle.c)
                : segmentMeeting(from, to, triangle.a, triangle.b, triangle.c);
        return meeting == SegmentMeeting::Misses;
    });
}

bool SoupDistance::segmentTouchesNoTriangle(const glm::dvec3& from, const glm::dvec3& to) const {
    const glm::dvec3 middle = 0.5 * (from + to);
    const PeriodicShifts shifts =
        periodicShifts(middle, bounds_, tile_, 0.5 * glm::length(to - from) + 1e-6);
    for (int n = shifts.yBegin; n <= shifts.yEnd; ++n) {
        for (int m = shifts.xBegin; m <= shifts.xEnd; ++m) {
            const glm::dvec3 shift(double(m) * tile_.width, double(n) * tile_.height, 0.0);
            if (!segmentTouchesNoTriangleOfCopy(from - shift, to - shift)) return false;
        }
    }
    return true;
}

double SoupDistance::windingNumberOfCopy(const glm::dvec3& point, double farFieldRatio) const {
    std::array<std::uint32_t, kStackSize> stack;
    int size = 0;
    stack[size++] = 0;
    double solidAngles = 0.0;
    while (size > 0) {
        const std::uint32_t index = stack[--size];
        const Node& node = nodes_[index];
        const Dipole& dipole = this->dipole(index);
        const glm::dvec3 toCentre = dipole.centre - point;
        const double distanceSquared = glm::dot(toCentre, toCentre);
        if (distanceSquared > farFieldRatio * farFieldRatio * dipole.radius * dipole.radius) {
            solidAngles += glm::dot(toCentre, dipole.vectorArea) /
                           (distanceSquared * std::sqrt(distanceSquared));
            continue;
        }
        if (node.triangleCount <= kWindingLeafTriangles) {
            for (std::uint32_t t = node.firstTriangle; t < node.firstTriangle + node.triangleCount;
                 ++t) {
                const Triangle& triangle = triangles_[t];
                solidAngles += solidAngle(point, triangle.a, triangle.b, triangle.c);
            }
            continue;
        }
        assert(size + 2 <= kStackSize);
        stack[size++] = node.first;
        stack[size++] = index + 1;
    }
    return solidAngles / kFourPi;
}

double SoupDistance::windingNumber(const glm::dvec3& texelPosition) const {
    const PeriodicShifts shifts = periodicShifts(texelPosition, bounds_, tile_, 0.0);
    const auto sum = [&](double farFieldRatio) {
        double winding = 0.0;
        for (int n = shifts.yBegin; n <= shifts.yEnd; ++n) {
            for (int m = shifts.xBegin; m <= shifts.xEnd; ++m) {
                const glm::dvec3 shift(double(m) * tile_.width, double(n) * tile_.height, 0.0);
                winding += windingNumberOfCopy(texelPosition - shift, farFieldRatio);
            }
        }
        return winding;
    };
    const double winding = sum(kWindingFarFieldRatio);
    if (std::abs(winding - 0.5) >= kWindingRecheckMargin) return winding;
    return sum(kWindingRecheckRatio);
}

double SoupDistance::signedDistance(const glm::dvec3& texelPosition, double cutoffTexels) const {
    const double distance = unsignedDistance(texelPosition, cutoffTexels);
    return windingNumber(texelPosition) > 0.5 ? -distance : distance;
}

}  // namespace distile
