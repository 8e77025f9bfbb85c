#include "common/position_weld.h"

#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <glm/geometric.hpp>
#include <numeric>
#include <tuple>

namespace distile {

double weldDistanceWorld(std::span<const glm::vec3> positions,
                         std::span<const glm::uvec3> triangles) {
    std::vector<float> edges;
    edges.reserve(3 * triangles.size());
    for (const glm::uvec3& triangle : triangles) {
        for (int corner = 0; corner < 3; ++corner) {
            const std::uint32_t from = triangle[corner], to = triangle[(corner + 1) % 3];
            if (from < positions.size() && to < positions.size())
                edges.push_back(glm::distance(positions[from], positions[to]));
        }
    }
    if (edges.empty()) return 0.0;
    const auto median = edges.begin() + std::ptrdiff_t(edges.size() / 2);
    std::nth_element(edges.begin(), median, edges.end());
    return std::isfinite(*median) ? kWeldFraction * double(*median) : 0.0;
}

std::vector<std::uint32_t> weldedPositionGroups(std::span<const glm::vec3> positions,
                                                std::span<const glm::uvec3> triangles) {
    const std::size_t count = positions.size();
    std::vector<std::uint32_t> groupOf(count);
    std::iota(groupOf.begin(), groupOf.end(), 0u);
    if (count < 2) return groupOf;
    const double tolerance = weldDistanceWorld(positions, triangles);
    // Cells of the tolerance's size: positions within it lie in the same or neighbouring cells.
    // Cell coordinates are clamped far out (a NaN-free, finite key: positions that far apart
    // share cells, and only the distance test below tells them apart). No tolerance (no edges,
    // or most of no length): cells of one position each, only equal positions weld.
    constexpr double kFarCells = 4.0e18;
    using Cell = std::array<std::int64_t, 3>;
    struct CellVertex {
        Cell cell;
        std::uint32_t index;
        bool operator<(const CellVertex& other) const {
            return std::tie(cell, index) < std::tie(other.cell, other.index);
        }
    };
    std::vector<CellVertex> sorted(count);
    for (std::uint32_t v = 0; v < count; ++v) {
        Cell cell{};
        for (int axis = 0; axis < 3; ++axis) {
            const float coordinate = positions[v][axis];
            // Without a tolerance: the coordinate's bits (equal floats, one key; -0 as +0).
            cell[axis] = tolerance > 0.0
                             ? std::int64_t(std::clamp(std::floor(double(coordinate) / tolerance),
                                                       -kFarCells, kFarCells))
                             : std::int64_t(std::bit_cast<std::uint32_t>(coordinate + 0.0f));
        }
        sorted[v] = {cell, v};
    }
    // Sorted by value rather than through an index array, so each comparison reads its own data;
    // the order is total (ties broken by index), so the parallel sort's result is unique.
    tbb::parallel_sort(sorted.begin(), sorted.end());

    // Union-find whose roots are each group's lowest index.
    auto root = [&](std::uint32_t v) {
        while (groupOf[v] != v) v = groupOf[v] = groupOf[groupOf[v]];
        return v;
    };
    auto weldIfNear = [&](std::uint32_t a, std::uint32_t b) {
        if (glm::distance(glm::dvec3(positions[a]), glm::dvec3(positions[b])) > tolerance) return;
        const std::uint32_t rootA = root(a), rootB = root(b);
        groupOf[std::max(rootA, rootB)] = std::min(rootA, rootB);
    };
    // Every vertex is compared with the later vertices of its own cell and of the neighbouring
    // cells after it in key order (each neighbouring pair of cells once): (x, y, z..z+1) follows
    // the vertex in the sorted array; (x+1, y-1..y+1, z-1..z+1) and (x, y+1, z-1..z+1) are four
    // runs whose starts only move forward as the vertex does. Without a tolerance, only the
    // vertex's own cell.
    const std::int64_t reach = tolerance > 0.0 ? 1 : 0;
    auto weldRun = [&](std::uint32_t vertex, std::size_t from, const Cell& last) {
        for (std::size_t next = from; next < count && !(last < sorted[next].cell); ++next)
            weldIfNear(vertex, sorted[next].index);
    };
    constexpr std::int64_t kRunOffsets[4][2] = {{1, -1}, {1, 0}, {1, 1}, {0, 1}};
    std::size_t runStart[4] = {0, 0, 0, 0};
    for (std::size_t k = 0; k < count; ++k) {
        const Cell& cell = sorted[k].cell;
        const std::uint32_t vertex = sorted[k].index;
        weldRun(vertex, k + 1, {cell[0], cell[1], cell[2] + reach});
        if (reach == 0) continue;
        for (int run = 0; run < 4; ++run) {
            const std::int64_t x = cell[0] + kRunOffsets[run][0];
            const std::int64_t y = cell[1] + kRunOffsets[run][1];
            const Cell first{x, y, cell[2] - 1};
            std::size_t& at = runStart[run];
            while (at < count && sorted[at].cell < first) ++at;
            weldRun(vertex, at, {x, y, cell[2] + 1});
        }
    }
    for (std::uint32_t v = 0; v < count; ++v) groupOf[v] = root(v);
    return groupOf;
}

}  // namespace distile
