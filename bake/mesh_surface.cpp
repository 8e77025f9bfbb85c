#include "bake/mesh_surface.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <functional>
#include <glm/geometric.hpp>
#include <optional>
#include <unordered_map>
#include <vector>

#include "truth/mesh_truth.h"

namespace distile {

namespace {

/// Voxel-centre layers searched for caps beyond the mesh's z extent, below and above.
constexpr int kLayerMarginTexels = 2;

struct Segment {
    glm::dvec3 a, b;
};

glm::dvec3 nearestOnSegment(const glm::dvec3& p, const Segment& s) {
    const glm::dvec3 ab = s.b - s.a;
    const double squared = glm::dot(ab, ab);
    const double t = squared > 0.0 ? std::clamp(glm::dot(p - s.a, ab) / squared, 0.0, 1.0) : 0.0;
    return s.a + t * ab;
}

/// The mesh's border: its unbalanced edges (bake/soup_distance.h).
std::vector<Segment> borderSegments(const TriangleSoup& soup) {
    std::vector<Segment> border;
    for (const UnbalancedEdge& edge : unbalancedEdges(soup)) border.push_back({edge.a, edge.b});
    return border;
}

/// The border's segments in buckets of kCapBorderReachTexels, for the nearest border point
/// within that reach of a point (periodic over the tile's copies).
class BorderIndex {
  public:
    BorderIndex(std::vector<Segment> segments, const Size3& tile)
        : segments_(std::move(segments)), tile_(tile) {
        if (segments_.empty()) return;
        bounds_ = {segments_.front().a, segments_.front().a};
        for (std::uint32_t s = 0; s < segments_.size(); ++s) {
            const Segment& segment = segments_[s];
            bounds_.min = glm::min(bounds_.min, glm::min(segment.a, segment.b));
            bounds_.max = glm::max(bounds_.max, glm::max(segment.a, segment.b));
            const glm::ivec3 lo = bucketOf(glm::min(segment.a, segment.b));
            const glm::ivec3 hi = bucketOf(glm::max(segment.a, segment.b));
            for (int z = lo.z - 1; z <= hi.z + 1; ++z)
                for (int y = lo.y - 1; y <= hi.y + 1; ++y)
                    for (int x = lo.x - 1; x <= hi.x + 1; ++x)
                        buckets_[keyOf({x, y, z})].push_back(s);
        }
    }

    /// The border point nearest to `point` within kCapBorderReachTexels (ties: the first
    /// segment, the nearest copy in the order of periodicShifts); none if there is none.
    std::optional<glm::dvec3> nearest(const glm::dvec3& point) const {
        if (segments_.empty()) return std::nullopt;
        double bestSquared = kCapBorderReachTexels * kCapBorderReachTexels;
        std::optional<glm::dvec3> best;
        const PeriodicShifts shifts = periodicShifts(point, bounds_, tile_, kCapBorderReachTexels);
        for (int n = shifts.yBegin; n <= shifts.yEnd; ++n) {
            for (int m = shifts.xBegin; m <= shifts.xEnd; ++m) {
                const glm::dvec3 shift(double(m) * tile_.width, double(n) * tile_.height, 0.0);
                const auto bucket = buckets_.find(keyOf(bucketOf(point - shift)));
                if (bucket == buckets_.end()) continue;
                for (const std::uint32_t s : bucket->second) {
                    const glm::dvec3 candidate = nearestOnSegment(point - shift, segments_[s]);
                    const double squared =
                        glm::dot(candidate - (point - shift), candidate - (point - shift));
                    if (squared < bestSquared) {
                        bestSquared = squared;
                        best = candidate + shift;
                    }
                }
            }
        }
        return best;
    }

  private:
    static glm::ivec3 bucketOf(const glm::dvec3& p) {
        return glm::ivec3(glm::floor(p / kCapBorderReachTexels));
    }
    static std::uint64_t keyOf(const glm::ivec3& bucket) {
        const auto part = [](int v) { return std::uint64_t(std::uint32_t(v) & 0x1fffffu); };
        return part(bucket.x) | (part(bucket.y) << 21) | (part(bucket.z) << 42);
    }

    std::vector<Segment> segments_;
    Size3 tile_;
    Bounds3 bounds_;
    std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> buckets_;
};

/// The voxel centres searched for caps: x, y over the footprint (periodic), z over `layers`
/// layers from `firstLayer`. Index x fastest, then y, then z.
struct CapGrid {
    Size3 tile;
    int firstLayer = 0;
    int layers = 0;

    std::size_t count() const { return std::size_t(tile.width) * tile.height * layers; }
    /// Index of the centre (i, j, k) (i, j wrapped into the footprint; k from firstLayer).
    std::size_t index(int i, int j, int k) const {
        return (std::size_t(k) * tile.height + std::size_t(j % tile.height)) * tile.width +
               std::size_t(i % tile.width);
    }
    /// Position of the centre (i, j, k), not wrapped: i may be W, j may be H.
    glm::dvec3 position(int i, int j, int k) const {
        return {i + 0.5, j + 0.5, firstLayer + k + 0.5};
    }
};

/// Tetrahedron edge directions: corner bits x = 1, y = 2, z = 4, from the lower corner.
glm::dvec3 directionOf(unsigned bits) {
    return {double(bits & 1u), double((bits >> 1) & 1u), double((bits >> 2) & 1u)};
}

/// The 6 tetrahedra of a cube around its diagonal from corner 0 to corner 7: each walks from 0
/// to 7 adding one axis at a time, in one of the 6 orders. Their corners only grow (each
/// corner's bits hold the previous one's), so every edge runs from a lower to a higher corner.
constexpr std::array<std::array<unsigned, 4>, 6> kTetrahedra = {
    {{0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7}, {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}}};

/// Where w = 1/2 on the segment from `a` (w = wa) to `b` (w = wb), wa and wb on either side of
/// 1/2, as a fraction of the way: regula falsi (Illinois), which converges fast where w is smooth
/// (no triangle on the segment) and always stays in the bracket.
double levelCrossing(const SoupDistance& soup, const glm::dvec3& a, const glm::dvec3& b, double wa,
                     double wb) {
    double t0 = 0.0, f0 = wa - 0.5, t1 = 1.0, f1 = wb - 0.5;
    int kept = 0;  // which end stayed last time: +1 the upper, -1 the lower
    double t = 0.5;
    for (int iteration = 0; iteration < 64; ++iteration) {
        t = f1 != f0 ? std::clamp((t0 * f1 - t1 * f0) / (f1 - f0), t0, t1) : 0.5 * (t0 + t1);
        if (t1 - t0 < 1e-10) break;
        const double f = soup.windingNumber(a + t * (b - a)) - 0.5;
        if (std::abs(f) < 1e-13) break;
        if ((f > 0.0) == (f1 > 0.0)) {
            t1 = t;
            f1 = f;
            if (kept == -1) f0 *= 0.5;
            kept = -1;
        } else {
            t0 = t;
            f0 = f;
            if (kept == 1) f1 *= 0.5;
            kept = 1;
        }
    }
    return t;
}

/// A tetrahedron edge whose ends differ in sign: the cap's vertex on it, as an offset from its
/// lower end (none: no border within reach).
struct CrossedEdge {
    std::size_t lower = 0;   ///< grid index of the lower end
    std::size_t upper = 0;   ///< grid index of the upper end
    unsigned direction = 0;  ///< corner bits from the lower end to the upper
    bool capEdge = false;
    glm::dvec3 lowerPosition{0.0};  ///< in the frame of the cell that found it first
    std::optional<glm::dvec3> offset;
};

/// The caps of `placedTexels` (the file note's steps 1 to 3).
TriangleSoup capsOf(const TriangleSoup& placedTexels, const SoupDistance& soup, const Size3& tile) {
    TriangleSoup caps;
    const Bounds3 bounds = boundsOf(placedTexels);
    CapGrid grid{tile, 0, 0};
    grid.firstLayer = int(std::floor(bounds.min.z)) - kLayerMarginTexels;
    grid.layers = int(std::ceil(bounds.max.z)) + kLayerMarginTexels - grid.firstLayer;

    // 1. w at the centres, and the distance to the mesh up to 2 texels (enough to tell whether
    // two ends at most sqrt(3) apart are farther from it, together, than their distance apart).
    constexpr double kNearCutoff = 2.0;
    std::vector<double> winding(grid.count()), distance(grid.count());
    tbb::parallel_for(tbb::blocked_range<int>(0, grid.layers * tile.height),
                      [&](const tbb::blocked_range<int>& rows) {
                          for (int row = rows.begin(); row != rows.end(); ++row) {
                              const int j = row % tile.height, k = row / tile.height;
                              SoupDistance::NearestHint hint;
                              for (int i = 0; i < tile.width; ++i) {
                                  const glm::dvec3 p = grid.position(i, j, k);
                                  winding[grid.index(i, j, k)] = soup.windingNumber(p);
                                  distance[grid.index(i, j, k)] =
                                      soup.unsignedDistance(p, kNearCutoff, hint);
                              }
                          }
                      });
    const auto inside = [&](std::size_t index) { return winding[index] > 0.5; };

    // 2. The tetrahedra with a cap edge, and the crossed edges they need, in cell order.
    std::vector<CrossedEdge> edges;
    std::unordered_map<std::uint64_t, std::uint32_t> edgeOf;  // lower * 8 + direction
    struct CapTetrahedron {
        int i, j, k;
        unsigned shape;                         ///< index into kTetrahedra
        std::array<std::uint32_t, 6> edgeSlot;  ///< per corner pair, UINT32_MAX: not crossed
    };
    std::vector<CapTetrahedron> tetrahedra;
    constexpr std::array<std::array<int, 2>, 6> kPairs = {
        {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};
    for (int k = 0; k + 1 < grid.layers; ++k) {
        for (int j = 0; j < tile.height; ++j) {
            for (int i = 0; i < tile.width; ++i) {
                std::array<std::size_t, 8> corner;
                int insideCorners = 0;
                for (unsigned c = 0; c < 8; ++c) {
                    corner[c] =
                        grid.index(i + int(c & 1u), j + int((c >> 1) & 1u), k + int((c >> 2) & 1u));
                    insideCorners += inside(corner[c]);
                }
                if (insideCorners == 0 || insideCorners == 8) continue;
                for (unsigned shape = 0; shape < kTetrahedra.size(); ++shape) {
                    const auto& bits = kTetrahedra[shape];
                    bool hasCapEdge = false;
                    std::array<bool, 6> crossed{};
                    for (int pair = 0; pair < 6; ++pair) {
                        const unsigned lo = bits[kPairs[pair][0]], hi = bits[kPairs[pair][1]];
                        crossed[pair] = inside(corner[lo]) != inside(corner[hi]);
                        const double length = std::sqrt(double(std::popcount(lo ^ hi)));
                        hasCapEdge =
                            hasCapEdge ||
                            (crossed[pair] && distance[corner[lo]] + distance[corner[hi]] > length);
                    }
                    if (!hasCapEdge) continue;
                    CapTetrahedron tetrahedron{i, j, k, shape, {}};
                    for (int pair = 0; pair < 6; ++pair) {
                        tetrahedron.edgeSlot[pair] = UINT32_MAX;
                        if (!crossed[pair]) continue;
                        const unsigned lo = bits[kPairs[pair][0]], hi = bits[kPairs[pair][1]];
                        const std::uint64_t key = std::uint64_t(corner[lo]) * 8 + (lo ^ hi);
                        const auto [entry, added] =
                            edgeOf.try_emplace(key, std::uint32_t(edges.size()));
                        if (added) {
                            const double length = std::sqrt(double(std::popcount(lo ^ hi)));
                            edges.push_back(
                                {corner[lo], corner[hi], lo ^ hi,
                                 distance[corner[lo]] + distance[corner[hi]] > length,
                                 grid.position(i + int(lo & 1u), j + int((lo >> 1) & 1u),
                                               k + int((lo >> 2) & 1u)),
                                 std::nullopt});
                        }
                        tetrahedron.edgeSlot[pair] = entry->second;
                    }
                    tetrahedra.push_back(tetrahedron);
                }
            }
        }
    }
    if (tetrahedra.empty()) return caps;

    // 3. The cap's vertex on each crossed edge: the level surface's crossing on a cap edge, else
    // the nearest border point.
    const BorderIndex border(borderSegments(placedTexels), tile);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, edges.size()),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t e = range.begin(); e != range.end(); ++e) {
                              CrossedEdge& edge = edges[e];
                              const glm::dvec3 step = directionOf(edge.direction);
                              if (edge.capEdge) {
                                  edge.offset = step * levelCrossing(soup, edge.lowerPosition,
                                                                     edge.lowerPosition + step,
                                                                     winding[edge.lower],
                                                                     winding[edge.upper]);
                              } else if (const std::optional<glm::dvec3> onBorder =
                                             border.nearest(edge.lowerPosition + 0.5 * step)) {
                                  edge.offset = *onBorder - edge.lowerPosition;
                              }
                          }
                      });

    // 4. Marching tetrahedra: the lone corner's three edges, or the quad between two and two.
    for (const CapTetrahedron& tetrahedron : tetrahedra) {
        const auto& bits = kTetrahedra[tetrahedron.shape];
        std::array<bool, 4> in;
        for (int c = 0; c < 4; ++c) {
            const unsigned b = bits[c];
            in[c] =
                inside(grid.index(tetrahedron.i + int(b & 1u), tetrahedron.j + int((b >> 1) & 1u),
                                  tetrahedron.k + int((b >> 2) & 1u)));
        }
        const auto vertex = [&](int c0, int c1) -> std::optional<glm::dvec3> {
            const int lo = std::min(c0, c1), hi = std::max(c0, c1);
            int pair = 0;
            while (kPairs[pair][0] != lo || kPairs[pair][1] != hi) ++pair;
            const CrossedEdge& edge = edges[tetrahedron.edgeSlot[pair]];
            if (!edge.offset) return std::nullopt;
            const unsigned b = bits[lo];
            return grid.position(tetrahedron.i + int(b & 1u), tetrahedron.j + int((b >> 1) & 1u),
                                 tetrahedron.k + int((b >> 2) & 1u)) +
                   *edge.offset;
        };
        const auto emit = [&](std::optional<glm::dvec3> a, std::optional<glm::dvec3> b,
                              std::optional<glm::dvec3> c) {
            if (!a || !b || !c) return;
            if (glm::length(glm::cross(*b - *a, *c - *a)) < 1e-12) return;  // degenerate
            const unsigned first = unsigned(caps.positions.size());
            caps.positions.insert(caps.positions.end(), {*a, *b, *c});
            caps.triangles.emplace_back(first, first + 1, first + 2);
        };
        const int insideCount = in[0] + in[1] + in[2] + in[3];
        if (insideCount == 1 || insideCount == 3) {
            int lone = 0;
            while ((in[lone] ? 1 : 0) != (insideCount == 1 ? 1 : 0)) ++lone;
            std::array<int, 3> others;
            for (int c = 0, n = 0; c < 4; ++c)
                if (c != lone) others[n++] = c;
            emit(vertex(lone, others[0]), vertex(lone, others[1]), vertex(lone, others[2]));
        } else {
            std::array<int, 2> ins, outs;
            for (int c = 0, ni = 0, no = 0; c < 4; ++c) (in[c] ? ins[ni++] : outs[no++]) = c;
            const auto a = vertex(ins[0], outs[0]), b = vertex(ins[0], outs[1]),
                       c = vertex(ins[1], outs[1]), d = vertex(ins[1], outs[0]);
            emit(a, b, c);
            emit(a, c, d);
        }
    }
    return caps;
}

/// Appends to `pieces` the parts of the triangle abc that bound the inside {w > 1/2}: where w
/// differs in sign on its two sides (1e-5 of its longest edge off its plane). Sampled at its
/// centroid and a tenth of the way from each corner to it: bounding at all four, it is kept;
/// at none, dropped; at some, split in four at its edges' middles, each part sampled again,
/// down to kSurfacePieceTexels, where a part bounding at one of its samples is kept whole.
/// Returns whether it was kept whole.
bool appendBoundingPieces(const SoupDistance& soup, const glm::dvec3& a, const glm::dvec3& b,
                          const glm::dvec3& c, std::vector<glm::dvec3>& pieces) {
    const glm::dvec3 normal = glm::cross(b - a, c - a);
    const double area = glm::length(normal);
    const double longest = std::max({glm::length(b - a), glm::length(c - b), glm::length(a - c)});
    int bounding = 4;  // zero-area triangles have no sides; they change no distance: kept
    if (area > 0.0) {
        const glm::dvec3 offset = (1e-5 * longest / area) * normal;
        const glm::dvec3 centroid = (a + b + c) / 3.0;
        bounding = 0;
        for (const glm::dvec3& sample : {centroid, glm::mix(a, centroid, 0.1),
                                         glm::mix(b, centroid, 0.1), glm::mix(c, centroid, 0.1)}) {
            bounding += (soup.countedWindingNumber(sample + offset) > 0.5) !=
                        (soup.countedWindingNumber(sample - offset) > 0.5);
        }
    }
    if (bounding == 4 || (bounding > 0 && longest <= kSurfacePieceTexels)) {
        pieces.insert(pieces.end(), {a, b, c});
        return bounding == 4;
    }
    if (bounding == 0) return false;
    const glm::dvec3 ab = 0.5 * (a + b), bc = 0.5 * (b + c), ca = 0.5 * (c + a);
    appendBoundingPieces(soup, a, ab, ca, pieces);
    appendBoundingPieces(soup, ab, b, bc, pieces);
    appendBoundingPieces(soup, ca, bc, c, pieces);
    appendBoundingPieces(soup, ab, bc, ca, pieces);
    return false;
}

/// For a mesh whose winding number changes only across the surface (closed, consistently
/// oriented parts), whether every triangle has the winding number 0 just in front of its
/// centroid. Crossing a triangle backwards adds exactly 1 (its own solid angle) unless another
/// triangle lies in the same place, so such a triangle has 0 in front and 1 behind: it bounds the
/// inside. One evaluation per triangle, where testing every triangle for what it bounds takes
/// eight or more: parts that overlap, nest or touch face to face (a face of one inside another,
/// or against it) put some front in another part and fail it.
bool allTrianglesFaceOutside(const TriangleSoup& placedTexels, const SoupDistance& soup) {
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, placedTexels.triangles.size()), true,
        [&](const tbb::blocked_range<std::size_t>& range, bool outside) {
            for (std::size_t t = range.begin(); outside && t != range.end(); ++t) {
                const glm::uvec3& triangle = placedTexels.triangles[t];
                outside = soup.facesOutsideAtCentroid(placedTexels.positions[triangle.x],
                                                      placedTexels.positions[triangle.y],
                                                      placedTexels.positions[triangle.z]);
            }
            return outside;
        },
        [](bool x, bool y) { return x && y; });
}

}  // namespace

MeshSurface::MeshSurface(const SoupDistance& soup) : soup_(&soup) {}

MeshSurface::MeshSurface(const TriangleSoup& placedTexels, const SoupDistance& soup,
                         const Size3& tile)
    : soup_(&soup) {
    if (soup.windingChangesOnlyAcrossTheSurface() && allTrianglesFaceOutside(placedTexels, soup))
        return;  // all triangles bound the inside, no holes: the surface is the mesh
    // Each triangle's bounding pieces, in triangle order whatever the threads.
    const std::size_t count = placedTexels.triangles.size();
    std::vector<std::vector<glm::dvec3>> pieces(count);
    std::vector<char> whole(count, 1);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t t = range.begin(); t != range.end(); ++t) {
                              const glm::uvec3& triangle = placedTexels.triangles[t];
                              whole[t] = appendBoundingPieces(
                                  soup, placedTexels.positions[triangle.x],
                                  placedTexels.positions[triangle.y],
                                  placedTexels.positions[triangle.z], pieces[t]);
                          }
                      });
    trimmedTriangles_ = std::size_t(std::count(whole.begin(), whole.end(), 0));
    TriangleSoup kept;
    for (const std::vector<glm::dvec3>& corners : pieces) {
        for (std::size_t n = 0; n < corners.size(); n += 3) {
            const unsigned first = unsigned(kept.positions.size());
            kept.positions.insert(kept.positions.end(), corners.begin() + n,
                                  corners.begin() + n + 3);
            kept.triangles.emplace_back(first, first + 1, first + 2);
        }
    }
    // Nothing bounds: no inside (the bake refuses it); then all count.
    if (kept.triangles.empty()) trimmedTriangles_ = 0;
    if (trimmedTriangles_ > 0) bounding_ = std::make_unique<const SoupDistance>(kept, tile);
    if (!soup.windingChangesOnlyAcrossTheSurface()) caps_ = capsOf(placedTexels, soup, tile);
    if (!caps_.triangles.empty()) capDistance_ = std::make_unique<const SoupDistance>(caps_, tile);
}

bool insideTestSignsAlike(const MeshDistance& mesh, const MeshSurface& surface,
                          const TriangleSoup& placedTexels) {
    return mesh.hasSign() && surface.trimmedTriangles() == 0 &&
           !inspectMesh(placedTexels).selfIntersecting;
}

MeshSurface::MeshSurface(MeshSurface&&) noexcept = default;
MeshSurface::~MeshSurface() = default;

double MeshSurface::unsignedDistance(const glm::dvec3& texelPosition, double cutoffTexels,
                                     SoupDistance::NearestHint& hint) const {
    double distance = 0.0;
    unsignedDistancesOnLine(glm::dvec2(texelPosition), std::span(&texelPosition.z, 1), cutoffTexels,
                            std::span(&hint, 1), std::span(&distance, 1));
    return distance;
}

void MeshSurface::unsignedDistancesOnLine(const glm::dvec2& xy, std::span<const double> z,
                                          double cutoffTexels,
                                          std::span<SoupDistance::NearestHint> hints,
                                          std::span<double> distances) const {
    const SoupDistance& triangles = bounding_ ? *bounding_ : *soup_;
    triangles.unsignedDistancesOnLine(xy, z, cutoffTexels, hints, distances);
    if (!capDistance_) return;
    for (std::size_t n = 0; n < z.size(); ++n) {
        if (distances[n] > 0.0)
            distances[n] = capDistance_->unsignedDistance({xy.x, xy.y, z[n]}, distances[n]);
    }
}

void MeshSurface::signedDistancesOnLine(const glm::dvec2& xy, std::span<const double> z,
                                        double cutoffTexels,
                                        std::span<SoupDistance::NearestHint> hints,
                                        std::span<double> distances) const {
    unsignedDistancesOnLine(xy, z, cutoffTexels, hints, distances);
    for (std::size_t n = 0; n < z.size(); ++n) {
        if (soup_->countedWindingNumber({xy.x, xy.y, z[n]}) > 0.5) distances[n] = -distances[n];
    }
}

double MeshSurface::signedDistance(const glm::dvec3& texelPosition, double cutoffTexels) const {
    SoupDistance::NearestHint none;
    const double distance = unsignedDistance(texelPosition, cutoffTexels, none);
    return soup_->countedWindingNumber(texelPosition) > 0.5 ? -distance : distance;
}

}  // namespace distile
