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

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <map>
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

}  // namespace

MeshTopology inspectMesh(const TriangleSoup& triangleSoup) {
    validateTriangleSoup(triangleSoup, "mesh inspection");
    const Soup soup = toCgalSoup(triangleSoup);
    MeshTopology topology;

    // Edge use counts straight from the soup: a border edge has one face, a closed surface has
    // two faces on every edge, more than two is a non-manifold edge.
    std::map<std::pair<std::size_t, std::size_t>, int> edgeFaces;
    for (const Polygon& polygon : soup.polygons) {
        if (isDegenerate(soup, polygon)) ++topology.degenerateFaces;
        for (int corner = 0; corner < 3; ++corner) {
            std::size_t a = polygon[corner];
            std::size_t b = polygon[(corner + 1) % 3];
            if (a == b) continue;
            if (a > b) std::swap(a, b);
            ++edgeFaces[{a, b}];
        }
    }
    bool nonManifoldEdge = false;
    for (const auto& [edge, faces] : edgeFaces) {
        if (faces == 1) ++topology.boundaryEdges;
        if (faces > 2) nonManifoldEdge = true;
    }
    topology.closed = topology.boundaryEdges == 0;

    SurfaceMesh mesh;
    const bool orientable = buildSurfaceMesh(soup, mesh);
    topology.manifold = orientable && !nonManifoldEdge && !mesh.is_empty();
    if (topology.manifold && soup.polygons.size() <= kMaxSelfIntersectionFaces) {
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
};

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
    const auto nearestWithin = [&](double reach) {
        double best = std::numeric_limits<double>::infinity();
        const PeriodicShifts shifts = periodicShifts(point, impl_->box, tile, reach);
        for (int m = shifts.xBegin; m <= shifts.xEnd; ++m) {
            for (int n = shifts.yBegin; n <= shifts.yEnd; ++n) {
                const glm::dvec3 shift(double(m) * tile.width, double(n) * tile.height, 0.0);
                best = std::min(best, impl_->squaredDistanceUnshifted(point - shift));
            }
        }
        return std::sqrt(best);
    };
    // A reach of max(W, H) always includes at least one copy in x and y. Copies left out are
    // farther than that reach; if the nearest found is farther still, widen to it.
    const double firstReach = std::max(tile.width, tile.height);
    const double nearest = nearestWithin(firstReach);
    return nearest <= firstReach ? nearest : nearestWithin(nearest);
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
    const Kernel::Ray_3 ray(toPoint(origin),
                            Kernel::Vector_3(direction.x, direction.y, direction.z));
    const auto hit = impl_->tree.first_intersection(ray);
    if (!hit) return false;
    const double lengthSquared = glm::dot(direction, direction);
    const auto parameterOf = [&](const Point& p) {
        const glm::dvec3 offset(p.x() - origin.x, p.y() - origin.y, p.z() - origin.z);
        return glm::dot(offset, direction) / lengthSquared;
    };
    if (const Point* point = boost::get<Point>(&hit->first)) {
        distance = parameterOf(*point);
    } else if (const Kernel::Segment_3* segment = boost::get<Kernel::Segment_3>(&hit->first)) {
        distance = std::min(parameterOf(segment->source()), parameterOf(segment->target()));
    } else {
        return false;
    }
    distance = std::max(distance, 0.0);
    return true;
}

std::size_t MeshDistance::triangleCount() const {
    return impl_->triangles.size();
}

}  // namespace distile
