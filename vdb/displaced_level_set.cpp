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
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>
#include <map>
#include <string>
#include <tuple>
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

/// One axis of the texel-space lattice: samples first + i * spacing for i in [0, count).
struct LatticeAxis {
    long long firstIndex = 0;  ///< first sample's position / spacing (an integer)
    long long count = 0;
    double capLow = -std::numeric_limits<double>::infinity();  ///< wall (texels), if any
    double capHigh = std::numeric_limits<double>::infinity();
};

LatticeAxis latticeAxis(double lowTexels, double highTexels, double spacing, bool wraps) {
    LatticeAxis axis;
    if (wraps) {  // seam vertices must coincide: samples exactly at both ends, no wall
        axis.firstIndex = std::llround(lowTexels / spacing);
        axis.count = std::llround(highTexels / spacing) - axis.firstIndex + 1;
        return axis;
    }
    constexpr int kPadding = 2;  // samples beyond the wall, so it is extracted
    axis.firstIndex = (long long)(std::floor(lowTexels / spacing)) - kPadding;
    axis.count = (long long)(std::ceil(highTexels / spacing)) + kPadding - axis.firstIndex + 1;
    // The walls sit a hair inside the chart, so their vertices map inside it.
    axis.capLow = lowTexels + 1e-3 * spacing;
    axis.capHigh = highTexels - 1e-3 * spacing;
    return axis;
}

long long positiveModulo(long long value, long long period) {
    const long long remainder = value % period;
    return remainder < 0 ? remainder + period : remainder;
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
    openvdb::initialize();
    auto impl = std::make_unique<Impl>();
    DisplacedLevelSetStats& stats = impl->stats;

    // 1. The detail on one tile's lattice (periodic in x and y), spacing 1 / samplesPerTexel.
    const int samples = options.samplesPerTexel;
    const double spacing = 1.0 / samples;
    const long long tileX = (long long)(tile.width) * samples;
    const long long tileY = (long long)(tile.height) * samples;
    constexpr int kMarginTexels = 2;  // below the floor slab and above the top
    // The solid floor's slab ends between lattice samples, so a sample inside it is negative.
    constexpr double kFloorSlabTexels = 1.5;
    const long long firstZ = -kMarginTexels * samples;
    const long long countZ = (long long)(tile.depth + 2 * kMarginTexels) * samples + 1;
    if (double(tileX) * double(tileY) * double(countZ) > double(1u << 31)) {
        reject("tile lattice", "more than 2^31 samples; use fewer samples per texel");
    }
    std::vector<float> tileDistances(std::size_t(tileX * tileY * countZ));
    tbb::parallel_for(tbb::blocked_range<long long>(0, countZ), [&](const auto& range) {
        for (long long k = range.begin(); k != range.end(); ++k) {
            for (long long j = 0; j < tileY; ++j) {
                for (long long i = 0; i < tileX; ++i) {
                    const glm::dvec3 texel(i * spacing, j * spacing, (firstZ + k) * spacing);
                    tileDistances[std::size_t(i + tileX * (j + tileY * k))] = float(detail(texel));
                }
            }
        }
    });

    // 2. The footprint: the chart's uv bounds in texels, walls where it does not wrap.
    const UvLocator locator(shell);
    const glm::dvec2 texelsPerUv(shell.uvScale.x * tile.width, shell.uvScale.y * tile.height);
    const glm::dvec2 uvMin = locator.uvMin(), uvMax = locator.uvMax();
    if (!(uvMax.x > uvMin.x && uvMax.y > uvMin.y)) reject("base mesh uvs", "the chart has no area");
    stats.wrapsU = chartWraps(shell, 0, uvMin.x, uvMax.x);
    stats.wrapsV = chartWraps(shell, 1, uvMin.y, uvMax.y);
    const LatticeAxis axisX =
        latticeAxis(uvMin.x * texelsPerUv.x, uvMax.x * texelsPerUv.x, spacing, stats.wrapsU);
    const LatticeAxis axisY =
        latticeAxis(uvMin.y * texelsPerUv.y, uvMax.y * texelsPerUv.y, spacing, stats.wrapsV);
    if (double(axisX.count) * double(axisY.count) * double(countZ) > double(1ull << 31)) {
        reject("footprint lattice", "more than 2^31 samples; use a smaller uv scale");
    }

    // 3. The footprint's field as a narrow-band texel-space grid (index space: lattice indices).
    const float bandTexels = float(2.0 * spacing);
    auto texelGrid = openvdb::FloatGrid::create(bandTexels);
    {
        auto transform = openvdb::math::Transform::createLinearTransform(spacing);
        transform->postTranslate(openvdb::Vec3d(double(axisX.firstIndex) * spacing,
                                                double(axisY.firstIndex) * spacing,
                                                double(firstZ) * spacing));
        texelGrid->setTransform(transform);
    }
    const double depthTexels = double(tile.depth);
    {
        auto accessor = texelGrid->getAccessor();
        for (long long j = 0; j < axisY.count; ++j) {
            const double y = double(axisY.firstIndex + j) * spacing;
            const long long tileJ = positiveModulo(axisY.firstIndex + j, tileY);
            for (long long i = 0; i < axisX.count; ++i) {
                const double x = double(axisX.firstIndex + i) * spacing;
                const long long tileI = positiveModulo(axisX.firstIndex + i, tileX);
                const double wall = std::max(
                    {axisX.capLow - x, x - axisX.capHigh, axisY.capLow - y, y - axisY.capHigh});
                for (long long k = 0; k < countZ; ++k) {
                    const double z = double(firstZ + k) * spacing;
                    double field = tileDistances[std::size_t(tileI + tileX * (tileJ + tileY * k))];
                    if (shell.solidFloor) {
                        field = std::max(std::min(field, z), -(z + kFloorSlabTexels));
                    } else {
                        field = std::max(field, -z);
                    }
                    field = std::max({field, z - depthTexels, wall});
                    if (std::abs(field) < bandTexels) {
                        accessor.setValue(openvdb::Coord(int(i), int(j), int(k)), float(field));
                    }
                }
            }
        }
    }
    tileDistances = {};
    openvdb::tools::signedFloodFill(texelGrid->tree());

    // 4. Its zero isosurface (texel space), every vertex mapped through the shell.
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(*texelGrid, points, triangles, quads, 0.0, 0.0);
    texelGrid.reset();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size()), [&](const auto& range) {
        for (std::size_t index = range.begin(); index != range.end(); ++index) {
            const openvdb::Vec3s texel = points[index];
            const glm::dvec2 uv(double(texel.x()) / texelsPerUv.x,
                                double(texel.y()) / texelsPerUv.y);
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
            points[index] = openvdb::Vec3s(float(world.x), float(world.y), float(world.z));
        }
    });
    stats.meshVertices = points.size();
    stats.meshPolygons = triangles.size() + quads.size();

    // 5. The world-space level set.
    stats.texelSizeWorld = medianTexelSizeWorld(shell, tile);
    stats.voxelSizeWorld = stats.texelSizeWorld / options.voxelsPerTexel;
    const auto worldTransform =
        openvdb::math::Transform::createLinearTransform(stats.voxelSizeWorld);
    impl->grid = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(
        *worldTransform, points, triangles, quads, options.halfBandVoxels);
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
