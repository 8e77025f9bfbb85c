#include "bake/soup_distance_grid.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>

namespace distile {

namespace {

/// Union-find over voxel indices where a region's root is its smallest voxel: joining two roots
/// hangs the larger under the smaller, so every parent index is below its child's, and the roots
/// do not depend on the order of the joins.
class VoxelRegions {
  public:
    explicit VoxelRegions(std::size_t voxels) : parent_(voxels) {}

    void reset(std::size_t voxel) { parent_[voxel] = std::uint32_t(voxel); }

    std::uint32_t root(std::uint32_t voxel) {
        while (parent_[voxel] != voxel) {
            parent_[voxel] = parent_[parent_[voxel]];
            voxel = parent_[voxel];
        }
        return voxel;
    }

    void join(std::uint32_t a, std::uint32_t b) {
        a = root(a);
        b = root(b);
        if (a < b) parent_[b] = a;
        if (b < a) parent_[a] = b;
    }

    /// Numbers the regions 0, 1, ... in the order of their roots; the region of every voxel.
    std::vector<std::uint32_t> regionOfEachVoxel(std::uint32_t& regionCount) const {
        std::vector<std::uint32_t> region(parent_.size());
        regionCount = 0;
        // Parents precede their children: a parent's region is known when its child asks.
        for (std::size_t v = 0; v < parent_.size(); ++v)
            region[v] = parent_[v] == v ? regionCount++ : region[parent_[v]];
        return region;
    }

  private:
    std::vector<std::uint32_t> parent_;
};

}  // namespace

SoupDistanceGrid soupDistanceGrid(const SoupDistance& soup, int zBegin, int zEnd,
                                  double cutoffTexels, bool signedByWindingNumber,
                                  const ProgressCallback& progress) {
    const Size3& tile = soup.tile();
    SoupDistanceGrid grid;
    grid.width = tile.width;
    grid.height = tile.height;
    grid.zBegin = zBegin;
    grid.zEnd = zEnd;
    const int slices = zEnd - zBegin;
    const std::size_t rowLength = std::size_t(tile.width);
    const std::size_t slabSize = rowLength * std::size_t(tile.height);
    const std::size_t voxels = slabSize * std::size_t(slices);
    assert(voxels < std::size_t(UINT32_MAX));
    grid.distancesTexels.resize(voxels);
    grid.nearest.resize(voxels);
    // Signed by regions: the side of the surface each voxel lies on at its nearest point (told
    // while the line's triangles are at hand), to check that the point bounds the inside.
    const bool byRegions = signedByWindingNumber && soup.windingChangesOnlyAcrossTheSurface();
    std::vector<std::int8_t> sides(byRegions ? voxels : 0);
    std::vector<double>& distances = grid.distancesTexels;
    const auto centre = [&](std::size_t voxel) {
        const std::size_t i = voxel % rowLength, j = (voxel / rowLength) % std::size_t(tile.height);
        const std::size_t k = voxel / slabSize;
        return glm::dvec3(double(i) + 0.5, double(j) + 0.5, double(zBegin + int(k)) + 0.5);
    };
    // Progress: the distances are most of the work; the sign takes the last step.
    const int steps = slices + (signedByWindingNumber ? 1 : 0);

    // Columns of kColumn x kColumn voxels through all the slices, each line of voxels through
    // the slices measured at once, started from the nearest triangles of its neighbour in the
    // row (that of the row below for a row's first): a hint gives the same exact result faster,
    // and the triangles near a column stay in the core's cache while it is measured. Progress
    // after each row of columns.
    constexpr int kColumn = 8;
    const int columnsX = (tile.width + kColumn - 1) / kColumn;
    const int columnsY = (tile.height + kColumn - 1) / kColumn;
    std::vector<double> sliceZ(static_cast<std::size_t>(slices));
    for (int slice = 0; slice < slices; ++slice) sliceZ[std::size_t(slice)] = zBegin + slice + 0.5;
    for (int columnRow = 0; columnRow < columnsY; ++columnRow) {
        tbb::parallel_for(0, columnsX, [&](int column) {
            const int i0 = column * kColumn, i1 = std::min(tile.width, i0 + kColumn);
            const int j0 = columnRow * kColumn, j1 = std::min(tile.height, j0 + kColumn);
            std::vector<SoupDistance::NearestHint> rowStart(static_cast<std::size_t>(slices)),
                hints;
            std::vector<double> line(static_cast<std::size_t>(slices));
            std::vector<SoupDistance::NearestHint> lineTies(byRegions ? std::size_t(slices) : 0);
            for (int j = j0; j < j1; ++j) {
                hints = rowStart;
                for (int i = i0; i < i1; ++i) {
                    soup.unsignedDistancesOnLine({i + 0.5, j + 0.5}, sliceZ, cutoffTexels, hints,
                                                 line, lineTies);
                    for (int slice = 0; slice < slices; ++slice) {
                        const std::size_t voxel = std::size_t(slice) * slabSize +
                                                  std::size_t(j) * rowLength + std::size_t(i);
                        distances[voxel] = line[std::size_t(slice)];
                        grid.nearest[voxel] = hints[std::size_t(slice)];
                        if (byRegions && line[std::size_t(slice)] < cutoffTexels) {
                            sides[voxel] = std::int8_t(
                                soup.sideOfNearestPoint(centre(voxel), hints[std::size_t(slice)],
                                                        lineTies[std::size_t(slice)]));
                        }
                    }
                    if (i == i0) rowStart = hints;
                }
            }
        });
        if (progress) progress(double(columnRow + 1) / columnsY * slices / steps);
    }
    if (!signedByWindingNumber) return grid;

    if (!soup.windingChangesOnlyAcrossTheSurface()) {
        // The winding number also varies off the surface: evaluated at every voxel.
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, voxels),
                          [&](const tbb::blocked_range<std::size_t>& range) {
                              for (std::size_t v = range.begin(); v != range.end(); ++v) {
                                  if (soup.windingNumber(centre(v)) > 0.5)
                                      distances[v] = -distances[v];
                              }
                          });
        if (progress) progress(1.0);
        return grid;
    }

    // Two neighbours 1 texel apart are in one region when no surface can lie between them: their
    // empty balls overlap, d1 + d2 > 1, covering the segment between them. Regions are the
    // connected parts of that relation. (Testing the segments of the other pairs against the
    // triangles would join more, but costs more than the winding numbers of the regions it
    // saves: a crossing count each.)
    const auto joined = [&](std::size_t a, std::size_t b) {
        return distances[a] + distances[b] > 1.0 + 1e-9;
    };
    VoxelRegions regions(voxels);
    // Within each slice (its voxels only, so slices are independent), then across slices.
    tbb::parallel_for(0, slices, [&](int slice) {
        const std::size_t first = std::size_t(slice) * slabSize;
        const std::size_t end = first + slabSize;
        for (std::size_t v = first; v < end; ++v) regions.reset(v);
        for (std::size_t v = first; v < end; ++v) {
            if (v % rowLength + 1 < rowLength && joined(v, v + 1))
                regions.join(std::uint32_t(v), std::uint32_t(v + 1));
            if (v + rowLength < end && joined(v, v + rowLength))
                regions.join(std::uint32_t(v), std::uint32_t(v + rowLength));
        }
    });
    for (std::size_t v = 0; v + slabSize < voxels; ++v) {
        if (joined(v, v + slabSize)) regions.join(std::uint32_t(v), std::uint32_t(v + slabSize));
    }
    std::uint32_t regionCount = 0;
    const std::vector<std::uint32_t> region = regions.regionOfEachVoxel(regionCount);
    // Each region's winding number at its voxel farthest from the surface (the first of equals),
    // where the far field approximates it best.
    std::vector<std::uint32_t> farthest(regionCount, UINT32_MAX);
    for (std::size_t v = 0; v < voxels; ++v) {
        std::uint32_t& best = farthest[region[v]];
        if (best == UINT32_MAX || distances[v] > distances[best]) best = std::uint32_t(v);
    }
    // An integer: counted from crossings where they are clear, else the far field rounded.
    std::vector<int> winding(regionCount);
    tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, regionCount),
                      [&](const tbb::blocked_range<std::uint32_t>& range) {
                          for (std::uint32_t r = range.begin(); r != range.end(); ++r) {
                              winding[r] =
                                  int(std::lround(soup.countedWindingNumber(centre(farthest[r]))));
                          }
                      });
    // Whether every voxel's distance is to the boundary of the inside: its nearest point bounds
    // it, winding number 0 in front and 1 behind (the voxel's, on its side); where the side is
    // not known, its nearest triangle must face outside at its centroid (what MeshSurface checks
    // of every triangle).
    std::vector<std::atomic<std::uint8_t>> toCheck(soup.triangleCount());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, voxels),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t v = range.begin(); v != range.end(); ++v) {
                              const int w = winding[region[v]];
                              if (w > 0) distances[v] = -distances[v];
                              // Beyond the cutoff the distance is the cutoff either way.
                              if (!(std::abs(distances[v]) < cutoffTexels)) continue;
                              const std::uint32_t nearest = grid.nearest[v].triangle;
                              if (sides[v] == 0 || (sides[v] > 0 ? w : w - 1) != 0)
                                  toCheck[nearest].store(1, std::memory_order_relaxed);
                          }
                      });
    grid.nearestPointsBound = tbb::parallel_reduce(
        tbb::blocked_range<std::uint32_t>(0, std::uint32_t(toCheck.size())), true,
        [&](const tbb::blocked_range<std::uint32_t>& range, bool bound) {
            for (std::uint32_t t = range.begin(); bound && t != range.end(); ++t) {
                if (!toCheck[t].load(std::memory_order_relaxed)) continue;
                bound = soup.facesOutsideAtCentroid(t);
            }
            return bound;
        },
        [](bool x, bool y) { return x && y; });
    if (progress) progress(1.0);
    return grid;
}

SoupDistance::NearestHint SoupDistanceGrid::hintNear(const glm::dvec3& texelPosition) const {
    const int i = int(std::floor(texelPosition.x)), j = int(std::floor(texelPosition.y));
    const int k = std::clamp(int(std::floor(texelPosition.z)), zBegin, zEnd - 1);
    // The copy of the tile the point lies in, and its voxel there.
    const int copyX = int(std::floor(double(i) / width)),
              copyY = int(std::floor(double(j) / height));
    const std::size_t voxel =
        (std::size_t(k - zBegin) * std::size_t(height) + std::size_t(j - copyY * height)) *
            std::size_t(width) +
        std::size_t(i - copyX * width);
    SoupDistance::NearestHint hint = nearest[voxel];
    if (hint.triangle != UINT32_MAX) {
        hint.copyX += copyX;
        hint.copyY += copyY;
    }
    return hint;
}

double signedDistanceBesideGrid(const SoupDistance& soup, const SoupDistanceGrid& grid,
                                const glm::dvec3& texelPosition, double distance) {
    if (soup.windingChangesOnlyAcrossTheSurface()) {
        // The voxel centres around the point (of the copy of the tile it lies in: the field is
        // periodic): the sign of one that no surface can separate from it, by their distances
        // (checked for all first, cheap) or else by a segment test.
        const Size3& tile = soup.tile();
        const auto wrap = [](int index, int count) { return ((index % count) + count) % count; };
        const int i0 = int(std::floor(texelPosition.x - 0.5));
        const int j0 = int(std::floor(texelPosition.y - 0.5));
        const int k0 = int(std::floor(texelPosition.z - 0.5));
        std::array<glm::dvec3, 8> centres;
        std::array<double, 8> voxelDistances;
        int count = 0;
        for (int k = k0; k <= k0 + 1; ++k) {
            if (k < grid.zBegin || k >= grid.zEnd) continue;
            for (int j = j0; j <= j0 + 1; ++j) {
                for (int i = i0; i <= i0 + 1; ++i) {
                    centres[count] = {i + 0.5, j + 0.5, k + 0.5};
                    voxelDistances[count++] =
                        grid.row(wrap(j, tile.height), k)[wrap(i, tile.width)];
                }
            }
        }
        for (int n = 0; n < count; ++n) {
            if (std::abs(voxelDistances[n]) + distance >
                glm::length(texelPosition - centres[n]) + 1e-9)
                return voxelDistances[n] < 0.0 ? -distance : distance;
        }
        for (int n = 0; n < count; ++n) {
            if (soup.segmentTouchesNoTriangle(centres[n], texelPosition))
                return voxelDistances[n] < 0.0 ? -distance : distance;
        }
    }
    return soup.windingNumber(texelPosition) > 0.5 ? -distance : distance;
}

}  // namespace distile
