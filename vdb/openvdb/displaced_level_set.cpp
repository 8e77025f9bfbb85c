// The OpenVDB half of vdb/displaced_level_set.h, in the module (vdb/detail/openvdb_module.h).
#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/RayIntersector.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "common/error.h"
#include "common/position_weld.h"
#include "vdb/openvdb/openvdb_parts.h"

namespace distile::detail {

namespace {

void reject(const std::string& what, const std::string& why) {
    throw InputError("world reference mesh: " + what + ": " + why);
}

template <int N>
bool isFinite(const glm::vec<N, float>& value) {
    for (int axis = 0; axis < N; ++axis) {
        if (!std::isfinite(value[axis])) return false;
    }
    return true;
}

void validateInput(const Size3& tile, const DisplacementShell& shell,
                   const DisplacedMeshOptions& options) {
    validateTileSize(tile, "world reference mesh: tile size");
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
    if (!(options.memoryBudgetBytes > 0.0)) reject("memory budget", "it must be > 0 bytes");
}

double cross2(const glm::dvec2& a, const glm::dvec2& b) {
    return a.x * b.y - a.y * b.x;
}

/// Lexicographic order of points (x, then y, then z): the order in which a cut between two
/// points is computed, so both triangles beside an edge compute the same bits.
template <class Vec>
bool lexicographicLess(const Vec& a, const Vec& b) {
    for (int axis = 0; axis < Vec::length(); ++axis) {
        if (a[axis] != b[axis]) return a[axis] < b[axis];
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

/// Polygons of the detail's zero isosurface over one tile, in texels: quads, and triangles as
/// quads whose last index is kNoCorner.
struct TileMesh {
    static constexpr unsigned kNoCorner = ~0u;
    std::vector<glm::dvec3> points;
    std::vector<glm::uvec4> polygons;
    /// How far its polygons reach out of the tile [0, W) x [0, H) (whole polygons are kept by
    /// their centroid), texels per axis: a repeat also covers this much of its neighbours.
    glm::dvec2 overhangTexels{0.0};
};

/// The detail on one tile's lattice (periodic in x and y), with the floor and the top applied.
class TileLattice {
  public:
    /// Lattice samples below z = 0 and above z = D (texels): the field is positive there.
    static constexpr int kMarginTexels = 2;
    // The solid floor's slab (kFloorSlabTexels) ends between lattice samples, so a sample
    // inside it is negative.

    TileLattice(const DetailDistanceFunction& detail, const Size3& tile, int samplesPerTexel,
                bool solidFloor)
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
    long long countZ() const { return countZ_; }
    double zOf(long long k) const { return double(firstZ_ + k) * spacing_; }

    /// The clipped field (detail, floor, top) at a texel position, trilinear between the
    /// lattice's samples in x and y, at the lattice's z sample `k`.
    double clippedAt(const glm::dvec2& texel, long long k) const {
        const double fx = texel.x / spacing_, fy = texel.y / spacing_;
        const double floorX = std::floor(fx), floorY = std::floor(fy);
        const double tx = fx - floorX, ty = fy - floorY;
        const long long i0 = positiveModulo((long long)floorX, countX_);
        const long long j0 = positiveModulo((long long)floorY, countY_);
        const long long i1 = (i0 + 1) % countX_, j1 = (j0 + 1) % countY_;
        const double low =
            (1.0 - tx) * distances_[index(i0, j0, k)] + tx * distances_[index(i1, j0, k)];
        const double high =
            (1.0 - tx) * distances_[index(i0, j1, k)] + tx * distances_[index(i1, j1, k)];
        return clipped((1.0 - ty) * low + ty * high, zOf(k));
    }

    /// The isosurface of one whole tile: the polygons whose centroid lies in [0, W) x [0, H)
    /// (texels). Extracted from the lattice padded by a few samples around the tile, so every
    /// polygon is complete; repeats of it placed side by side meet without gaps or overlaps.
    TileMesh extractTile() const {
        constexpr long long kPadSamples = 3;
        const float bandTexels = float(2.0 * spacing_);
        auto grid = openvdb::FloatGrid::create(bandTexels);
        grid->setTransform(openvdb::math::Transform::createLinearTransform(spacing_));
        auto accessor = grid->getAccessor();
        for (long long k = 0; k < countZ_; ++k) {
            const double z = zOf(k);
            for (long long j = -kPadSamples; j < countY_ + kPadSamples; ++j) {
                const long long tileJ = positiveModulo(j, countY_);
                for (long long i = -kPadSamples; i < countX_ + kPadSamples; ++i) {
                    const long long tileI = positiveModulo(i, countX_);
                    const double field = clipped(distances_[index(tileI, tileJ, k)], z);
                    if (std::abs(field) < bandTexels) {
                        accessor.setValue(openvdb::Coord(int(i), int(j), int(firstZ_ + k)),
                                          float(field));
                    }
                }
            }
        }
        openvdb::tools::signedFloodFill(grid->tree());
        std::vector<openvdb::Vec3s> points;
        std::vector<openvdb::Vec3I> triangles;
        std::vector<openvdb::Vec4I> quads;
        openvdb::tools::volumeToMesh(*grid, points, triangles, quads, 0.0, 0.0);
        grid.reset();

        // Keep the polygons whose centroid lies in the tile (a hair wider, so a centroid on its
        // edge is kept by both neighbours rather than lost to rounding; the copies coincide).
        constexpr double kTieTexels = 1e-4;
        const double width = double(countX_) * spacing_, height = double(countY_) * spacing_;
        TileMesh kept;
        std::vector<unsigned> newIndex(points.size(), TileMesh::kNoCorner);
        const auto keep = [&](const unsigned* corners, int count) {
            glm::dvec2 centroid(0.0);
            for (int c = 0; c < count; ++c) {
                centroid += glm::dvec2(points[corners[c]].x(), points[corners[c]].y());
            }
            centroid /= double(count);
            if (!(centroid.x >= -kTieTexels && centroid.x < width + kTieTexels &&
                  centroid.y >= -kTieTexels && centroid.y < height + kTieTexels)) {
                return;
            }
            glm::uvec4 polygon(TileMesh::kNoCorner);
            for (int c = 0; c < count; ++c) {
                if (newIndex[corners[c]] == TileMesh::kNoCorner) {
                    newIndex[corners[c]] = unsigned(kept.points.size());
                    const openvdb::Vec3s& p = points[corners[c]];
                    kept.points.emplace_back(p.x(), p.y(), p.z());
                }
                polygon[c] = newIndex[corners[c]];
            }
            kept.polygons.push_back(polygon);
        };
        for (const openvdb::Vec3I& t : triangles) keep(t.asPointer(), 3);
        for (const openvdb::Vec4I& q : quads) keep(q.asPointer(), 4);
        for (const glm::dvec3& point : kept.points) {
            kept.overhangTexels = glm::max(
                kept.overhangTexels,
                glm::max(-glm::dvec2(point), glm::dvec2(point) - glm::dvec2(width, height)));
        }
        return kept;
    }

  private:
    std::size_t index(long long i, long long j, long long k) const {
        return std::size_t(i + countX_ * (j + countY_ * k));
    }

    double clipped(double detail, double z) const {
        return clippedDetailTexels(detail, z, depthTexels_, solidFloor_);
    }

    double spacing_;
    long long countX_, countY_;  ///< samples per tile period
    long long firstZ_, countZ_;  ///< z = (firstZ_ + k) * spacing_ for k in [0, countZ_)
    double depthTexels_;
    bool solidFloor_;
    std::vector<float> distances_;  ///< x fastest, then y, then z
};

/// The tile mesh's polygons binned on a grid of cells by their first corner, to find those
/// near a base triangle.
class TileMeshCells {
  public:
    static constexpr double kCellTexels = 8.0;

    TileMeshCells(const TileMesh& mesh, const glm::dvec2& tileTexels) {
        cellsX_ = std::max(1, int(std::ceil(tileTexels.x / kCellTexels)));
        cellsY_ = std::max(1, int(std::ceil(tileTexels.y / kCellTexels)));
        std::vector<std::uint32_t> cellOfPolygon(mesh.polygons.size());
        firstOfCell_.assign(std::size_t(cellsX_) * cellsY_ + 1, 0);
        for (std::size_t index = 0; index < mesh.polygons.size(); ++index) {
            const glm::uvec4& polygon = mesh.polygons[index];
            const glm::dvec2 first(mesh.points[polygon[0]]);
            for (int corner = 0; corner < 4 && polygon[corner] != TileMesh::kNoCorner; ++corner) {
                const glm::dvec2 offset =
                    glm::abs(glm::dvec2(mesh.points[polygon[corner]]) - first);
                reachTexels_ = std::max({reachTexels_, offset.x, offset.y});
            }
            const glm::ivec2 cell = cellOf(first);
            cellOfPolygon[index] = std::uint32_t(cell.x + cellsX_ * cell.y);
            ++firstOfCell_[cellOfPolygon[index] + 1];
        }
        for (std::size_t cell = 1; cell < firstOfCell_.size(); ++cell) {
            firstOfCell_[cell] += firstOfCell_[cell - 1];
        }
        polygonsByCell_.resize(mesh.polygons.size());
        std::vector<std::uint32_t> next(firstOfCell_.begin(), firstOfCell_.end() - 1);
        for (std::size_t index = 0; index < mesh.polygons.size(); ++index) {
            polygonsByCell_[next[cellOfPolygon[index]]++] = std::uint32_t(index);
        }
    }

    /// Calls function(polygon index) for every polygon that may overlap [low, high] (texels in
    /// the tile's own coordinates), each once, in a fixed order.
    template <class Function>
    void forEachNear(const glm::dvec2& low, const glm::dvec2& high, Function&& function) const {
        const glm::ivec2 first = cellOf(low - reachTexels_), last = cellOf(high + reachTexels_);
        for (int y = first.y; y <= last.y; ++y) {
            for (int x = first.x; x <= last.x; ++x) {
                const std::size_t cell = std::size_t(x + cellsX_ * y);
                for (std::uint32_t slot = firstOfCell_[cell]; slot < firstOfCell_[cell + 1];
                     ++slot) {
                    function(polygonsByCell_[slot]);
                }
            }
        }
    }

  private:
    glm::ivec2 cellOf(const glm::dvec2& texel) const {
        const glm::dvec2 cell = glm::floor(texel / kCellTexels);
        return {std::clamp(int(std::clamp(cell.x, -1.0, double(cellsX_))), 0, cellsX_ - 1),
                std::clamp(int(std::clamp(cell.y, -1.0, double(cellsY_))), 0, cellsY_ - 1)};
    }

    int cellsX_ = 1, cellsY_ = 1;
    double reachTexels_ = 0.0;  ///< farthest any corner of a polygon is from its first, per axis
    std::vector<std::uint32_t> firstOfCell_;
    std::vector<std::uint32_t> polygonsByCell_;
};

/// One base triangle's map from texel space to world space (the shell), with its edges.
class ShellTriangleMap {
  public:
    ShellTriangleMap(const DisplacementShell& shell, std::uint32_t triangle,
                     const glm::dvec2& texelsPerUv, double depthTexels)
        : depthWorld_(shell.depthWorld), depthTexels_(depthTexels) {
        const glm::uvec3& corners = shell.triangles[triangle];
        for (int c = 0; c < 3; ++c) {
            corner_[c] = glm::dvec2(shell.uvs[corners[c]]) * texelsPerUv;
            top_[c] = glm::dvec3(shell.positions[corners[c]]);
            normal_[c] = glm::dvec3(shell.normals[corners[c]]);
        }
        area_ = cross2(corner_[1] - corner_[0], corner_[2] - corner_[0]);
        for (int edge = 0; edge < 3; ++edge) {
            int a = edge, b = (edge + 1) % 3;
            if (lexicographicLess(corner_[b], corner_[a])) std::swap(a, b);
            edgeFrom_[edge] = a;
            edgeTo_[edge] = b;
            // Inside is where the opposite corner is.
            edgeSign_[edge] = lineValue(edge, corner_[3 - a - b]) > 0.0 ? 1.0 : -1.0;
        }
    }

    /// The triangle has a uv area to carry detail (a hair more than rounding).
    bool hasArea() const {
        const double scale =
            glm::length(corner_[1] - corner_[0]) * glm::length(corner_[2] - corner_[0]);
        return std::abs(area_) > 1e-9 * scale && scale > 0.0;
    }
    /// The triangle's area in texel space, texels squared.
    double texelArea() const { return 0.5 * std::abs(area_); }
    glm::dvec2 low() const { return glm::min(corner_[0], glm::min(corner_[1], corner_[2])); }
    glm::dvec2 high() const { return glm::max(corner_[0], glm::max(corner_[1], corner_[2])); }
    glm::dvec2 corner(int c) const { return corner_[c]; }
    int edgeFrom(int edge) const { return edgeFrom_[edge]; }
    int edgeTo(int edge) const { return edgeTo_[edge]; }

    /// > 0 inside edge `edge`'s half-plane; bit for bit the negation of the value the triangle
    /// on the other side of the edge computes.
    double inside(int edge, const glm::dvec2& texel) const {
        return edgeSign_[edge] * lineValue(edge, texel);
    }

    /// World position of a texel-space point, by the triangle's barycentrics (extrapolated
    /// linearly outside it).
    glm::dvec3 map(const glm::dvec3& texel) const {
        const glm::dvec2 p(texel);
        const double b1 = cross2(p - corner_[0], corner_[2] - corner_[0]) / area_;
        const double b2 = cross2(corner_[1] - corner_[0], p - corner_[0]) / area_;
        const double weights[3] = {1.0 - b1 - b2, b1, b2};
        glm::dvec3 world(0.0);
        for (int c = 0; c < 3; ++c) world += weights[c] * shellPoint(c, texel.z);
        return world;
    }

    /// World position of a texel-space point on edge `edge`, from the edge's two corners only,
    /// so the triangle on the other side maps it to the same bits.
    glm::dvec3 mapOnEdge(int edge, const glm::dvec3& texel) const {
        const int a = edgeFrom_[edge], b = edgeTo_[edge];
        const glm::dvec2 along = corner_[b] - corner_[a];
        const double t = glm::dot(glm::dvec2(texel) - corner_[a], along) / glm::dot(along, along);
        return (1.0 - t) * shellPoint(a, texel.z) + t * shellPoint(b, texel.z);
    }

  private:
    double lineValue(int edge, const glm::dvec2& p) const {
        const glm::dvec2 a = corner_[edgeFrom_[edge]], b = corner_[edgeTo_[edge]];
        return cross2(b - a, p - a);
    }
    glm::dvec3 shellPoint(int c, double zTexels) const {
        return top_[c] - normal_[c] * (depthWorld_ * (1.0 - zTexels / depthTexels_));
    }

    glm::dvec2 corner_[3];
    glm::dvec3 top_[3], normal_[3];
    double area_ = 0.0;
    int edgeFrom_[3] = {}, edgeTo_[3] = {};
    double edgeSign_[3] = {};
    double depthWorld_, depthTexels_;
};

/// Which edges of the base triangles are open borders: not shared by another triangle with a uv
/// area (edges matched by their corners' welded world positions, so a uv seam is not a border).
std::vector<std::array<bool, 3>> findBorderEdges(const DisplacementShell& shell,
                                                 const std::vector<bool>& hasArea) {
    // Corners by their welded position (common/position_weld.h), as the renderer joins prisms.
    const std::vector<std::uint32_t> point = weldedPositionGroups(shell.positions, shell.triangles);
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> uses;
    const auto key = [&](const glm::uvec3& t, int edge) {
        const std::uint32_t a = point[t[edge]], b = point[t[(edge + 1) % 3]];
        return std::make_pair(std::min(a, b), std::max(a, b));
    };
    for (std::size_t index = 0; index < shell.triangles.size(); ++index) {
        if (!hasArea[index]) continue;
        for (int edge = 0; edge < 3; ++edge) ++uses[key(shell.triangles[index], edge)];
    }
    std::vector<std::array<bool, 3>> border(shell.triangles.size(), {false, false, false});
    for (std::size_t index = 0; index < shell.triangles.size(); ++index) {
        if (!hasArea[index]) continue;
        for (int edge = 0; edge < 3; ++edge)
            border[index][edge] = uses[key(shell.triangles[index], edge)] == 1;
    }
    return border;
}

/// The world-space polygons one base triangle carries.
struct TrianglePieces {
    std::vector<glm::vec3> positions, texelPositions;
    std::vector<glm::uvec3> triangles;
    std::vector<glm::uvec4> quads;

    unsigned addVertex(const glm::dvec3& world, const glm::dvec3& texel) {
        positions.emplace_back(world);
        texelPositions.emplace_back(texel);
        return unsigned(positions.size() - 1);
    }
};

/// A corner of a clipped polygon: texel position and the base edge it was cut on (-1: none).
struct ClipCorner {
    glm::dvec3 texel;
    int edge = -1;
};

/// Clips `polygon` to the half-plane inside base edge `edge` into `out`. A cut point is computed
/// from its segment's two ends in lexicographic order, so the neighbour across the edge computes
/// the same bits.
void clipToEdge(const ShellTriangleMap& map, int edge, const std::vector<ClipCorner>& polygon,
                std::vector<ClipCorner>& out) {
    out.clear();
    const std::size_t count = polygon.size();
    for (std::size_t index = 0; index < count; ++index) {
        const ClipCorner& current = polygon[index];
        const ClipCorner& next = polygon[(index + 1) % count];
        const double dCurrent = map.inside(edge, glm::dvec2(current.texel));
        const double dNext = map.inside(edge, glm::dvec2(next.texel));
        if (dCurrent >= 0.0) out.push_back(current);
        if ((dCurrent >= 0.0) == (dNext >= 0.0)) continue;
        const bool currentFirst = lexicographicLess(current.texel, next.texel);
        const ClipCorner& p = currentFirst ? current : next;
        const ClipCorner& q = currentFirst ? next : current;
        const double dP = currentFirst ? dCurrent : dNext;
        const double dQ = currentFirst ? dNext : dCurrent;
        out.push_back({p.texel + (q.texel - p.texel) * (dP / (dP - dQ)), edge});
    }
}

/// Per-thread working memory of mapTriangle: which tile-mesh point became which vertex of the
/// current tile repeat (stamped, so nothing is cleared between repeats).
struct MapScratch {
    std::vector<std::uint32_t> stamp, vertex;
    std::uint32_t currentStamp = 0;
    std::vector<ClipCorner> polygon, clipped;
};

/// The detail of one base triangle: the tile repeats over its uv triangle clipped to it and
/// mapped, and walls on its border edges.
void mapTriangle(const ShellTriangleMap& map, const std::array<bool, 3>& border,
                 const TileMesh& tileMesh, const TileMeshCells& cells, const TileLattice& lattice,
                 const glm::dvec2& tileTexels, MapScratch& scratch, TrianglePieces& pieces) {
    const glm::dvec2 low = map.low(), high = map.high();
    // The repeats that reach the triangle, also those whose polygons only hang over into it
    // (a triangle whose uvs start on a tile's border takes the wires crossing it from both).
    const auto firstCopy =
        glm::vec<2, long long>(glm::floor((low - tileMesh.overhangTexels) / tileTexels));
    const auto lastCopy =
        glm::vec<2, long long>(glm::floor((high + tileMesh.overhangTexels) / tileTexels));
    if (scratch.stamp.size() != tileMesh.points.size()) {
        scratch.stamp.assign(tileMesh.points.size(), 0);
        scratch.vertex.assign(tileMesh.points.size(), 0);
        scratch.currentStamp = 0;
    }
    for (long long copyY = firstCopy.y; copyY <= lastCopy.y; ++copyY) {
        for (long long copyX = firstCopy.x; copyX <= lastCopy.x; ++copyX) {
            const glm::dvec2 origin = glm::dvec2(double(copyX), double(copyY)) * tileTexels;
            const glm::dvec3 origin3(origin, 0.0);
            if (++scratch.currentStamp == 0) {
                std::fill(scratch.stamp.begin(), scratch.stamp.end(), 0);
                scratch.currentStamp = 1;
            }
            const auto shared = [&](unsigned point) {
                if (scratch.stamp[point] != scratch.currentStamp) {
                    scratch.stamp[point] = scratch.currentStamp;
                    const glm::dvec3 texel = tileMesh.points[point] + origin3;
                    scratch.vertex[point] = pieces.addVertex(map.map(texel), texel);
                }
                return scratch.vertex[point];
            };
            cells.forEachNear(low - origin, high - origin, [&](std::uint32_t index) {
                const glm::uvec4& polygon = tileMesh.polygons[index];
                const int count = polygon[3] == TileMesh::kNoCorner ? 3 : 4;
                glm::dvec2 polygonLow(std::numeric_limits<double>::max());
                glm::dvec2 polygonHigh(-std::numeric_limits<double>::max());
                for (int c = 0; c < count; ++c) {
                    const glm::dvec2 p = glm::dvec2(tileMesh.points[polygon[c]]) + origin;
                    polygonLow = glm::min(polygonLow, p);
                    polygonHigh = glm::max(polygonHigh, p);
                }
                if (polygonHigh.x < low.x || polygonHigh.y < low.y || polygonLow.x > high.x ||
                    polygonLow.y > high.y) {
                    return;
                }
                bool allInside = true;
                for (int edge = 0; edge < 3; ++edge) {
                    int outside = 0;
                    for (int c = 0; c < count; ++c) {
                        const glm::dvec2 p = glm::dvec2(tileMesh.points[polygon[c]]) + origin;
                        if (map.inside(edge, p) < 0.0) ++outside;
                    }
                    if (outside == count) return;  // wholly outside this edge
                    if (outside > 0) allInside = false;
                }
                if (allInside) {
                    if (count == 3) {
                        pieces.triangles.emplace_back(shared(polygon[0]), shared(polygon[1]),
                                                      shared(polygon[2]));
                    } else {
                        pieces.quads.emplace_back(shared(polygon[0]), shared(polygon[1]),
                                                  shared(polygon[2]), shared(polygon[3]));
                    }
                    return;
                }
                scratch.polygon.clear();
                for (int c = 0; c < count; ++c) {
                    scratch.polygon.push_back({tileMesh.points[polygon[c]] + origin3, -1});
                }
                for (int edge = 0; edge < 3; ++edge) {
                    clipToEdge(map, edge, scratch.polygon, scratch.clipped);
                    std::swap(scratch.polygon, scratch.clipped);
                    if (scratch.polygon.size() < 3) return;
                }
                const unsigned first = unsigned(pieces.positions.size());
                for (const ClipCorner& corner : scratch.polygon) {
                    pieces.addVertex(corner.edge >= 0 ? map.mapOnEdge(corner.edge, corner.texel)
                                                      : map.map(corner.texel),
                                     corner.texel);
                }
                for (unsigned c = 1; c + 1 < scratch.polygon.size(); ++c) {
                    pieces.triangles.emplace_back(first, first + c, first + c + 1);
                }
            });
        }
    }

    // Walls: the detail's cross-section on each border edge, from the lattice sampled along the
    // edge (trilinear in x and y) at its z samples; each cell of that (along, z) grid is split
    // into two triangles, each cut to where the field is <= 0 (linear on the triangle).
    for (int edge = 0; edge < 3; ++edge) {
        if (!border[edge]) continue;
        const glm::dvec2 a = map.corner(map.edgeFrom(edge)), b = map.corner(map.edgeTo(edge));
        const auto steps =
            std::max<long long>(1, (long long)std::ceil(glm::length(b - a) / lattice.spacing()));
        const long long countZ = lattice.countZ();
        std::vector<double> field(std::size_t((steps + 1) * countZ));
        for (long long step = 0; step <= steps; ++step) {
            const glm::dvec2 texel = a + (b - a) * (double(step) / double(steps));
            for (long long k = 0; k < countZ; ++k)
                field[std::size_t(step * countZ + k)] = lattice.clippedAt(texel, k);
        }
        struct Node {
            long long step, k;
        };
        const auto value = [&](const Node& n) { return field[std::size_t(n.step * countZ + n.k)]; };
        const auto texelOf = [&](double step, double z) {
            return glm::dvec3(a + (b - a) * (step / double(steps)), z);
        };
        std::array<glm::dvec3, 4> cut;
        for (long long step = 0; step < steps; ++step) {
            for (long long k = 0; k + 1 < countZ; ++k) {
                const Node cell[4] = {{step, k}, {step + 1, k}, {step + 1, k + 1}, {step, k + 1}};
                for (const std::array<int, 3>& half : {std::array<int, 3>{0, 1, 2}, {0, 2, 3}}) {
                    int cutCount = 0;
                    for (int c = 0; c < 3; ++c) {
                        const Node& n = cell[half[c]];
                        const Node& m = cell[half[(c + 1) % 3]];
                        const double vn = value(n), vm = value(m);
                        if (vn <= 0.0) cut[cutCount++] = texelOf(double(n.step), lattice.zOf(n.k));
                        if ((vn <= 0.0) == (vm <= 0.0)) continue;
                        const double t = vn / (vn - vm);
                        cut[cutCount++] =
                            texelOf(double(n.step) + t * double(m.step - n.step),
                                    lattice.zOf(n.k) + t * (lattice.zOf(m.k) - lattice.zOf(n.k)));
                    }
                    if (cutCount < 3) continue;
                    const unsigned first = unsigned(pieces.positions.size());
                    for (int c = 0; c < cutCount; ++c) {
                        pieces.addVertex(map.mapOnEdge(edge, cut[std::size_t(c)]),
                                         cut[std::size_t(c)]);
                    }
                    for (int c = 1; c + 1 < cutCount; ++c) {
                        pieces.triangles.emplace_back(first, first + unsigned(c),
                                                      first + unsigned(c) + 1);
                    }
                }
            }
        }
    }
}

}  // namespace

/// Memory a world-space detail mesh takes at its peak, per polygon the covered tile area
/// predicts, bytes. The mesh (vertex positions in world and texel space, polygons, their base
/// triangles), the per-triangle pieces it is joined from and Embree's BVH over it peaked at
/// 150-170 bytes per polygon in the world reference of the example scenes and the demo; clipping
/// to the base triangles makes 1.0-1.7 times the polygons the covered area predicts.
constexpr double kBytesPerEstimatedPolygon = 300.0;

DisplacedMesh buildDisplacedMesh(const DetailDistanceFunction& detail, const Size3& tile,
                                 const DisplacementShell& shell,
                                 const DisplacedMeshOptions& options) {
    validateInput(tile, shell, options);
    openvdb::initialize();
    DisplacedMesh mesh;
    DisplacedMeshStats& stats = mesh.stats;
    stats.texelSizeWorld = medianTexelSizeWorld(shell, tile);

    // 1. The detail on one tile's lattice, sampled once (multi-threaded), and its isosurface.
    auto start = std::chrono::steady_clock::now();
    const TileLattice lattice(detail, tile, options.samplesPerTexel, shell.solidFloor);
    stats.latticeSeconds = secondsSince(start);
    start = std::chrono::steady_clock::now();
    const TileMesh tileMesh = lattice.extractTile();
    const glm::dvec2 tileTexels(tile.width, tile.height);
    const TileMeshCells cells(tileMesh, tileTexels);
    stats.tilePolygons = tileMesh.polygons.size();
    stats.extractSeconds = secondsSince(start);

    // 2. Per base triangle: the tile repeats over its uv triangle, clipped and mapped.
    start = std::chrono::steady_clock::now();
    const glm::dvec2 texelsPerUv = shell.uvScale * tileTexels;
    const double depthTexels = double(tile.depth);
    const std::size_t triangleCount = shell.triangles.size();
    std::vector<bool> hasArea(triangleCount);
    double repeats = 0.0, coveredTexels = 0.0;
    for (std::size_t index = 0; index < triangleCount; ++index) {
        const ShellTriangleMap map(shell, std::uint32_t(index), texelsPerUv, depthTexels);
        hasArea[index] = map.hasArea();
        if (!hasArea[index]) continue;
        coveredTexels += map.texelArea();
        const glm::dvec2 copies =
            glm::floor(map.high() / tileTexels) - glm::floor(map.low() / tileTexels) + 1.0;
        repeats += copies.x * copies.y;
    }
    constexpr double kMaxRepeats = 1 << 16;
    if (repeats > kMaxRepeats) {
        reject("uv scale", "the base triangles hold " + std::to_string((long long)repeats) +
                               " tile repeats; at most 65536 are accepted");
    }
    const double estimatedPolygons =
        coveredTexels / (tileTexels.x * tileTexels.y) * double(stats.tilePolygons);
    stats.estimatedBytes = estimatedPolygons * kBytesPerEstimatedPolygon;
    if (!(stats.estimatedBytes <= options.memoryBudgetBytes)) {
        char message[300];
        std::snprintf(message, sizeof message,
                      "the detail over the base triangles (%.4g tile repeats of %zu polygons) "
                      "needs about %.1f GB with its BVH; %.1f GB is accepted",
                      coveredTexels / (tileTexels.x * tileTexels.y), stats.tilePolygons,
                      stats.estimatedBytes / 1e9, options.memoryBudgetBytes / 1e9);
        reject("uv scale and tile size", message);
    }
    if (options.estimateOnly) return mesh;
    const std::vector<std::array<bool, 3>> border = findBorderEdges(shell, hasArea);
    for (const auto& edges : border) {
        stats.borderEdges += std::size_t(edges[0]) + std::size_t(edges[1]) + std::size_t(edges[2]);
    }
    std::vector<TrianglePieces> pieces(triangleCount);
    tbb::enumerable_thread_specific<MapScratch> scratches;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, triangleCount), [&](const auto& range) {
        MapScratch& scratch = scratches.local();
        for (std::size_t index = range.begin(); index != range.end(); ++index) {
            if (!hasArea[index]) continue;
            const ShellTriangleMap map(shell, std::uint32_t(index), texelsPerUv, depthTexels);
            mapTriangle(map, border[index], tileMesh, cells, lattice, tileTexels, scratch,
                        pieces[index]);
        }
    });

    // 3. The pieces joined in triangle order (the same mesh for any thread count).
    std::vector<std::size_t> firstVertex(triangleCount + 1, 0), firstTriangle(triangleCount + 1, 0),
        firstQuad(triangleCount + 1, 0);
    for (std::size_t index = 0; index < triangleCount; ++index) {
        firstVertex[index + 1] = firstVertex[index] + pieces[index].positions.size();
        firstTriangle[index + 1] = firstTriangle[index] + pieces[index].triangles.size();
        firstQuad[index + 1] = firstQuad[index] + pieces[index].quads.size();
    }
    if (firstVertex.back() > std::size_t(std::numeric_limits<std::uint32_t>::max())) {
        reject("detail", "the world-space mesh would have more than 2^32 vertices");
    }
    mesh.positions.resize(firstVertex.back());
    mesh.texelPositions.resize(firstVertex.back());
    mesh.triangles.resize(firstTriangle.back());
    mesh.triangleBase.resize(firstTriangle.back());
    mesh.quads.resize(firstQuad.back());
    mesh.quadBase.resize(firstQuad.back());
    tbb::parallel_for(std::size_t(0), triangleCount, [&](std::size_t index) {
        TrianglePieces& own = pieces[index];
        const auto offset = unsigned(firstVertex[index]);
        std::copy(own.positions.begin(), own.positions.end(),
                  mesh.positions.begin() + std::ptrdiff_t(firstVertex[index]));
        std::copy(own.texelPositions.begin(), own.texelPositions.end(),
                  mesh.texelPositions.begin() + std::ptrdiff_t(firstVertex[index]));
        for (std::size_t t = 0; t < own.triangles.size(); ++t) {
            mesh.triangles[firstTriangle[index] + t] = own.triangles[t] + offset;
            mesh.triangleBase[firstTriangle[index] + t] = std::uint32_t(index);
        }
        for (std::size_t q = 0; q < own.quads.size(); ++q) {
            mesh.quads[firstQuad[index] + q] = own.quads[q] + offset;
            mesh.quadBase[firstQuad[index] + q] = std::uint32_t(index);
        }
        own = TrianglePieces{};
    });
    stats.mapSeconds = secondsSince(start);
    stats.meshVertices = mesh.positions.size();
    stats.meshPolygons = mesh.triangles.size() + mesh.quads.size();
    if (stats.meshPolygons == 0) reject("detail", "its surface is empty inside the shell");
    return mesh;
}

namespace {

/// A DisplacedMesh as OpenVDB's mesh-to-volume conversion reads it (its MeshDataAdapter
/// interface): triangles first, then quads, points in the grid's index space.
class MeshAdapter {
  public:
    MeshAdapter(const DisplacedMesh& mesh, const openvdb::math::Transform& transform)
        : mesh_(mesh), transform_(transform) {}
    std::size_t polygonCount() const { return mesh_.triangles.size() + mesh_.quads.size(); }
    std::size_t pointCount() const { return mesh_.positions.size(); }
    std::size_t vertexCount(std::size_t polygon) const {
        return polygon < mesh_.triangles.size() ? 3 : 4;
    }
    void getIndexSpacePoint(std::size_t polygon, std::size_t corner, openvdb::Vec3d& point) const {
        const std::size_t triangles = mesh_.triangles.size();
        const unsigned vertex = polygon < triangles ? mesh_.triangles[polygon][int(corner)]
                                                    : mesh_.quads[polygon - triangles][int(corner)];
        const glm::vec3& p = mesh_.positions[vertex];
        point = transform_.worldToIndex(openvdb::Vec3d(p.x, p.y, p.z));
    }

  private:
    const DisplacedMesh& mesh_;
    const openvdb::math::Transform& transform_;
};

/// A displaced mesh's world level set, with OpenVDB's ray intersector.
class OpenVdbDisplacedGrid final : public DisplacedGrid {
  public:
    explicit OpenVdbDisplacedGrid(openvdb::FloatGrid::Ptr grid)
        : grid_(std::move(grid)), intersector_(*grid_) {}

    bool intersect(const glm::dvec3& origin, const glm::dvec3& unitDirection,
                   double maxDistanceWorld, double& distanceWorld,
                   glm::dvec3& normalWorld) const override {
        // The intersector keeps per-query state: every call works on its own copy.
        auto intersector = intersector_;
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

  private:
    openvdb::FloatGrid::Ptr grid_;
    openvdb::tools::LevelSetRayIntersector<openvdb::FloatGrid> intersector_;
};

}  // namespace

BuiltDisplacedLevelSet buildDisplacedLevelSet(const DisplacedMesh& mesh,
                                              const DisplacedLevelSetOptions& options) {
    validateDisplacedLevelSetOptions(options);
    if (mesh.triangles.empty() && mesh.quads.empty()) reject("detail", "the mesh is empty");
    openvdb::initialize();
    BuiltDisplacedLevelSet built;
    DisplacedLevelSetStats& stats = built.stats;
    stats.mesh = mesh.stats;
    const auto start = std::chrono::steady_clock::now();
    // The voxels per texel as vdb/displaced_level_set.cpp resolved and checked them against the
    // build budget (the automatic choice made).
    if (options.voxelsPerTexel == 0.0) {
        throw InternalError("the displaced level set's resolution reached the module unresolved");
    }
    stats.voxelsPerTexel = options.voxelsPerTexel;
    stats.voxelSizeWorld = mesh.stats.texelSizeWorld / stats.voxelsPerTexel;
    const auto transform = openvdb::math::Transform::createLinearTransform(stats.voxelSizeWorld);
    openvdb::FloatGrid::Ptr grid = openvdb::tools::meshToVolume<openvdb::FloatGrid>(
        MeshAdapter(mesh, *transform), *transform, options.halfBandVoxels, options.halfBandVoxels);
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    stats.levelSetSeconds = secondsSince(start);
    stats.activeVoxels = grid->activeVoxelCount();
    stats.memoryBytes = grid->memUsage();
    if (stats.activeVoxels == 0) reject("detail", "its surface is empty inside the shell");
    built.grid = std::make_unique<OpenVdbDisplacedGrid>(grid);
    return built;
}

}  // namespace distile::detail
