#include "bake/soup_distance.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <numbers>
#include <unordered_map>
#include <utility>

namespace distile {

namespace {

constexpr std::uint32_t kLeafTriangles = 4;
/// Deeper than any median-split hierarchy of 2^32 triangles needs (two entries per level).
constexpr int kStackSize = 128;
constexpr double kFourPi = 4.0 * std::numbers::pi;

double boxDistanceSquared(const glm::dvec3& p, const glm::dvec3& lo, const glm::dvec3& hi) {
    const glm::dvec3 outside = glm::max(glm::max(lo - p, p - hi), glm::dvec3(0.0));
    return glm::dot(outside, outside);
}

/// Squared distance from p to the triangle abc (Ericson, Real-Time Collision Detection, 5.1.5).
double triangleDistanceSquared(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                               const glm::dvec3& c) {
    const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    const auto squared = [&p](const glm::dvec3& q) { return glm::dot(p - q, p - q); };
    if (d1 <= 0.0 && d2 <= 0.0) return squared(a);
    const glm::dvec3 bp = p - b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return squared(b);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return squared(a + ab * (d1 / (d1 - d3)));
    const glm::dvec3 cp = p - c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return squared(c);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return squared(a + ac * (d2 / (d2 - d6)));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        return squared(b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    const double denominator = 1.0 / (va + vb + vc);
    if (!std::isfinite(denominator)) {  // degenerate (zero-area) triangle: nearest corner
        return std::min({squared(a), squared(b), squared(c)});
    }
    return squared(a + ab * (vb * denominator) + ac * (vc * denominator));
}

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

struct PositionHash {
    std::size_t operator()(const glm::dvec3& p) const {
        const std::hash<double> hash;
        return hash(p.x) ^ (hash(p.y) * 0x9e3779b97f4a7c15ull) ^
               (hash(p.z) * 0xc2b2ae3d27d4eb4full);
    }
};

/// Whether every edge, its corners matched by exact position, is used as often in each
/// direction.
bool edgeUsesCancel(const TriangleSoup& soup) {
    std::unordered_map<glm::dvec3, std::uint32_t, PositionHash> ids;
    ids.reserve(soup.positions.size());
    std::vector<std::uint32_t> idOf(soup.positions.size());
    for (std::size_t v = 0; v < soup.positions.size(); ++v) {
        // -0.0 and +0.0 are one position.
        const glm::dvec3 p = soup.positions[v] + glm::dvec3(0.0);
        idOf[v] = ids.try_emplace(p, std::uint32_t(ids.size())).first->second;
    }
    std::unordered_map<std::uint64_t, std::int64_t> netUses;
    netUses.reserve(3 * soup.triangles.size());
    for (const glm::uvec3& t : soup.triangles) {
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t from = idOf[t[c]], to = idOf[t[(c + 1) % 3]];
            if (from == to) continue;
            const std::uint64_t key =
                (std::uint64_t(std::min(from, to)) << 32) | std::max(from, to);
            netUses[key] += from < to ? 1 : -1;
        }
    }
    return std::all_of(netUses.begin(), netUses.end(),
                       [](const auto& entry) { return entry.second == 0; });
}

}  // namespace

SoupDistance::SoupDistance(const TriangleSoup& soupTexels, const Size3& tile)
    : tile_(tile), bounds_(boundsOf(soupTexels)) {
    std::vector<Triangle> input;
    input.reserve(soupTexels.triangles.size());
    for (const glm::uvec3& t : soupTexels.triangles) {
        input.push_back(
            {soupTexels.positions[t.x], soupTexels.positions[t.y], soupTexels.positions[t.z]});
    }
    std::vector<std::uint32_t> order(input.size());
    for (std::uint32_t i = 0; i < order.size(); ++i) order[i] = i;
    triangles_.reserve(input.size());
    nodes_.reserve(2 * (input.size() / kLeafTriangles + 1));
    dipoles_.reserve(nodes_.capacity());
    build(order, 0, std::uint32_t(order.size()), input);
    windingPiecewiseConstant_ = edgeUsesCancel(soupTexels);
}

std::uint32_t SoupDistance::build(std::vector<std::uint32_t>& order, std::uint32_t begin,
                                  std::uint32_t end, const std::vector<Triangle>& input) {
    const std::uint32_t index = std::uint32_t(nodes_.size());
    nodes_.emplace_back();
    dipoles_.emplace_back();
    Node node;
    Dipole dipole;
    node.boxMin = glm::dvec3(HUGE_VAL);
    node.boxMax = glm::dvec3(-HUGE_VAL);
    glm::dvec3 centroidMin(HUGE_VAL), centroidMax(-HUGE_VAL), weightedCentre(0.0);
    double area = 0.0;
    for (std::uint32_t i = begin; i < end; ++i) {
        const Triangle& t = input[order[i]];
        node.boxMin = glm::min(node.boxMin, glm::min(t.a, glm::min(t.b, t.c)));
        node.boxMax = glm::max(node.boxMax, glm::max(t.a, glm::max(t.b, t.c)));
        const glm::dvec3 centroid = (t.a + t.b + t.c) / 3.0;
        centroidMin = glm::min(centroidMin, centroid);
        centroidMax = glm::max(centroidMax, centroid);
        const glm::dvec3 vectorArea = 0.5 * glm::cross(t.b - t.a, t.c - t.a);
        const double triangleArea = glm::length(vectorArea);
        dipole.vectorArea += vectorArea;
        weightedCentre += triangleArea * centroid;
        area += triangleArea;
    }
    dipole.centre = area > 0.0 ? weightedCentre / area : 0.5 * (node.boxMin + node.boxMax);
    for (std::uint32_t i = begin; i < end; ++i) {
        const Triangle& t = input[order[i]];
        for (const glm::dvec3& corner : {t.a, t.b, t.c})
            dipole.radius = std::max(dipole.radius, glm::length(corner - dipole.centre));
    }
    dipoles_[index] = dipole;
    if (end - begin <= kLeafTriangles) {
        node.first = std::uint32_t(triangles_.size());
        node.count = end - begin;
        for (std::uint32_t i = begin; i < end; ++i) triangles_.push_back(input[order[i]]);
        nodes_[index] = node;
        return index;
    }
    // Median split of the centroids along the longest axis of their box.
    const glm::dvec3 spread = centroidMax - centroidMin;
    const int axis =
        spread.x >= spread.y && spread.x >= spread.z ? 0 : (spread.y >= spread.z ? 1 : 2);
    const std::uint32_t middle = begin + (end - begin) / 2;
    std::nth_element(order.begin() + begin, order.begin() + middle, order.begin() + end,
                     [&input, axis](std::uint32_t l, std::uint32_t r) {
                         const Triangle& a = input[l];
                         const Triangle& b = input[r];
                         const double ca = a.a[axis] + a.b[axis] + a.c[axis];
                         const double cb = b.a[axis] + b.b[axis] + b.c[axis];
                         return ca < cb || (ca == cb && l < r);
                     });
    build(order, begin, middle, input);
    node.first = build(order, middle, end, input);
    node.count = 0;
    nodes_[index] = node;
    return index;
}

double SoupDistance::closestSquared(const glm::dvec3& point, double bestSquared,
                                    std::uint32_t& bestTriangle) const {
    // Each entry keeps its box's squared distance, computed when it was pushed.
    std::array<std::pair<std::uint32_t, double>, kStackSize> stack;
    int size = 0;
    stack[size++] = {0u, boxDistanceSquared(point, nodes_[0].boxMin, nodes_[0].boxMax)};
    while (size > 0) {
        const auto [index, boxSquared] = stack[--size];
        if (boxSquared >= bestSquared) continue;
        const Node& node = nodes_[index];
        if (node.count > 0) {
            for (std::uint32_t t = node.first; t < node.first + node.count; ++t) {
                const Triangle& triangle = triangles_[t];
                const double squared =
                    triangleDistanceSquared(point, triangle.a, triangle.b, triangle.c);
                if (squared < bestSquared) {
                    bestSquared = squared;
                    bestTriangle = t;
                }
            }
            continue;
        }
        // Visit the nearer child first: push it last.
        const std::uint32_t left = index + 1, right = node.first;
        const double leftSquared =
            boxDistanceSquared(point, nodes_[left].boxMin, nodes_[left].boxMax);
        const double rightSquared =
            boxDistanceSquared(point, nodes_[right].boxMin, nodes_[right].boxMax);
        assert(size + 2 <= kStackSize);
        if (leftSquared <= rightSquared) {
            if (rightSquared < bestSquared) stack[size++] = {right, rightSquared};
            if (leftSquared < bestSquared) stack[size++] = {left, leftSquared};
        } else {
            if (leftSquared < bestSquared) stack[size++] = {left, leftSquared};
            if (rightSquared < bestSquared) stack[size++] = {right, rightSquared};
        }
    }
    return bestSquared;
}

double SoupDistance::unsignedDistance(const glm::dvec3& texelPosition, double cutoffTexels) const {
    NearestHint none;
    return unsignedDistance(texelPosition, cutoffTexels, none);
}

double SoupDistance::unsignedDistance(const glm::dvec3& texelPosition, double cutoffTexels,
                                      NearestHint& hint) const {
    // The hint's triangle is one of the candidates the search compares anyway (the same
    // arithmetic on the same shifted point), so starting from it gives the same minimum.
    double bestSquared = cutoffTexels * cutoffTexels;
    if (hint.triangle != UINT32_MAX) {
        const Triangle& triangle = triangles_[hint.triangle];
        bestSquared =
            std::min(bestSquared, triangleDistanceSquared(texelPosition - hint.shift, triangle.a,
                                                          triangle.b, triangle.c));
    }
    const PeriodicShifts shifts =
        periodicShifts(texelPosition, bounds_, tile_, std::sqrt(bestSquared));
    for (int n = shifts.yBegin; n <= shifts.yEnd; ++n) {
        for (int m = shifts.xBegin; m <= shifts.xEnd; ++m) {
            const glm::dvec3 shift(double(m) * tile_.width, double(n) * tile_.height, 0.0);
            std::uint32_t found = UINT32_MAX;
            bestSquared = closestSquared(texelPosition - shift, bestSquared, found);
            if (found != UINT32_MAX) hint = {found, shift};
        }
    }
    return std::sqrt(bestSquared);
}

double SoupDistance::windingNumberOfCopy(const glm::dvec3& point, double farFieldRatio) const {
    std::array<std::uint32_t, kStackSize> stack;
    int size = 0;
    stack[size++] = 0;
    double solidAngles = 0.0;
    while (size > 0) {
        const std::uint32_t index = stack[--size];
        const Node& node = nodes_[index];
        const Dipole& dipole = dipoles_[index];
        const glm::dvec3 toCentre = dipole.centre - point;
        const double distanceSquared = glm::dot(toCentre, toCentre);
        if (distanceSquared > farFieldRatio * farFieldRatio * dipole.radius * dipole.radius) {
            solidAngles += glm::dot(toCentre, dipole.vectorArea) /
                           (distanceSquared * std::sqrt(distanceSquared));
            continue;
        }
        if (node.count > 0) {
            for (std::uint32_t t = node.first; t < node.first + node.count; ++t) {
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
