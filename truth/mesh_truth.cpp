#include "truth/mesh_truth.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "common/error.h"

namespace distile {

namespace {

namespace PMP = CGAL::Polygon_mesh_processing;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Triangle = Kernel::Triangle_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using Polygon = std::array<std::size_t, 3>;
using TriangleList = std::vector<Triangle>;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, TriangleList::const_iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
using SideOfMesh = CGAL::Side_of_triangle_mesh<SurfaceMesh, Kernel>;

Point toPoint(const glm::dvec3& p) {
    return Point(p.x, p.y, p.z);
}

struct Soup {
    std::vector<Point> points;
    std::vector<Polygon> polygons;
};

Soup toCgalSoup(const TriangleSoup& soup) {
    Soup result;
    result.points.reserve(soup.positions.size());
    for (const glm::dvec3& p : soup.positions) result.points.push_back(toPoint(p));
    result.polygons.reserve(soup.triangles.size());
    for (const glm::uvec3& t : soup.triangles) result.polygons.push_back({t.x, t.y, t.z});
    return result;
}

bool isDegenerate(const Soup& soup, const Polygon& polygon) {
    if (polygon[0] == polygon[1] || polygon[1] == polygon[2] || polygon[0] == polygon[2]) {
        return true;
    }
    return CGAL::collinear(soup.points[polygon[0]], soup.points[polygon[1]],
                           soup.points[polygon[2]]);
}

/// Orients the soup and builds a Surface_mesh from it; returns whether orienting needed no
/// vertex duplication (the soup is an orientable manifold), and stores the mesh in `mesh`.
bool buildSurfaceMesh(Soup soup, SurfaceMesh& mesh) {
    // Degenerate polygons (repeated corners) break the soup-to-mesh conversion; drop them here,
    // inspectMesh counts them separately.
    std::erase_if(soup.polygons, [](const Polygon& polygon) {
        return polygon[0] == polygon[1] || polygon[1] == polygon[2] || polygon[0] == polygon[2];
    });
    const bool orientedWithoutSplits = PMP::orient_polygon_soup(soup.points, soup.polygons);
    mesh.clear();
    if (PMP::is_polygon_soup_a_polygon_mesh(soup.polygons)) {
        PMP::polygon_soup_to_polygon_mesh(soup.points, soup.polygons, mesh);
    }
    return orientedWithoutSplits;
}

/// Whether every vertex of `soup` is manifold, assuming every edge is used exactly twice, once in
/// each direction: the faces around a vertex then link its neighbours into disjoint cycles (each
/// face (v, x, y) links x to y), and the vertex is manifold when they form one cycle.
bool everyVertexIsOneFan(const TriangleSoup& soup) {
    // Each face corner as (vertex, x, y), grouped by vertex.
    struct Corner {
        unsigned vertex, from, to;
    };
    std::vector<Corner> corners;
    corners.reserve(3 * soup.triangles.size());
    for (const glm::uvec3& t : soup.triangles) {
        corners.push_back({t.x, t.y, t.z});
        corners.push_back({t.y, t.z, t.x});
        corners.push_back({t.z, t.x, t.y});
    }
    tbb::parallel_sort(corners.begin(), corners.end(), [](const Corner& l, const Corner& r) {
        return l.vertex < r.vertex || (l.vertex == r.vertex && l.from < r.from);
    });
    // Within a vertex's corners (sorted by `from`), follow the links from the first one: one
    // cycle visits them all.
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, corners.size()), true,
        [&](const tbb::blocked_range<std::size_t>& range, bool manifold) {
            std::size_t begin = range.begin();
            while (begin > 0 && begin < corners.size() &&
                   corners[begin - 1].vertex == corners[begin].vertex)
                ++begin;  // a vertex starting before the range belongs to the range before
            for (std::size_t first = begin; manifold && first < range.end();) {
                std::size_t end = first;
                while (end < corners.size() && corners[end].vertex == corners[first].vertex) ++end;
                const auto fan = std::span(corners).subspan(first, end - first);
                std::size_t visited = 0;
                unsigned at = fan.front().from;
                do {
                    const auto link = std::lower_bound(
                        fan.begin(), fan.end(), at,
                        [](const Corner& c, unsigned value) { return c.from < value; });
                    if (link == fan.end() || link->from != at) return false;
                    at = link->to;
                    ++visited;
                } while (at != fan.front().from && visited <= fan.size());
                manifold = visited == fan.size();
                first = end;
            }
            return manifold;
        },
        [](bool x, bool y) { return x && y; });
}

}  // namespace

MeshTopology inspectMesh(const TriangleSoup& triangleSoup) {
    validateTriangleSoup(triangleSoup, "mesh inspection");
    const Soup soup = toCgalSoup(triangleSoup);
    MeshTopology topology;

    // Edge uses straight from the soup, sorted: a border edge has one face, a closed surface has
    // two faces on every edge, more than two is a non-manifold edge. An edge used once in each
    // direction is consistently oriented.
    std::vector<std::uint64_t> uses;  // lower corner, higher corner, direction in the lowest bit
    uses.reserve(3 * soup.polygons.size());
    for (const Polygon& polygon : soup.polygons) {
        if (isDegenerate(soup, polygon)) ++topology.degenerateFaces;
        for (int corner = 0; corner < 3; ++corner) {
            const std::uint64_t a = polygon[corner], b = polygon[(corner + 1) % 3];
            if (a == b) continue;
            uses.push_back((std::min(a, b) << 33) | (std::max(a, b) << 1) | (a > b ? 1 : 0));
        }
    }
    tbb::parallel_sort(uses.begin(), uses.end());
    bool nonManifoldEdge = false, consistentlyOriented = true;
    for (std::size_t n = 0; n < uses.size();) {
        std::size_t end = n;
        while (end < uses.size() && (uses[end] >> 1) == (uses[n] >> 1)) ++end;
        const std::size_t faces = end - n;
        if (faces == 1) ++topology.boundaryEdges;
        if (faces > 2) nonManifoldEdge = true;
        if (faces != 2 || (uses[n] & 1) == (uses[n + 1] & 1)) consistentlyOriented = false;
        n = end;
    }
    topology.closed = topology.boundaryEdges == 0;

    // A closed, consistently oriented soup without repeated corners whose vertices are all
    // manifold is an oriented manifold as it stands: what orienting it with CGAL would find,
    // without building the mesh (which takes seconds at a million faces). Otherwise CGAL decides.
    const bool repeatedCorners =
        std::any_of(soup.polygons.begin(), soup.polygons.end(), [](const Polygon& polygon) {
            return polygon[0] == polygon[1] || polygon[1] == polygon[2] || polygon[0] == polygon[2];
        });
    const bool testSelfIntersection = soup.polygons.size() <= kMaxSelfIntersectionFaces;
    if (topology.closed && consistentlyOriented && !repeatedCorners && !soup.polygons.empty() &&
        everyVertexIsOneFan(triangleSoup) && !testSelfIntersection) {
        topology.manifold = true;
        return topology;
    }
    SurfaceMesh mesh;
    const bool orientable = buildSurfaceMesh(soup, mesh);
    topology.manifold = orientable && !nonManifoldEdge && !mesh.is_empty();
    if (topology.manifold && testSelfIntersection) {
        topology.selfIntersecting = PMP::does_self_intersect(mesh);
        topology.selfIntersectionTested = true;
    }
    return topology;
}

struct MeshDistance::Impl {
    TriangleList triangles;
    Tree tree;
    SurfaceMesh mesh;                  // only when closed
    std::unique_ptr<SideOfMesh> side;  // only when closed
    std::optional<Periodic> periodic;
    Bounds3 box;

    double squaredDistanceUnshifted(const glm::dvec3& p) const {
        return tree.squared_distance(toPoint(p));
    }

    bool insideUnshifted(const glm::dvec3& p) const {
        return (*side)(toPoint(p)) == CGAL::ON_BOUNDED_SIDE;
    }

    /// The first hit of origin + t * direction, t >= 0, with the unshifted mesh.
    std::optional<RayHit> firstHitUnshifted(const glm::dvec3& origin,
                                            const glm::dvec3& direction) const;
};

std::optional<MeshDistance::RayHit> MeshDistance::Impl::firstHitUnshifted(
    const glm::dvec3& origin, const glm::dvec3& direction) const {
    const Kernel::Ray_3 ray(toPoint(origin),
                            Kernel::Vector_3(direction.x, direction.y, direction.z));
    const auto hit = tree.first_intersection(ray);
    if (!hit) return std::nullopt;
    const double lengthSquared = glm::dot(direction, direction);
    const auto parameterOf = [&](const Point& p) {
        const glm::dvec3 offset(p.x() - origin.x, p.y() - origin.y, p.z() - origin.z);
        return glm::dot(offset, direction) / lengthSquared;
    };
    RayHit result;
    if (const Point* point = boost::get<Point>(&hit->first)) {
        result.distance = parameterOf(*point);
    } else if (const Kernel::Segment_3* segment = boost::get<Kernel::Segment_3>(&hit->first)) {
        result.distance = std::min(parameterOf(segment->source()), parameterOf(segment->target()));
    } else {
        return std::nullopt;
    }
    result.distance = std::max(result.distance, 0.0);
    const Triangle& triangle = *hit->second;
    const auto toVector = [](const Point& p) { return glm::dvec3(p.x(), p.y(), p.z()); };
    const glm::dvec3 corner = toVector(triangle.vertex(0));
    const glm::dvec3 normal =
        glm::cross(toVector(triangle.vertex(1)) - corner, toVector(triangle.vertex(2)) - corner);
    const double normalLength = glm::length(normal);
    // A degenerate triangle has no plane; facing the ray is the only orientation left.
    result.normal =
        normalLength > 0.0 ? normal / normalLength : -direction / std::sqrt(lengthSquared);
    if (glm::dot(result.normal, direction) > 0.0) result.normal = -result.normal;
    return result;
}

MeshDistance::MeshDistance(const TriangleSoup& soup, std::optional<Periodic> periodic)
    : impl_(std::make_unique<Impl>()) {
    validateTriangleSoup(soup, "mesh distance");
    if (periodic) validateTileSize(periodic->tile, "mesh distance: periodic tile");
    impl_->periodic = periodic;
    impl_->box = boundsOf(soup);
    impl_->triangles.reserve(soup.triangles.size());
    for (const glm::uvec3& t : soup.triangles) {
        impl_->triangles.emplace_back(toPoint(soup.positions[t.x]), toPoint(soup.positions[t.y]),
                                      toPoint(soup.positions[t.z]));
    }
    // Build the tree and its distance-query acceleration now, so that const queries from several
    // threads never trigger a lazy build.
    impl_->tree.insert(impl_->triangles.begin(), impl_->triangles.end());
    impl_->tree.build();
    impl_->tree.accelerate_distance_queries();

    SurfaceMesh mesh;
    buildSurfaceMesh(toCgalSoup(soup), mesh);
    if (!mesh.is_empty() && CGAL::is_closed(mesh)) {
        impl_->mesh = std::move(mesh);
        impl_->side = std::make_unique<SideOfMesh>(impl_->mesh);
        (void)impl_->insideUnshifted(impl_->box.min);  // builds its tree now, not on first use
    }
}

MeshDistance::MeshDistance(MeshDistance&&) noexcept = default;
MeshDistance& MeshDistance::operator=(MeshDistance&&) noexcept = default;
MeshDistance::~MeshDistance() = default;

double MeshDistance::unsignedDistance(const glm::dvec3& point) const {
    if (!impl_->periodic) return std::sqrt(impl_->squaredDistanceUnshifted(point));
    const Size3& tile = impl_->periodic->tile;
    // The copy whose box centre is nearest in x and y bounds the distance; a copy nearer than
    // that bound has its box within it, so only those copies are queried besides (usually one
    // to four, where a fixed reach of a tile would query nine).
    const glm::dvec3 centre = 0.5 * (impl_->box.min + impl_->box.max);
    const int nearestM = int(std::lround((point.x - centre.x) / tile.width));
    const int nearestN = int(std::lround((point.y - centre.y) / tile.height));
    const auto shiftOf = [&](int m, int n) {
        return glm::dvec3(double(m) * tile.width, double(n) * tile.height, 0.0);
    };
    double best = impl_->squaredDistanceUnshifted(point - shiftOf(nearestM, nearestN));
    const PeriodicShifts shifts = periodicShifts(point, impl_->box, tile, std::sqrt(best));
    for (int m = shifts.xBegin; m <= shifts.xEnd; ++m) {
        for (int n = shifts.yBegin; n <= shifts.yEnd; ++n) {
            if (m == nearestM && n == nearestN) continue;
            best = std::min(best, impl_->squaredDistanceUnshifted(point - shiftOf(m, n)));
        }
    }
    return std::sqrt(best);
}

bool MeshDistance::hasSign() const {
    return impl_->side != nullptr;
}

bool MeshDistance::isInside(const glm::dvec3& point) const {
    if (!hasSign()) {
        throw InputError(
            "mesh distance: the mesh is not closed, so it has no inside; "
            "signed distances need a closed mesh");
    }
    if (!impl_->periodic) return impl_->insideUnshifted(point);
    const Size3& tile = impl_->periodic->tile;
    const PeriodicShifts shifts = periodicShifts(point, impl_->box, tile, 0.0);
    for (int m = shifts.xBegin; m <= shifts.xEnd; ++m) {
        for (int n = shifts.yBegin; n <= shifts.yEnd; ++n) {
            const glm::dvec3 shift(double(m) * tile.width, double(n) * tile.height, 0.0);
            if (impl_->insideUnshifted(point - shift)) return true;
        }
    }
    return false;
}

double MeshDistance::signedDistance(const glm::dvec3& point) const {
    const bool inside = isInside(point);
    const double distance = unsignedDistance(point);
    return inside ? -distance : distance;
}

bool MeshDistance::rayHit(const glm::dvec3& origin, const glm::dvec3& direction,
                          double& distance) const {
    const std::optional<RayHit> hit = impl_->firstHitUnshifted(origin, direction);
    if (hit) distance = hit->distance;
    return hit.has_value();
}

namespace {

/// The parameter range [entry, exit] of origin + t * direction inside `box` for t in
/// [0, maxDistance]; empty (entry > exit) when the ray misses the box there.
std::pair<double, double> rayBoxRange(const glm::dvec3& origin, const glm::dvec3& direction,
                                      const Bounds3& box, double maxDistance) {
    double entry = 0.0, exit = maxDistance;
    for (int axis = 0; axis < 3; ++axis) {
        if (direction[axis] == 0.0) {
            if (origin[axis] < box.min[axis] || origin[axis] > box.max[axis]) return {1.0, 0.0};
            continue;
        }
        double near = (box.min[axis] - origin[axis]) / direction[axis];
        double far = (box.max[axis] - origin[axis]) / direction[axis];
        if (near > far) std::swap(near, far);
        entry = std::max(entry, near);
        exit = std::min(exit, far);
    }
    return {entry, exit};
}

/// Copy indices k whose interval [low + k period, high + k period] overlaps [from, to].
std::pair<int, int> overlappingCopies(double from, double to, double low, double high,
                                      double period) {
    return {int(std::ceil((from - high) / period)), int(std::floor((to - low) / period))};
}

}  // namespace

std::optional<MeshDistance::RayHit> MeshDistance::firstHit(const glm::dvec3& origin,
                                                           const glm::dvec3& direction,
                                                           double maxDistance) const {
    const auto within = [&](std::optional<RayHit> hit) {
        return hit && hit->distance <= maxDistance ? hit : std::nullopt;
    };
    if (!impl_->periodic) return within(impl_->firstHitUnshifted(origin, direction));
    if (!std::isfinite(maxDistance)) {
        throw InputError(
            "mesh distance: a periodic first hit needs a finite maximum distance along the ray");
    }
    const double width = impl_->periodic->tile.width;
    const double height = impl_->periodic->tile.height;
    // The box grown by a hair, so a hit on a face of the box (a flat top, a cube's side) is not
    // lost to the rounding of the slab test.
    Bounds3 box = impl_->box;
    const double pad = 1e-9 * (1.0 + glm::length(box.max - box.min));
    box.min -= glm::dvec3(pad);
    box.max += glm::dvec3(pad);

    // The copies (m, n) whose shifted box the ray crosses within [0, maxDistance]: for each m
    // whose box the xy path reaches in x, the stretch of the path inside that box's x range
    // gives the n whose box it reaches in y. Work grows with the tiles the path crosses.
    struct Candidate {
        double entry;
        glm::dvec3 shift;
    };
    std::vector<Candidate> candidates;
    const glm::dvec3 end = origin + direction * maxDistance;
    const auto [mBegin, mEnd] = overlappingCopies(
        std::min(origin.x, end.x), std::max(origin.x, end.x), box.min.x, box.max.x, width);
    for (int m = mBegin; m <= mEnd; ++m) {
        double from = 0.0, to = maxDistance;
        if (direction.x != 0.0) {
            from = (box.min.x + m * width - origin.x) / direction.x;
            to = (box.max.x + m * width - origin.x) / direction.x;
            if (from > to) std::swap(from, to);
            from = std::max(from, 0.0);
            to = std::min(to, maxDistance);
        }
        if (from > to) continue;
        const double yFrom = origin.y + direction.y * from, yTo = origin.y + direction.y * to;
        const auto [nBegin, nEnd] = overlappingCopies(std::min(yFrom, yTo), std::max(yFrom, yTo),
                                                      box.min.y, box.max.y, height);
        for (int n = nBegin; n <= nEnd; ++n) {
            const glm::dvec3 shift(m * width, n * height, 0.0);
            const auto [entry, exit] = rayBoxRange(origin - shift, direction, box, maxDistance);
            if (entry <= exit) candidates.push_back({entry, shift});
        }
    }
    // Nearest box first; a copy whose box the ray enters beyond the best hit cannot beat it.
    std::sort(candidates.begin(), candidates.end(),
              [](const Candidate& a, const Candidate& b) { return a.entry < b.entry; });
    std::optional<RayHit> best;
    for (const Candidate& candidate : candidates) {
        if (best && candidate.entry > best->distance) break;
        const std::optional<RayHit> hit =
            within(impl_->firstHitUnshifted(origin - candidate.shift, direction));
        if (hit && (!best || hit->distance < best->distance)) best = hit;
    }
    return best;
}

std::size_t MeshDistance::triangleCount() const {
    return impl_->triangles.size();
}

}  // namespace distile
