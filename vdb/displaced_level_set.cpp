#include "vdb/displaced_level_set.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/RayIntersector.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <initializer_list>
#include <limits>
#include <map>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "common/error.h"

namespace distile {

namespace {

void reject(const std::string& what, const std::string& why) {
    throw InputError("world reference level set: " + what + ": " + why);
}

template <int N>
bool isFinite(const glm::vec<N, float>& value) {
    for (int axis = 0; axis < N; ++axis) {
        if (!std::isfinite(value[axis])) return false;
    }
    return true;
}

void validateInput(const Size3& tile, const DisplacementShell& shell,
                   const DisplacedLevelSetOptions& options) {
    validateTileSize(tile, "world reference level set: tile size");
    const std::size_t vertexCount = shell.positions.size();
    if (shell.triangles.empty()) reject("base mesh", "it has no triangles");
    if (shell.normals.size() != vertexCount || shell.uvs.size() != vertexCount) {
        reject("base mesh", "positions, normals and uvs must have one entry per vertex");
    }
    for (std::size_t vertex = 0; vertex < vertexCount; ++vertex) {
        const bool finite = isFinite(shell.positions[vertex]) && isFinite(shell.normals[vertex]) &&
                            isFinite(shell.uvs[vertex]);
        if (!finite) reject("vertex " + std::to_string(vertex), "it is not finite");
    }
    for (const glm::uvec3& triangle : shell.triangles) {
        if (triangle.x >= vertexCount || triangle.y >= vertexCount || triangle.z >= vertexCount) {
            reject("base mesh", "a triangle index is out of range");
        }
    }
    if (!(shell.uvScale.x > 0.0 && shell.uvScale.y > 0.0) || !std::isfinite(shell.uvScale.x) ||
        !std::isfinite(shell.uvScale.y)) {
        reject("uv scale", "it must be finite and > 0");
    }
    if (!(shell.depthWorld > 0.0) || !std::isfinite(shell.depthWorld)) {
        reject("depth", "it must be finite and > 0 world units");
    }
    if (options.samplesPerTexel < 1 || options.samplesPerTexel > 8) {
        reject("samples per texel", std::to_string(options.samplesPerTexel) + " is not in [1, 8]");
    }
    if (!(options.voxelsPerTexel > 0.0 && options.voxelsPerTexel <= 16.0)) {
        reject("voxels per texel", std::to_string(options.voxelsPerTexel) + " is not in (0, 16]");
    }
    if (!(options.halfBandVoxels >= 2.0f && options.halfBandVoxels <= 16.0f)) {
        reject("half band", std::to_string(options.halfBandVoxels) + " voxels is not in [2, 16]");
    }
}

double cross2(const glm::dvec2& a, const glm::dvec2& b) {
    return a.x * b.y - a.y * b.x;
}

/// Does the chart wrap along `axis` (0: u, 1: v)? True when it spans exactly one unit there and
/// some vertex shares its position with another whose uv differs by one unit along that axis.
bool chartWraps(const DisplacementShell& shell, int axis, double uvMin, double uvMax) {
    if (std::abs(uvMax - uvMin - 1.0) > 1e-5) return false;
    std::map<std::tuple<float, float, float>, std::vector<float>> coordinatesByPosition;
    for (std::size_t vertex = 0; vertex < shell.positions.size(); ++vertex) {
        const glm::vec3& p = shell.positions[vertex];
        coordinatesByPosition[{p.x, p.y, p.z}].push_back(shell.uvs[vertex][axis]);
    }
    for (const auto& [position, coordinates] : coordinatesByPosition) {
        const auto [low, high] = std::minmax_element(coordinates.begin(), coordinates.end());
        if (std::abs(*high - *low - 1.0f) < 1e-5f) return true;
    }
    return false;
}

double secondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

long long positiveModulo(long long value, long long period) {
    const long long remainder = value % period;
    return remainder < 0 ? remainder + period : remainder;
}

/// Which base triangle holds a uv, through a uniform grid of cells over the chart's bounds.
class UvLocator {
  public:
    explicit UvLocator(const DisplacementShell& shell) : shell_(shell) {
        uvMin_ = glm::dvec2(shell.uvs[0]);
        uvMax_ = uvMin_;
        for (const glm::vec2& uv : shell.uvs) {
            uvMin_ = glm::min(uvMin_, glm::dvec2(uv));
            uvMax_ = glm::max(uvMax_, glm::dvec2(uv));
        }
        cells_ = std::clamp(int(std::sqrt(double(shell.triangles.size()))), 1, 1024);
        cellSize_ = glm::max((uvMax_ - uvMin_) / double(cells_), glm::dvec2(1e-12));
        cellTriangles_.resize(std::size_t(cells_) * cells_);
        for (std::uint32_t index = 0; index < shell.triangles.size(); ++index) {
            const auto corners = uvCorners(index);
            if (std::abs(cross2(corners[1] - corners[0], corners[2] - corners[0])) <= 1e-14)
                continue;  // zero uv area: holds no uv
            const glm::dvec2 low = glm::min(corners[0], glm::min(corners[1], corners[2]));
            const glm::dvec2 high = glm::max(corners[0], glm::max(corners[1], corners[2]));
            const glm::ivec2 first = cellOf(low), last = cellOf(high);
            for (int y = first.y; y <= last.y; ++y) {
                for (int x = first.x; x <= last.x; ++x) {
                    cellTriangles_[std::size_t(x) + std::size_t(cells_) * y].push_back(index);
                }
            }
        }
    }

    glm::dvec2 uvMin() const { return uvMin_; }
    glm::dvec2 uvMax() const { return uvMax_; }

    /// The triangle holding `uv` with its barycentric weights; for a uv outside every triangle
    /// (beyond the chart's edge, or in a gap of it), the nearest candidate with its weights
    /// clamped to the triangle. False when the chart holds no triangle of non-zero uv area.
    bool locate(const glm::dvec2& uv, std::uint32_t& triangle, glm::dvec3& weights) const {
        const glm::ivec2 cell = cellOf(uv);
        double bestInside = -std::numeric_limits<double>::infinity();
        for (int ring = 0; ring <= cells_; ++ring) {
            for (int y = cell.y - ring; y <= cell.y + ring; ++y) {
                for (int x = cell.x - ring; x <= cell.x + ring; ++x) {
                    const bool onRing =
                        std::max(std::abs(x - cell.x), std::abs(y - cell.y)) == ring;
                    if (!onRing || x < 0 || y < 0 || x >= cells_ || y >= cells_) continue;
                    for (std::uint32_t index :
                         cellTriangles_[std::size_t(x) + std::size_t(cells_) * y]) {
                        const glm::dvec3 b = barycentric(index, uv);
                        const double inside = std::min(b.x, std::min(b.y, b.z));
                        if (inside > bestInside) {
                            bestInside = inside;
                            triangle = index;
                            weights = b;
                        }
                    }
                }
            }
            // Inside a triangle, or something found and one more ring searched for a nearer edge.
            if (bestInside >= -1e-9 || (ring >= 1 && std::isfinite(bestInside))) break;
        }
        if (!std::isfinite(bestInside)) return false;
        if (bestInside < 0.0) {
            weights = glm::max(weights, glm::dvec3(0.0));
            weights /= weights.x + weights.y + weights.z;
        }
        return true;
    }

  private:
    std::array<glm::dvec2, 3> uvCorners(std::uint32_t index) const {
        const glm::uvec3& t = shell_.triangles[index];
        return {glm::dvec2(shell_.uvs[t.x]), glm::dvec2(shell_.uvs[t.y]),
                glm::dvec2(shell_.uvs[t.z])};
    }
    glm::ivec2 cellOf(const glm::dvec2& uv) const {
        const glm::dvec2 cell = glm::floor((uv - uvMin_) / cellSize_);
        return glm::clamp(glm::ivec2(glm::clamp(cell, -1.0, double(cells_))), 0, cells_ - 1);
    }
    glm::dvec3 barycentric(std::uint32_t index, const glm::dvec2& uv) const {
        const auto c = uvCorners(index);
        const double area = cross2(c[1] - c[0], c[2] - c[0]);
        const double b1 = cross2(uv - c[0], c[2] - c[0]) / area;
        const double b2 = cross2(c[1] - c[0], uv - c[0]) / area;
        return {1.0 - b1 - b2, b1, b2};
    }

    const DisplacementShell& shell_;
    glm::dvec2 uvMin_, uvMax_;
    int cells_ = 1;
    glm::dvec2 cellSize_{1.0};
    std::vector<std::vector<std::uint32_t>> cellTriangles_;
};

/// Median over the triangles of the world length of one texel: sqrt(world area / texel area).
double medianTexelSizeWorld(const DisplacementShell& shell, const Size3& tile) {
    const double texelsPerUv2 =
        shell.uvScale.x * tile.width * shell.uvScale.y * tile.height;  // texels per unit uv area
    std::vector<double> sizes;
    for (const glm::uvec3& t : shell.triangles) {
        const glm::dvec3 p0(shell.positions[t.x]), p1(shell.positions[t.y]),
            p2(shell.positions[t.z]);
        const glm::dvec2 u0(shell.uvs[t.x]), u1(shell.uvs[t.y]), u2(shell.uvs[t.z]);
        const double uvArea = std::abs(cross2(u1 - u0, u2 - u0));
        const double worldArea = glm::length(glm::cross(p1 - p0, p2 - p0));
        if (uvArea > 1e-14 && worldArea > 0.0)
            sizes.push_back(std::sqrt(worldArea / (uvArea * texelsPerUv2)));
    }
    if (sizes.empty()) reject("base mesh", "no triangle has both a world and a uv area");
    std::nth_element(sizes.begin(), sizes.begin() + sizes.size() / 2, sizes.end());
    return sizes[sizes.size() / 2];
}

/// The chart's extent along one texel axis and whether it wraps there (no wall).
struct FootprintAxis {
    double lowTexels = 0.0;  ///< the chart's edges, texels
    double highTexels = 0.0;
    bool wraps = false;
    /// The walls of a chart that does not wrap sit a hair inside it, so their vertices map
    /// inside the chart; a wrapping chart has none.
    double wallLow() const { return wraps ? -kNoWall : lowTexels + kWallInset; }
    double wallHigh() const { return wraps ? kNoWall : highTexels - kWallInset; }
    /// Polygons are kept with their centroid in [ownLow, ownHigh): the chart, plus the walls.
    double ownLow() const { return wraps ? lowTexels : lowTexels - kWallMargin; }
    double ownHigh() const { return wraps ? highTexels : highTexels + kWallMargin; }

    static constexpr double kNoWall = 1e300;
    static constexpr double kWallInset = 1e-3;  ///< texels
    static constexpr double kWallMargin = 2.0;  ///< texels beyond the wall that hold its polygons
};

/// Texel-space polygons of the detail's zero isosurface in one box of the footprint, in
/// coordinates relative to the box's tile copy (texels).
struct TexelMesh {
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
};

/// Which repeat of the tile: copy (i, j) has its origin at texel (i W, j H).
using CopyIndex = glm::vec<2, long long>;

/// One repeat of the tile in the footprint: its origin (texels) and the mesh placed there.
struct TileCopy {
    glm::dvec2 originTexels{0.0};
    const TexelMesh* mesh = nullptr;
};

/// The detail on one tile's lattice (periodic in x and y), with the floor, top and walls applied
/// where a box of the footprint is extracted.
class TileLattice {
  public:
    /// Lattice samples below z = 0 and above z = D (texels): the field is positive there.
    static constexpr int kMarginTexels = 2;
    /// The solid floor's slab ends between lattice samples, so a sample inside it is negative.
    static constexpr double kFloorSlabTexels = 1.5;

    TileLattice(const DisplacedLevelSet::DistanceFunction& detail, const Size3& tile,
                int samplesPerTexel, bool solidFloor)
        : spacing_(1.0 / samplesPerTexel),
          countX_((long long)(tile.width) * samplesPerTexel),
          countY_((long long)(tile.height) * samplesPerTexel),
          firstZ_(-kMarginTexels * samplesPerTexel),
          countZ_((long long)(tile.depth + 2 * kMarginTexels) * samplesPerTexel + 1),
          depthTexels_(tile.depth),
          solidFloor_(solidFloor) {
        if (double(countX_) * double(countY_) * double(countZ_) > double(1u << 31)) {
            reject("tile lattice", "more than 2^31 samples; use fewer samples per texel");
        }
        distances_.resize(std::size_t(countX_ * countY_ * countZ_));
        tbb::parallel_for(tbb::blocked_range<long long>(0, countZ_), [&](const auto& range) {
            for (long long k = range.begin(); k != range.end(); ++k) {
                for (long long j = 0; j < countY_; ++j) {
                    for (long long i = 0; i < countX_; ++i) {
                        const glm::dvec3 texel(i * spacing_, j * spacing_,
                                               (firstZ_ + k) * spacing_);
                        distances_[index(i, j, k)] = float(detail(texel));
                    }
                }
            }
        });
    }

    double spacing() const { return spacing_; }

    /// The isosurface's polygons whose centroid lies in [ownLow, ownHigh) (texels relative to
    /// `originTexels`, a whole number of tiles), with the walls of `axisX`, `axisY` applied.
    /// Extracted from the lattice padded by kPadSamples around that box, so every polygon in it
    /// is complete and the padding's boundary effects are dropped.
    TexelMesh extract(const glm::dvec2& originTexels, const glm::dvec2& ownLow,
                      const glm::dvec2& ownHigh, const FootprintAxis& axisX,
                      const FootprintAxis& axisY) const {
        constexpr long long kPadSamples = 3;
        const long long firstI = (long long)(std::floor(ownLow.x / spacing_)) - kPadSamples;
        const long long lastI = (long long)(std::ceil(ownHigh.x / spacing_)) + kPadSamples;
        const long long firstJ = (long long)(std::floor(ownLow.y / spacing_)) - kPadSamples;
        const long long lastJ = (long long)(std::ceil(ownHigh.y / spacing_)) + kPadSamples;
        const long long originI = std::llround(originTexels.x / spacing_);
        const long long originJ = std::llround(originTexels.y / spacing_);
        // Narrow band: every sign change between neighbouring samples has both ends active.
        const float bandTexels = float(2.0 * spacing_);
        auto grid = openvdb::FloatGrid::create(bandTexels);
        grid->setTransform(openvdb::math::Transform::createLinearTransform(spacing_));
        auto accessor = grid->getAccessor();
        for (long long k = 0; k < countZ_; ++k) {
            const double z = double(firstZ_ + k) * spacing_;
            for (long long j = firstJ; j <= lastJ; ++j) {
                const double y = double(originJ + j) * spacing_;
                const double wallY = std::max(axisY.wallLow() - y, y - axisY.wallHigh());
                const long long tileJ = positiveModulo(originJ + j, countY_);
                for (long long i = firstI; i <= lastI; ++i) {
                    const double x = double(originI + i) * spacing_;
                    const double wall =
                        std::max({axisX.wallLow() - x, x - axisX.wallHigh(), wallY});
                    const long long tileI = positiveModulo(originI + i, countX_);
                    const double field = clipped(distances_[index(tileI, tileJ, k)], z, wall);
                    if (std::abs(field) < bandTexels) {
                        accessor.setValue(openvdb::Coord(int(i), int(j), int(firstZ_ + k)),
                                          float(field));
                    }
                }
            }
        }
        openvdb::tools::signedFloodFill(grid->tree());
        TexelMesh all;
        openvdb::tools::volumeToMesh(*grid, all.points, all.triangles, all.quads, 0.0, 0.0);
        grid.reset();
        return keepOwned(std::move(all), ownLow, ownHigh);
    }

  private:
    std::size_t index(long long i, long long j, long long k) const {
        return std::size_t(i + countX_ * (j + countY_ * k));
    }

    /// The detail with the floor (a slab below z = 0, or open), the top (z = D) and the walls.
    double clipped(double detail, double z, double wall) const {
        double field = solidFloor_ ? std::max(std::min(detail, z), -(z + kFloorSlabTexels))
                                   : std::max(detail, -z);
        return std::max({field, z - depthTexels_, wall});
    }

    /// The polygons of `all` with their centroid in [ownLow, ownHigh) (a hair wider, so a
    /// centroid on the line between two boxes is kept twice rather than lost to rounding; the
    /// copies coincide), with only the points they use.
    static TexelMesh keepOwned(TexelMesh all, const glm::dvec2& ownLow, const glm::dvec2& ownHigh) {
        constexpr double kTieTexels = 1e-4;
        const auto owned = [&](std::initializer_list<unsigned> corners) {
            glm::dvec2 centroid(0.0);
            for (unsigned corner : corners) {
                centroid += glm::dvec2(all.points[corner].x(), all.points[corner].y());
            }
            centroid /= double(corners.size());
            return centroid.x >= ownLow.x - kTieTexels && centroid.x < ownHigh.x + kTieTexels &&
                   centroid.y >= ownLow.y - kTieTexels && centroid.y < ownHigh.y + kTieTexels;
        };
        TexelMesh kept;
        std::vector<unsigned> newIndex(all.points.size(), ~0u);
        const auto keep = [&](unsigned corner) {
            if (newIndex[corner] == ~0u) {
                newIndex[corner] = unsigned(kept.points.size());
                kept.points.push_back(all.points[corner]);
            }
            return newIndex[corner];
        };
        for (const openvdb::Vec3I& t : all.triangles) {
            if (owned({t[0], t[1], t[2]}))
                kept.triangles.emplace_back(keep(t[0]), keep(t[1]), keep(t[2]));
        }
        for (const openvdb::Vec4I& q : all.quads) {
            if (owned({q[0], q[1], q[2], q[3]})) {
                kept.quads.emplace_back(keep(q[0]), keep(q[1]), keep(q[2]), keep(q[3]));
            }
        }
        return kept;
    }

    double spacing_;
    long long countX_, countY_;  ///< samples per tile period
    long long firstZ_, countZ_;  ///< z = (firstZ_ + k) * spacing_ for k in [0, countZ_)
    double depthTexels_;
    bool solidFloor_;
    std::vector<float> distances_;  ///< x fastest, then y, then z
};

/// The interval [first, end) of tile copies along one axis that meet the chart; the first and
/// the last also hold the polygons of the walls just beyond it.
std::pair<long long, long long> copyRange(const FootprintAxis& axis, double tileTexels) {
    const auto first = (long long)(std::floor(axis.lowTexels / tileTexels));
    return {first, std::max(first + 1, (long long)(std::ceil(axis.highTexels / tileTexels)))};
}

/// The polygons copy `index` of [first, end) keeps along one axis, texels relative to its
/// origin: its own tile, clipped to the chart, the first and last copies extended to the walls.
std::pair<double, double> copyOwnership(const FootprintAxis& axis, long long index,
                                        std::pair<long long, long long> range, double tileTexels) {
    const double origin = double(index) * tileTexels;
    const double low = index == range.first ? axis.ownLow() : std::max(origin, axis.ownLow());
    const double high =
        index + 1 == range.second ? axis.ownHigh() : std::min(origin + tileTexels, axis.ownHigh());
    return {low - origin, high - origin};
}

/// Whether copy `index` (tile length `tileTexels`) can be the shared tile mesh placed as it is:
/// it lies inside the kept range, and far enough from the walls that they change no sample
/// its polygons depend on (the detail is a distance, so a sample next to a sign change is
/// > -spacing; a wall more than a few samples away is below that).
bool plainAlong(const FootprintAxis& axis, long long index, double tileTexels, double spacing) {
    const double low = double(index) * tileTexels, high = low + tileTexels;
    if (axis.wraps) return low >= axis.lowTexels && high <= axis.highTexels;
    const double wallClearance = 4.0 * spacing + 1.0;
    return low >= axis.wallLow() + wallClearance && high <= axis.wallHigh() - wallClearance;
}

}  // namespace

struct DisplacedLevelSet::Impl {
    openvdb::FloatGrid::Ptr grid;
    std::unique_ptr<openvdb::tools::LevelSetRayIntersector<openvdb::FloatGrid>> intersector;
    DisplacedLevelSetStats stats;
};

DisplacedLevelSet::DisplacedLevelSet(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
DisplacedLevelSet::DisplacedLevelSet(DisplacedLevelSet&&) noexcept = default;
DisplacedLevelSet& DisplacedLevelSet::operator=(DisplacedLevelSet&&) noexcept = default;
DisplacedLevelSet::~DisplacedLevelSet() = default;

const DisplacedLevelSetStats& DisplacedLevelSet::stats() const {
    return impl_->stats;
}

DisplacedLevelSet DisplacedLevelSet::build(const DistanceFunction& detail, const Size3& tile,
                                           const DisplacementShell& shell,
                                           const DisplacedLevelSetOptions& options) {
    validateInput(tile, shell, options);
    const auto start = std::chrono::steady_clock::now();
    openvdb::initialize();
    auto impl = std::make_unique<Impl>();
    DisplacedLevelSetStats& stats = impl->stats;

    // 1. The detail on one tile's lattice, sampled once (multi-threaded).
    const TileLattice lattice(detail, tile, options.samplesPerTexel, shell.solidFloor);

    // 2. The footprint: the chart's uv bounds in texels, walls where it does not wrap.
    const UvLocator locator(shell);
    const glm::dvec2 texelsPerUv(shell.uvScale.x * tile.width, shell.uvScale.y * tile.height);
    const glm::dvec2 uvMin = locator.uvMin(), uvMax = locator.uvMax();
    if (!(uvMax.x > uvMin.x && uvMax.y > uvMin.y)) reject("base mesh uvs", "the chart has no area");
    stats.wrapsU = chartWraps(shell, 0, uvMin.x, uvMax.x);
    stats.wrapsV = chartWraps(shell, 1, uvMin.y, uvMax.y);
    const FootprintAxis axisX{uvMin.x * texelsPerUv.x, uvMax.x * texelsPerUv.x, stats.wrapsU};
    const FootprintAxis axisY{uvMin.y * texelsPerUv.y, uvMax.y * texelsPerUv.y, stats.wrapsV};

    // 3. The tile copies that cover it: the copies away from walls and chart edges share one
    //    extracted tile mesh; the others are extracted with the walls and clipped to the chart.
    const glm::dvec2 tileTexels(tile.width, tile.height);
    const auto copiesX = copyRange(axisX, tileTexels.x);
    const auto copiesY = copyRange(axisY, tileTexels.y);
    const auto [firstCopyX, endCopyX] = copiesX;
    const auto [firstCopyY, endCopyY] = copiesY;
    const double copyCount = double(endCopyX - firstCopyX) * double(endCopyY - firstCopyY);
    constexpr double kMaxCopies = 1 << 16;
    if (copyCount > kMaxCopies) {
        reject("uv scale", "the chart holds " + std::to_string((long long)(copyCount)) +
                               " tile repeats; at most 65536 are accepted");
    }
    std::vector<CopyIndex> edgeCopies;
    std::vector<TileCopy> copies;
    for (long long copyY = firstCopyY; copyY < endCopyY; ++copyY) {
        for (long long copyX = firstCopyX; copyX < endCopyX; ++copyX) {
            const glm::dvec2 origin(double(copyX) * tileTexels.x, double(copyY) * tileTexels.y);
            if (plainAlong(axisX, copyX, tileTexels.x, lattice.spacing()) &&
                plainAlong(axisY, copyY, tileTexels.y, lattice.spacing())) {
                copies.push_back({origin, nullptr});  // the shared tile mesh, set below
            } else {
                edgeCopies.push_back({copyX, copyY});
            }
        }
    }
    TexelMesh tileMesh;
    if (!copies.empty()) {
        const FootprintAxis unwalled{0.0, 0.0, true};
        tileMesh =
            lattice.extract(glm::dvec2(0.0), glm::dvec2(0.0), tileTexels, unwalled, unwalled);
        for (TileCopy& copy : copies) copy.mesh = &tileMesh;
    }
    stats.tileCopies = copies.size();
    stats.edgeCopies = edgeCopies.size();
    std::vector<TexelMesh> edgeMeshes(edgeCopies.size());
    tbb::parallel_for(std::size_t(0), edgeCopies.size(), [&](std::size_t index) {
        const CopyIndex copy = edgeCopies[index];
        const glm::dvec2 origin = glm::dvec2(copy) * tileTexels;
        const auto [lowX, highX] = copyOwnership(axisX, copy.x, copiesX, tileTexels.x);
        const auto [lowY, highY] = copyOwnership(axisY, copy.y, copiesY, tileTexels.y);
        edgeMeshes[index] = lattice.extract(origin, {lowX, lowY}, {highX, highY}, axisX, axisY);
    });
    for (std::size_t index = 0; index < edgeCopies.size(); ++index) {
        copies.push_back({glm::dvec2(edgeCopies[index]) * tileTexels, &edgeMeshes[index]});
    }

    // 4. The copies' vertices mapped through the shell (a wrapping chart's coordinate taken
    //    modulo one unit of uv, so vertices past the seam land beside it), their polygons joined.
    std::vector<std::size_t> firstPoint(copies.size() + 1, 0);
    std::size_t triangleCount = 0, quadCount = 0;
    for (std::size_t index = 0; index < copies.size(); ++index) {
        firstPoint[index + 1] = firstPoint[index] + copies[index].mesh->points.size();
        triangleCount += copies[index].mesh->triangles.size();
        quadCount += copies[index].mesh->quads.size();
    }
    std::vector<openvdb::Vec3s> points(firstPoint.back());
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    triangles.reserve(triangleCount);
    quads.reserve(quadCount);
    for (std::size_t index = 0; index < copies.size(); ++index) {
        const auto offset = unsigned(firstPoint[index]);
        for (const openvdb::Vec3I& t : copies[index].mesh->triangles) {
            triangles.push_back(t + openvdb::Vec3I(offset));
        }
        for (const openvdb::Vec4I& q : copies[index].mesh->quads) {
            quads.push_back(q + openvdb::Vec4I(offset));
        }
    }
    const double depthTexels = double(tile.depth);
    const auto wrapped = [](double uv, double uvLow, bool wraps) {
        return wraps ? uvLow + (uv - uvLow - std::floor(uv - uvLow)) : uv;
    };
    for (std::size_t index = 0; index < copies.size(); ++index) {
        const TileCopy& copy = copies[index];
        tbb::parallel_for(std::size_t(0), copy.mesh->points.size(), [&](std::size_t point) {
            const openvdb::Vec3s texel = copy.mesh->points[point];
            const glm::dvec2 uv(
                wrapped((copy.originTexels.x + texel.x()) / texelsPerUv.x, uvMin.x, stats.wrapsU),
                wrapped((copy.originTexels.y + texel.y()) / texelsPerUv.y, uvMin.y, stats.wrapsV));
            std::uint32_t triangle = 0;
            glm::dvec3 weights(0.0);
            locator.locate(uv, triangle, weights);  // the chart has area (checked above)
            const double below = shell.depthWorld * (1.0 - double(texel.z()) / depthTexels);
            const glm::uvec3& corners = shell.triangles[triangle];
            glm::dvec3 world(0.0);
            for (int corner = 0; corner < 3; ++corner) {
                world += weights[corner] * (glm::dvec3(shell.positions[corners[corner]]) -
                                            glm::dvec3(shell.normals[corners[corner]]) * below);
            }
            points[firstPoint[index] + point] =
                openvdb::Vec3s(float(world.x), float(world.y), float(world.z));
        });
    }
    copies.clear();
    edgeMeshes.clear();
    tileMesh = {};
    stats.meshVertices = points.size();
    stats.meshPolygons = triangles.size() + quads.size();

    stats.surfaceSeconds = secondsSince(start);
    const auto levelSetStart = std::chrono::steady_clock::now();

    // 5. The world-space level set.
    stats.texelSizeWorld = medianTexelSizeWorld(shell, tile);
    stats.voxelSizeWorld = stats.texelSizeWorld / options.voxelsPerTexel;
    const auto worldTransform =
        openvdb::math::Transform::createLinearTransform(stats.voxelSizeWorld);
    impl->grid = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(
        *worldTransform, points, triangles, quads, options.halfBandVoxels);
    stats.levelSetSeconds = secondsSince(levelSetStart);
    stats.activeVoxels = impl->grid->activeVoxelCount();
    stats.memoryBytes = impl->grid->memUsage();
    if (stats.activeVoxels == 0) reject("detail", "its surface is empty inside the shell");
    impl->intersector =
        std::make_unique<openvdb::tools::LevelSetRayIntersector<openvdb::FloatGrid>>(*impl->grid);
    return DisplacedLevelSet(std::move(impl));
}

bool DisplacedLevelSet::intersect(const glm::dvec3& origin, const glm::dvec3& unitDirection,
                                  double maxDistanceWorld, double& distanceWorld,
                                  glm::dvec3& normalWorld) const {
    // The intersector keeps per-query state: every call works on its own copy.
    auto intersector = *impl_->intersector;
    using RayT = openvdb::math::Ray<double>;
    const RayT ray(openvdb::Vec3d(origin.x, origin.y, origin.z),
                   openvdb::Vec3d(unitDirection.x, unitDirection.y, unitDirection.z), 0.0,
                   maxDistanceWorld);
    openvdb::Vec3d world, normal;
    if (!intersector.intersectsWS(ray, world, normal)) return false;
    const glm::dvec3 hit(world.x(), world.y(), world.z());
    distanceWorld = glm::dot(hit - origin, unitDirection);
    const double length = normal.length();
    normalWorld =
        length > 0.0 ? glm::dvec3(normal.x(), normal.y(), normal.z()) / length : -unitDirection;
    return true;
}

}  // namespace distile
