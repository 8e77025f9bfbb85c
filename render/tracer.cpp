#include "render/tracer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "common/error.h"
#include "common/simd.h"
#include "common/thread_scratch.h"
#include "render/analytic_filter.h"
#include "render/detail/entry_wide.h"

namespace distile {

namespace {

/// The most texels per world unit along any axis of a shell's texel space: a texel-space ray
/// direction's squared length must stay finite in float (about 1e38), with room to spare.
constexpr float kMaxTexelsPerWorld = 1e15f;

/// Throws InputError naming object `index`'s material when its texel space is denser than
/// kMaxTexelsPerWorld along `axis` (`texelsPerWorld` on one of its triangles, or on all).
void requireTexelDensity(std::size_t index, float texelsPerWorld, const char* axis,
                         const char* remedy) {
    if (texelsPerWorld <= kMaxTexelsPerWorld) return;
    char value[32];
    std::snprintf(value, sizeof value, "%.3g", double(texelsPerWorld));
    throw InputError::inField("objects[" + std::to_string(index) + "].material",
                              std::string(value) + " texels per world unit along " + axis +
                                  " is not accepted; at most 1e15 (" + remedy + ")");
}

/// The march's result taken from the material's exact first hit (reference renders,
/// Material::exactHit) instead of marching: the hit on the path to the floor z = 0 (or to where
/// the ray leaves through an open border, `leaveTravelTexels`, if that comes first), else the
/// floor, ended as the march ends there (solid: a hit; open: the ray leaves). One query counts as
/// one iteration. Stores the unit texel-space normal of a detail hit in `normalTexels`. A NaN/Inf
/// start or direction returns at once, not converged, as march() does.
/// Not inlined: GCC 12 inlined into the caller that computes `start` in double (takeEntry) gave
/// the query the double values from before their rounding to float in some builds (the origin
/// of a reference query was not a float), so reference renders changed with unrelated edits.
[[gnu::noinline]] MarchResult exactFirstHit(const Material& material, const glm::vec3& start,
                                            const glm::vec3& direction, float leaveTravelTexels,
                                            glm::vec3& normalTexels) {
    MarchResult result;
    result.texelPosition = start;
    if (!(std::isfinite(start.x) && std::isfinite(start.y) && std::isfinite(start.z) &&
          std::isfinite(direction.x) && std::isfinite(direction.y) && std::isfinite(direction.z)))
        return result;
    result.iterations = 1;
    const glm::dvec3 origin(start);
    const glm::dvec3 unitDirection = glm::normalize(glm::dvec3(direction));
    double toFloor = origin.z / -unitDirection.z;
    Floor floor = material.floor;
    detail::leaveBeforeFloor(toFloor, floor, double(leaveTravelTexels));
    const std::optional<DetailHit> found = material.exactHit(origin, unitDirection, toFloor);
    if (!found) {
        detail::endOnFloor(result, start, direction, 0.0f, float(toFloor), floor);
        return result;
    }
    result.converged = true;
    result.travelTexels = float(found->travelTexels);
    result.texelPosition = glm::vec3(origin + unitDirection * found->travelTexels);
    normalTexels = glm::vec3(found->normalTexels);
    return result;
}

/// The entry's unit frame from an interpolated vertex normal and tangent (xyz, w: handedness):
/// N normalised, T the tangent made orthogonal to it, B = N x T with the tangent's handedness.
void setFrame(ShellEntry& entry, const glm::vec3& normal, const glm::vec4& tangent) {
    entry.normal = glm::normalize(normal);
    const glm::vec3 inPlane =
        glm::vec3(tangent) - entry.normal * glm::dot(glm::vec3(tangent), entry.normal);
    const float inPlaneLength = glm::length(inPlane);
    if (inPlaneLength > 1e-6f) {
        entry.tangent = inPlane / inPlaneLength;
    } else {  // the interpolated tangent vanished (opposite tangents across a seam): any valid
              // frame
        const glm::vec3 axis =
            std::abs(entry.normal.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
        entry.tangent = glm::normalize(glm::cross(entry.normal, axis));
    }
    entry.bitangent = glm::cross(entry.normal, entry.tangent) * (tangent.w < 0.0f ? -1.0f : 1.0f);
}

/// The plane of side `side` (opposite corner `side`) of the flat shell over `mesh`'s triangle of
/// `corners` with unit normal `normal`: through the side's edge along the normal, with its normal
/// `outward` (not unit) turned away from that corner and `offset` = dot(outward, point) on it.
void flatSidePlane(const BaseMesh& mesh, const glm::uvec3& corners, const glm::dvec3& normal,
                   int side, glm::dvec3& outward, double& offset) {
    const glm::dvec3 opposite(mesh.positions[corners[side]]);
    const glm::dvec3 from(mesh.positions[corners[(side + 1) % 3]]);
    const glm::dvec3 to(mesh.positions[corners[(side + 2) % 3]]);
    outward = glm::cross(to - from, normal);
    if (glm::dot(outward, opposite - from) > 0.0) outward = -outward;
    offset = glm::dot(outward, from);
}

/// Lower bounds of the distance from every point of each flat triangle of `mesh` to the mesh's
/// open border, world units, when its flat triangles lie in one plane; 0 for the other triangles,
/// and for all when they do not. `normals[t]`: the unit normal of triangle t's flat shell with
/// detail, zero for the others; `neighbours[t][i]`: the triangle across side i (numbered within
/// the mesh, ShellPrisms::kNoNeighbour at an open border).
///
/// Walking across the sides of coplanar flat shells (SceneTracer::borderExitWorld), a ray leaves
/// at a point whose projection onto the plane lies on a border side, so no nearer to where it
/// entered than that side. The border sides are marked on a grid over the plane; every point of a
/// cell k cells from the nearest marked one (chessboard distance, exact in two raster passes) is
/// at least k - 1 cell widths from every border side, and every point of a triangle within its
/// reach (the farthest corner) of its centroid.
std::vector<float> planarBorderDistances(const BaseMesh& mesh, std::span<const glm::vec3> normals,
                                         std::span<const std::array<std::uint32_t, 3>> neighbours,
                                         detail::BorderGrid& grid) {
    const std::size_t count = mesh.triangles.size();
    std::vector<float> distances(count, 0.0f);
    std::size_t firstFlat = 0;
    while (firstFlat < count && normals[firstFlat] == glm::vec3(0.0f)) ++firstFlat;
    if (firstFlat == count) return distances;
    // The plane of the first flat triangle, and two axes in it.
    const glm::dvec3 normal(normals[firstFlat]);
    const glm::dvec3 origin(mesh.positions[mesh.triangles[firstFlat][0]]);
    const glm::dvec3 helper =
        std::abs(normal.x) < 0.6 ? glm::dvec3(1.0, 0.0, 0.0) : glm::dvec3(0.0, 1.0, 0.0);
    const glm::dvec3 axisU = glm::normalize(glm::cross(normal, helper));
    const glm::dvec3 axisV = glm::cross(normal, axisU);
    const auto inPlane = [&](std::uint32_t vertex) {
        const glm::dvec3 offset = glm::dvec3(mesh.positions[vertex]) - origin;
        return glm::dvec2(glm::dot(offset, axisU), glm::dot(offset, axisV));
    };
    const auto flat = [&](std::size_t t) { return normals[t] != glm::vec3(0.0f); };
    // A triangle's centroid in the plane and its reach (the farthest corner from it).
    struct Footprint {
        glm::dvec2 centroid;
        double reach;
    };
    const auto footprintOf = [&](std::size_t t) {
        glm::dvec2 corners[3];
        for (int corner = 0; corner < 3; ++corner)
            corners[corner] = inPlane(mesh.triangles[t][corner]);
        Footprint footprint{(corners[0] + corners[1] + corners[2]) / 3.0, 0.0};
        for (const glm::dvec2& corner : corners)
            footprint.reach = std::max(footprint.reach, glm::length(corner - footprint.centroid));
        return footprint;
    };
    glm::dvec2 low(std::numeric_limits<double>::infinity());
    glm::dvec2 high = -low;
    double offPlane = 0.0, leastReach = std::numeric_limits<double>::infinity();
    for (std::size_t t = 0; t < count; ++t) {
        if (!flat(t)) continue;
        if (!(glm::dot(glm::dvec3(normals[t]), normal) >= 1.0 - 1e-12)) return distances;
        for (int corner = 0; corner < 3; ++corner) {
            const std::uint32_t vertex = mesh.triangles[t][corner];
            offPlane = std::max(
                offPlane, std::abs(glm::dot(glm::dvec3(mesh.positions[vertex]) - origin, normal)));
            low = glm::min(low, inPlane(vertex));
            high = glm::max(high, inPlane(vertex));
        }
        leastReach = std::min(leastReach, footprintOf(t).reach);
    }
    const double extent = std::max(high.x - low.x, high.y - low.y);
    if (!(extent > 0.0) || !(offPlane <= 1e-6 * extent)) return distances;  // not one plane
    // Cells of about half the smallest triangle's reach, at least 256 and at most 1024 along the
    // longer side (the grid also bounds points: BorderGrid::distanceWorld).
    const double cell = std::max(extent / 1024.0, std::min(0.5 * leastReach, extent / 256.0));
    const int columns = int((high.x - low.x) / cell) + 1;
    const int rows = int((high.y - low.y) / cell) + 1;
    const auto cellOf = [&](const glm::dvec2& point) {
        return glm::ivec2(std::clamp(int((point.x - low.x) / cell), 0, columns - 1),
                          std::clamp(int((point.y - low.y) / cell), 0, rows - 1));
    };
    constexpr int kFar = std::numeric_limits<int>::max() / 2;
    std::vector<int> steps(std::size_t(columns) * std::size_t(rows), kFar);
    const auto at = [&](int x, int y) -> int& { return steps[std::size_t(y) * columns + x]; };
    bool anyBorder = false;
    for (std::size_t t = 0; t < count; ++t) {
        if (!flat(t)) continue;
        for (int side = 0; side < 3; ++side) {
            if (neighbours[t][std::size_t(side)] != ShellPrisms::kNoNeighbour) continue;
            anyBorder = true;
            // In pieces of at most a cell, each marking the cells its bounding box meets.
            const glm::dvec2 from = inPlane(mesh.triangles[t][(side + 1) % 3]);
            const glm::dvec2 to = inPlane(mesh.triangles[t][(side + 2) % 3]);
            const int pieces = std::max(1, int(std::ceil(glm::length(to - from) / cell)));
            for (int piece = 0; piece < pieces; ++piece) {
                const glm::dvec2 a = from + (to - from) * (double(piece) / pieces);
                const glm::dvec2 b = from + (to - from) * (double(piece + 1) / pieces);
                const glm::ivec2 first = cellOf(glm::min(a, b)), last = cellOf(glm::max(a, b));
                for (int y = first.y; y <= last.y; ++y)
                    for (int x = first.x; x <= last.x; ++x) at(x, y) = 0;
            }
        }
    }
    if (!anyBorder) return distances;
    for (int y = 0; y < rows; ++y) {
        for (int x = 0; x < columns; ++x) {
            int& value = at(x, y);
            if (x > 0) value = std::min(value, at(x - 1, y) + 1);
            if (y == 0) continue;
            for (int dx = std::max(x - 1, 0); dx <= std::min(x + 1, columns - 1); ++dx)
                value = std::min(value, at(dx, y - 1) + 1);
        }
    }
    for (int y = rows - 1; y >= 0; --y) {
        for (int x = columns - 1; x >= 0; --x) {
            int& value = at(x, y);
            if (x + 1 < columns) value = std::min(value, at(x + 1, y) + 1);
            if (y + 1 == rows) continue;
            for (int dx = std::max(x - 1, 0); dx <= std::min(x + 1, columns - 1); ++dx)
                value = std::min(value, at(dx, y + 1) + 1);
        }
    }
    // Rounding of the projections and the cells is far below this margin.
    const double margin = 1e-5 * extent;
    tbb::parallel_for(std::size_t(0), count, [&](std::size_t t) {
        if (!flat(t)) return;
        const Footprint footprint = footprintOf(t);
        const glm::ivec2 home = cellOf(footprint.centroid);
        const double distance = (at(home.x, home.y) - 1) * cell - footprint.reach - margin;
        if (distance > 0.0) distances[t] = float(distance) * (1.0f - 1e-6f);
    });
    grid = {origin, axisU, axisV, low, cell, margin, columns, rows, {}};
    grid.steps.resize(steps.size());
    for (std::size_t index = 0; index < steps.size(); ++index)  // saturated: still a lower bound
        grid.steps[index] = std::uint16_t(std::min(steps[index], 0xffff));
    return distances;
}

}  // namespace

float detail::BorderGrid::distanceWorld(const glm::vec3& point) const {
    if (steps.empty()) return 0.0f;
    const glm::dvec3 offset = glm::dvec3(point) - origin;
    const double u = (glm::dot(offset, axisU) - low.x) / cellWorld;
    const double v = (glm::dot(offset, axisV) - low.y) / cellWorld;
    if (!(u >= 0.0 && v >= 0.0 && u < double(columns) && v < double(rows))) return 0.0f;
    const int k = steps[std::size_t(v) * std::size_t(columns) + std::size_t(u)];
    return float(std::max((k - 1) * cellWorld - marginWorld, 0.0)) * (1.0f - 1e-6f);
}

glm::vec3 ShellEntry::toTexel(const glm::vec3& world) const {
    if (curved) return texelFromWorld * world;
    return {glm::dot(world, tangent) * texelsPerWorld.x,
            glm::dot(world, bitangent) * texelsPerWorld.y,
            glm::dot(world, normal) * texelsPerWorld.z};
}

glm::vec3 ShellEntry::gradientToWorld(const glm::vec3& gradient) const {
    // Texel = M world with M's rows T sx, B sy, N sz; gradients transform with M transposed.
    if (curved) return glm::transpose(texelFromWorld) * gradient;
    return tangent * (gradient.x * texelsPerWorld.x) + bitangent * (gradient.y * texelsPerWorld.y) +
           normal * (gradient.z * texelsPerWorld.z);
}

SceneTracer::SceneTracer(const Scene& scene, const TraceOptions& options)
    : scene_(scene), options_(options) {
    std::size_t triangleCount = 0;
    for (const SceneObject& object : scene.objects) triangleCount += object.mesh.triangles.size();
    triangles_.resize(triangleCount);
    std::vector<glm::vec3> corners(3 * triangleCount);
    std::size_t firstTriangle = 0;  // of the object, in triangles_
    for (std::uint32_t objectIndex = 0; objectIndex < scene.objects.size(); ++objectIndex) {
        const SceneObject& object = scene.objects[objectIndex];
        const BaseMesh& mesh = object.mesh;
        const Tile* tile = object.material.tile.get();
        if (tile) {
            requireTexelDensity(objectIndex, float(tile->size().depth) / object.material.depthWorld,
                                "depth", "a larger depth");
        }
        // The shell of the object's triangle t.
        auto shellTriangle = [&](std::uint32_t t) {
            const glm::uvec3 triangle = mesh.triangles[t];
            const glm::vec2 texelsPerWorld =
                tile ? texelsPerWorldUv(mesh, triangle, object.material.uvScale, tile->size())
                     : glm::vec2(0.0f);
            const glm::vec3& p0 = mesh.positions[triangle[0]];
            const glm::vec3& p1 = mesh.positions[triangle[1]];
            const glm::vec3& p2 = mesh.positions[triangle[2]];
            ShellTriangle shell{objectIndex, t, texelsPerWorld, glm::cross(p1 - p0, p2 - p0),
                                DoubleTriangle(p0, p1, p2)};
            const bool sameCorners = mesh.normals[triangle[0]] == mesh.normals[triangle[1]] &&
                                     mesh.normals[triangle[0]] == mesh.normals[triangle[2]] &&
                                     mesh.tangents[triangle[0]] == mesh.tangents[triangle[1]] &&
                                     mesh.tangents[triangle[0]] == mesh.tangents[triangle[2]];
            if (sameCorners) {
                shell.flatFrame = true;
                ShellEntry frame;
                setFrame(frame, mesh.normals[triangle[0]], mesh.tangents[triangle[0]]);
                shell.frameNormal = frame.normal;
                shell.frameTangent = frame.tangent;
                shell.frameBitangent = frame.bitangent;
            }
            shell.curved = shell.hasDetail() && !shell.flatFrame &&
                           options.shellMapping == ShellMapping::Curved;
            return shell;
        };
        const auto count = std::uint32_t(mesh.triangles.size());
        tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, count, 1024),
                          [&](const tbb::blocked_range<std::uint32_t>& range) {
                              for (std::uint32_t t = range.begin(); t != range.end(); ++t) {
                                  for (int corner = 0; corner < 3; ++corner)
                                      corners[3 * (firstTriangle + t) + corner] =
                                          mesh.positions[mesh.triangles[t][corner]];
                                  triangles_[firstTriangle + t] = shellTriangle(t);
                              }
                          });
        // Checked in triangle order, so an error names the first triangle's density whatever
        // the threads did.
        if (tile) {
            const char* remedy = "a smaller uv_scale or a larger mesh";
            for (std::uint32_t t = 0; t < count; ++t) {
                const glm::vec2 texelsPerWorld = triangles_[firstTriangle + t].texelsPerWorldUv;
                requireTexelDensity(objectIndex, texelsPerWorld.x, "u", remedy);
                requireTexelDensity(objectIndex, texelsPerWorld.y, "v", remedy);
            }
        }
        firstTriangle += count;
    }
    // Independent: the base triangles' BVH, and the curved shells' prisms and flat shells' borders.
    tbb::parallel_invoke([&] { bvh_ = TriangleBvh(std::move(corners)); },
                         [&] {
                             buildShellMap();
                             buildBorders();  // takes the shell map's neighbours
                         });
    shellPrisms_ = {prisms_, neighbours_, neighbourCorners_};

    // Per tile (objects sharing one share these): its columns, and its empty space where the
    // skip holds (for the filters whose support the occupancy bounds).
    const bool skipEmptySpace =
        options.skips.emptySpace && !options.reference &&
        (options.filter == FilterKind::Trilinear || options.filter == FilterKind::Nearest ||
         options.filter == FilterKind::TricubicBSpline);
    const OccupancySupport support = options.filter == FilterKind::TricubicBSpline
                                         ? OccupancySupport::CubicBSpline
                                         : OccupancySupport::Linear;
    columns_.resize(scene.objects.size());
    occupancies_.resize(scene.objects.size());
    for (std::size_t object = 0; object < scene.objects.size(); ++object) {
        const Tile* tile = scene.objects[object].material.tile.get();
        if (!tile) continue;
        std::size_t first = 0;
        while (scene.objects[first].material.tile.get() != tile) ++first;
        if (first < object) {
            columns_[object] = columns_[first];
            occupancies_[object] = occupancies_[first];
            continue;
        }
        columns_[object] = std::make_shared<const TileColumns>(*tile);
        if (skipEmptySpace) {
            // Tiles without empty space to skip keep no occupancy: their rays pay nothing for it.
            auto occupancy =
                std::make_shared<const TileOccupancy>(*tile, options.march.epsilonTexels, support);
            if (occupancy->hasEmptySpace()) occupancies_[object] = std::move(occupancy);
        }
    }
}

[[gnu::always_inline]] inline void SceneTracer::shellEntry(const TriangleHit& hit, const Ray& ray,
                                                           ShellEntry& entry) const {
    const ShellTriangle& shell = triangles_[hit.triangle];
    const SceneObject& object = scene_.objects[shell.object];
    const BaseMesh& mesh = object.mesh;
    const glm::uvec3 triangle = mesh.triangles[shell.localTriangle];
    // Frames and uvs for shading take the weights in float; the march's start, the double ones.
    const float b1 = float(hit.b1), b2 = float(hit.b2);
    const float b0 = 1.0f - b1 - b2;
    auto interpolate = [&](const auto& values) {
        return values[triangle[0]] * b0 + values[triangle[1]] * b1 + values[triangle[2]] * b2;
    };
    entry.position = ray.origin + ray.direction * hit.distanceWorld;
    entry.curved = false;
    if (shell.flatFrame) {
        entry.normal = shell.frameNormal;
        entry.tangent = shell.frameTangent;
        entry.bitangent = shell.frameBitangent;
    } else {
        setFrame(entry, interpolate(mesh.normals), interpolate(mesh.tangents));
    }
    entry.uv = interpolate(mesh.uvs);
    entry.frontFacing = shell.frontFacing(ray.direction);
    const Tile* tile = object.material.tile.get();
    const float depthTexels = tile ? float(tile->size().depth) : 1.0f;
    entry.texelsPerWorld = {shell.texelsPerWorldUv.x, shell.texelsPerWorldUv.y,
                            depthTexels / object.material.depthWorld};
}

bool SceneTracer::entersFrontFirst(const Ray& ray, float minDistance, std::uint32_t object,
                                   float distanceWorld) const {
    // Past other objects' triangles, a bounded number of them (then: not known to be an opening).
    constexpr int kMaxOtherTriangles = 16;
    TriangleHit baseHit;
    float from = minDistance;
    for (int other = 0; other <= kMaxOtherTriangles; ++other) {
        if (!bvh_.intersect(ray, from, distanceWorld, baseHit)) return false;
        const ShellTriangle& triangle = triangles_[baseHit.triangle];
        if (triangle.object == object) return triangle.frontFacing(ray.direction);
        from = baseHit.distanceWorld;
    }
    return false;
}

float SceneTracer::exitDistance(const Ray& ray, float fromDistance, std::uint32_t object) const {
    constexpr int kMaxTriangles = 16;
    TriangleHit baseHit;
    float from = fromDistance;
    for (int passed = 0; passed <= kMaxTriangles; ++passed) {
        if (!bvh_.intersect(ray, from, std::numeric_limits<float>::max(), baseHit))
            return std::numeric_limits<float>::infinity();
        const ShellTriangle& triangle = triangles_[baseHit.triangle];
        if (triangle.object == object && !triangle.frontFacing(ray.direction))
            return baseHit.distanceWorld;
        from = baseHit.distanceWorld;
    }
    return std::numeric_limits<float>::infinity();
}

bool SceneTracer::traceNearest(const Ray& ray, float minDistance, SurfaceHit& hit,
                               TraceCounters& counters) const {
    bool found = false;
    traceNearestBatch(std::span<const Ray>(&ray, 1), minDistance, std::span<SurfaceHit>(&hit, 1),
                      std::span<bool>(&found, 1), counters);
    return found;
}

void SceneTracer::traceNearestBatch(std::span<const Ray> rays, float minDistance,
                                    std::span<SurfaceHit> hits, std::span<bool> found,
                                    TraceCounters& counters, bool withNormals) const {
    const std::size_t count = rays.size();
    // An open floor lets a ray leave a shell through a hole and go on (another pass from where
    // it left); bounded by the object count so a ray cannot loop.
    const std::size_t maxPasses = scene_.objects.size() + 2;
    float from[kMaxBatchRays];
    // A ray that left a curved shell through its top crosses that top from behind just after:
    // back faces nearer than this are the way out, not a stop.
    float skipBackFacesBefore[kMaxBatchRays];
    std::size_t passes[kMaxBatchRays];
    bool active[kMaxBatchRays];
    for (std::size_t r = 0; r < count; ++r) {
        from[r] = minDistance;
        skipBackFacesBefore[r] = minDistance;
        passes[r] = 0;
        active[r] = true;
        found[r] = false;
    }
    ShellMarch marches[kMaxBatchRays];
    ShellMarch* pending[kMaxBatchRays];
    std::size_t pendingRay[kMaxBatchRays];
    // Rays along one direction (a shadow map's light rays) meet the base triangles together.
    const bool parallel = count > 1 && std::all_of(rays.begin(), rays.end(), [&](const Ray& ray) {
                              return ray.direction == rays[0].direction;
                          });
    constexpr float kFar = std::numeric_limits<float>::max();
    TriangleHit baseHits[kMaxBatchRays];
    bool onTops[kMaxBatchRays];
    for (;;) {
        // Each active ray's first base triangle on from where it is (none past its passes).
        std::size_t tracing[kMaxBatchRays];
        std::size_t tracingCount = 0;
        for (std::size_t r = 0; r < count; ++r) {
            if (!active[r]) continue;
            onTops[r] = false;
            if (passes[r]++ != maxPasses) tracing[tracingCount++] = r;
        }
        if (parallel) {
            for (std::size_t first = 0; first < tracingCount; first += TriangleBvh::kPacketRays) {
                const std::size_t size = std::min(TriangleBvh::kPacketRays, tracingCount - first);
                Ray packet[TriangleBvh::kPacketRays];
                float packetFrom[TriangleBvh::kPacketRays];
                TriangleHit packetHits[TriangleBvh::kPacketRays];
                bool packetFound[TriangleBvh::kPacketRays];
                for (std::size_t k = 0; k < size; ++k) {
                    packet[k] = rays[tracing[first + k]];
                    packetFrom[k] = from[tracing[first + k]];
                }
                bvh_.intersectParallel(std::span(packet, size), std::span(packetFrom, size), kFar,
                                       std::span(packetHits, size), std::span(packetFound, size));
                for (std::size_t k = 0; k < size; ++k) {
                    onTops[tracing[first + k]] = packetFound[k];
                    baseHits[tracing[first + k]] = packetHits[k];
                }
            }
        } else {
            for (std::size_t t = 0; t < tracingCount; ++t) {
                const std::size_t r = tracing[t];
                onTops[r] = bvh_.intersect(rays[r], from[r], kFar, baseHits[r]);
            }
        }
        std::size_t pendingCount = 0;
        for (std::size_t r = 0; r < count; ++r) {
            if (!active[r]) continue;
            TriangleHit& baseHit = baseHits[r];
            bool onTop = onTops[r];
            while (onTop && baseHit.distanceWorld < skipBackFacesBefore[r] &&
                   !triangles_[baseHit.triangle].frontFacing(rays[r].direction)) {
                onTop = passes[r]++ != maxPasses &&
                        bvh_.intersect(rays[r], baseHit.distanceWorld, kFar, baseHit);
            }
            // A side on an open border before the top the ray meets: it enters there.
            if (passes[r] <= maxPasses &&
                enterNearestSide(rays[r], from[r], onTop ? baseHit.distanceWorld : kFar, hits[r],
                                 marches[r])) {
                pending[pendingCount] = &marches[r];
                pendingRay[pendingCount++] = r;
                continue;
            }
            if (!onTop) {
                active[r] = false;
                continue;
            }
            if (!enterAt(rays[r], baseHit, hits[r], marches[r])) {  // stops on the base surface
                found[r] = true;
                active[r] = false;
                continue;
            }
            pending[pendingCount] = &marches[r];
            pendingRay[pendingCount++] = r;
        }
        if (pendingCount == 0) return;
        const std::span<ShellMarch* const> taken(pending, pendingCount);
        takeEntries(taken);
        takeMarches(taken);
        if (withNormals) takeGradients(taken);
        for (std::size_t p = 0; p < pendingCount; ++p) {
            const std::size_t r = pendingRay[p];
            const ShellMarch& march = marches[r];
            if (finishShell(rays[r], march, hits[r], counters, withNormals)) {
                found[r] = true;
                active[r] = false;
            } else if (march.curved) {  // out of a curved shell: on from where it left
                from[r] = march.lastInsideWorld;
                skipBackFacesBefore[r] = march.firstOutsideWorld;
            } else {  // out through an open floor: on from where it left
                from[r] = march.baseHit.distanceWorld +
                          march.result.travelTexels / hits[r].texelsPerWorldAlongRay;
            }
        }
    }
}

void SceneTracer::shellCorners(std::uint32_t shell, glm::vec3 top[3], glm::vec3 bottom[3]) const {
    const ShellTriangle& triangle = triangles_[shell];
    const SceneObject& object = scene_.objects[triangle.object];
    const glm::uvec3 vertices = object.mesh.triangles[triangle.localTriangle];
    const float depthWorld = object.material.tile ? object.material.depthWorld : 0.0f;
    for (int corner = 0; corner < 3; ++corner) {
        top[corner] = object.mesh.positions[vertices[corner]];
        bottom[corner] = top[corner] - object.mesh.normals[vertices[corner]] * depthWorld;
    }
}

void SceneTracer::baseSurfaceHit(const Ray& ray, const TriangleHit& baseHit,
                                 SurfaceHit& hit) const {
    ShellEntry entry;
    shellEntry(baseHit, ray, entry);
    hit.entry = entry;
    atEntry(baseHit, entry.position, entry.normal, hit);
}

void SceneTracer::atEntry(const TriangleHit& baseHit, const glm::vec3& position,
                          const glm::vec3& normal, SurfaceHit& hit) const {
    hit.object = triangles_[baseHit.triangle].object;
    hit.distanceWorld = baseHit.distanceWorld;
    hit.position = position;
    hit.normal = normal;
    hit.onDetail = false;
    hit.texelsPerWorldAlongRay = 0.0f;
    hit.entryBorderClearanceWorld = std::numeric_limits<float>::infinity();
}

void SceneTracer::takeEntry(ShellMarch& march) const {
    const Ray& ray = *march.ray;
    SurfaceHit& hit = *march.hit;
    const TriangleHit& baseHit = march.baseHit;
    const ShellTriangle& shell = triangles_[baseHit.triangle];
    const Material& material = scene_.objects[shell.object].material;
    baseSurfaceHit(ray, baseHit, hit);
    const Size3& size = material.tile->size();
    glm::vec3 direction = hit.entry.toTexel(ray.direction);
    // Silhouettes of smooth-shaded meshes can tilt the interpolated frame until the ray no
    // longer descends; keep it descending so the march stays in the shell.
    float texelsPerWorldAlongRay = glm::length(direction);
    const float steepest = -1e-3f * texelsPerWorldAlongRay;
    if (steepest < direction.z) {  // std::min(direction.z, steepest), the length anew
        direction.z = steepest;
        texelsPerWorldAlongRay = glm::length(direction);
    }
    direction /= texelsPerWorldAlongRay;
    hit.texelsPerWorldAlongRay = texelsPerWorldAlongRay;
    march.directionTexels = direction;
    // Wrap the entry point into the tile in double precision: far repeats keep their
    // sub-texel position. The uv is interpolated here in double from the corners (as corner 0 plus
    // the weighted edge deltas), not taken from the float entry.uv: near uv 1e4 a float
    // interpolation is off by a few ulps of 2^-10, a tenth of a texel (tests/stress_test.cpp).
    const BaseMesh& baseMesh = scene_.objects[shell.object].mesh;
    const glm::uvec3 corners = baseMesh.triangles[shell.localTriangle];
    auto interpolateUv = [&](int axis) {
        const double first = baseMesh.uvs[corners[0]][axis];
        return first + baseHit.b1 * (double(baseMesh.uvs[corners[1]][axis]) - first) +
               baseHit.b2 * (double(baseMesh.uvs[corners[2]][axis]) - first);
    };
    const double u = interpolateUv(0) * material.uvScale.x;
    const double v = interpolateUv(1) * material.uvScale.y;
    const glm::vec3 start(float((u - std::floor(u)) * size.width),
                          float((v - std::floor(v)) * size.height),
                          float(size.depth) - march.entryDepthWorld * hit.entry.texelsPerWorld.z);
    // Reference renders of detail with an exact first hit (mesh truth) take it instead of marching.
    if (options_.reference && material.exactHit) {
        march.startTexels = start;
        march.skippedTexels = 0.0f;
        setBorderExit(march, flatSidesOf(march.baseHit.triangle));
        march.result = exactFirstHit(material, start, direction, march.leaveTravelTexels,
                                     march.gradientTexels);
        march.gradientKnown = true;
        march.marched = true;
        return;
    }
    // The empty path above the detail needs no samples: the march starts where it ends.
    const TileOccupancy* occupancy = occupancies_[shell.object].get();
    // The block walk costs about what a few samples do: for the trilinear march (8 samples per
    // AVX2 call, sampler/trilinear_wide.h) more than the samples it saves (on the sheet with a low
    // height field, bench --speed), for the nearest and the 64-tap tricubic marches much less. The
    // jump to the highest top is always worth it. Not decided by the processor, so every machine
    // gives the same image.
    const bool walkBlocks = options_.filter != FilterKind::Trilinear;
    march.skippedTexels =
        occupancy ? occupancy->emptyTravelTexels(start, direction, walkBlocks) : 0.0f;
    march.startTexels = start + direction * march.skippedTexels;
    beginMarch(march, flatSidesOf(march.baseHit.triangle));
}

void SceneTracer::beginMarch(ShellMarch& march, const FlatSides* sides) const {
    march.settings = options_.march;
    setBorderExit(march, sides);
    if (const auto refused =
            refusedMarch(march.startTexels, march.directionTexels, march.settings)) {
        march.result = *refused;
        march.marched = true;
    } else if (isSphereTracing(march.settings.method)) {
        march.trace.start(march.startTexels, march.directionTexels,
                          scene_.objects[march.object].material.floor, march.settings,
                          march.leaveTravelTexels);
    }
}

const SceneTracer::FlatSides* SceneTracer::flatSidesOf(std::uint32_t shell) const {
    const ShellTriangle& triangle = triangles_[shell];
    if (!triangle.flatFrame || flatSidesFirst_[triangle.object] == kNoFlatBorder) return nullptr;
    return &flatSides_[flatSidesFirst_[triangle.object] + triangle.localTriangle];
}

void SceneTracer::setBorderExit(ShellMarch& march, const FlatSides* sides) const {
    // The entry's distance to the nearest side of its triangle, or the triangle's to the border,
    // whichever is larger (atEntry left +infinity for a shell without sides).
    SurfaceHit& hit = *march.hit;
    hit.entryShell = march.baseHit.triangle;
    if (sides) {
        const float b1 = float(march.baseHit.b1), b2 = float(march.baseHit.b2);
        const float weights[3] = {1.0f - b1 - b2, b1, b2};
        hit.entryBorderClearanceWorld =
            std::max(std::min({weights[0] * sides->height[0], weights[1] * sides->height[1],
                               weights[2] * sides->height[2]}),
                     sides->borderDistanceWorld);
    }
    march.leaveTravelTexels = leaveTravelTexels(march, sides);
}

float SceneTracer::leaveTravelTexels(const ShellMarch& march, const FlatSides* sides) const {
    constexpr float kNever = std::numeric_limits<float>::infinity();
    if (!sides) return kNever;
    // Most rays end far from every side of their triangle: a path to the floor shorter than
    // the entry's clearance cannot leave (no division: both sides of path < clearance x
    // texelsPerWorld taken times the descent).
    const float nearestSideWorld = march.hit->entryBorderClearanceWorld;
    const float descent = -march.directionTexels.z;
    if (march.skippedTexels * descent + march.startTexels.z <
        nearestSideWorld * march.hit->texelsPerWorldAlongRay * descent)
        return kNever;
    // The march's path ends on the floor: from the top's entry, the skipped empty path and the
    // path to the floor, at texelsPerWorldAlongRay texels per world unit (as finishShell maps
    // travel back to the ray).
    const double texelsPerWorld = march.hit->texelsPerWorldAlongRay;
    const double entryWorld = march.baseHit.distanceWorld;
    const double toFloorTexels = march.startTexels.z / -march.directionTexels.z;
    // Then the entry's own distance to the border, from the plane's grid.
    if ((march.skippedTexels + toFloorTexels) / texelsPerWorld <
        borderGrids_[march.object].distanceWorld(march.hit->entry.position))
        return kNever;
    const double exitWorld =
        borderExitWorld(glm::dvec3(march.ray->origin), glm::dvec3(march.ray->direction),
                        march.baseHit.triangle,
                        entryWorld + (march.skippedTexels + toFloorTexels) / texelsPerWorld)
            .exitWorld;
    if (!(exitWorld < std::numeric_limits<double>::infinity())) return kNever;
    return float((exitWorld - entryWorld) * texelsPerWorld - march.skippedTexels);
}

SceneTracer::BorderWalk SceneTracer::borderExitWorld(const glm::dvec3& origin,
                                                     const glm::dvec3& direction,
                                                     std::uint32_t shell, double endWorld) const {
    const ShellTriangle& entered = triangles_[shell];
    const std::uint32_t firstShell = shell - entered.localTriangle;  // the object's first
    const std::uint32_t first = flatSidesFirst_[entered.object];
    const BaseMesh& mesh = scene_.objects[entered.object].mesh;
    std::uint32_t triangle = entered.localTriangle;
    for (int walk = 0; walk < kMaxBorderWalk; ++walk) {
        const ShellTriangle& crossed = triangles_[firstShell + triangle];
        if (!crossed.flatWithDetail()) return {};
        const FlatSides& sides = flatSides_[first + triangle];
        const glm::dvec3 normal(crossed.frameNormal);
        // The ray is inside the prism until it crosses the first side it moves out through.
        double exitWorld = std::numeric_limits<double>::infinity();
        int exitSide = -1;
        for (int side = 0; side < 3; ++side) {
            glm::dvec3 outward;
            double offset = 0.0;
            flatSidePlane(mesh, mesh.triangles[triangle], normal, side, outward, offset);
            const double away = glm::dot(direction, outward);
            if (!(away > 0.0)) continue;
            const double at = (offset - glm::dot(origin, outward)) / away;
            if (at < exitWorld) {
                exitWorld = at;
                exitSide = side;
            }
        }
        if (exitSide < 0 || !(exitWorld < endWorld)) return {.endShell = firstShell + triangle};
        triangle = sides.neighbour[exitSide];
        if (triangle == ShellPrisms::kNoNeighbour) return {.exitWorld = exitWorld};
    }
    return {};
}

float SceneTracer::selfShadowTopTexels(const SurfaceHit& hit, const glm::vec3& toLightWorld,
                                       const glm::vec3& startTexels, const glm::vec3& toLightTexels,
                                       float topTexels) const {
    if (!(hit.entryBorderClearanceWorld < std::numeric_limits<float>::infinity()) ||
        !(toLightTexels.z > 0.0f))
        return topTexels;
    // Both paths, the camera ray's from its entry to the hit and this ray's to the top, stay
    // within their lengths of the entry: shorter together than its clearance, neither leaves.
    // Most hits stop here, so no root and no division: the light's rise in texels per world unit
    // is the flat frame's z of its direction, and both sides are taken times the two scales.
    const float risePerWorld =
        glm::dot(toLightWorld, hit.entry.normal) * hit.entry.texelsPerWorld.z;
    const float alongRay = hit.texelsPerWorldAlongRay;
    if ((hit.march.travelTexels * risePerWorld + (topTexels - startTexels.z) * alongRay) *
            (1.0f + 1e-5f) <
        hit.entryBorderClearanceWorld * alongRay * risePerWorld)
        return topTexels;
    // Then the hit's own distance to the border, from the plane's grid.
    const double toTopWorld = double(topTexels - startTexels.z) / double(risePerWorld);
    if (toTopWorld < borderGrids_[hit.object].distanceWorld(hit.position)) return topTexels;
    // The shell under the hit, then where this ray leaves from there.
    const double texelsPerWorldToLight = double(risePerWorld) / double(toLightTexels.z);
    const glm::dvec3 entry(hit.entry.position), at(hit.position);
    const double cameraPathWorld = glm::length(at - entry);
    std::uint32_t shell = hit.entryShell;
    if (cameraPathWorld > 0.0) {
        shell =
            borderExitWorld(entry, (at - entry) / cameraPathWorld, shell, cameraPathWorld).endShell;
        if (shell == kNoShell) return topTexels;
    }
    const double exitWorld =
        borderExitWorld(at, glm::dvec3(toLightWorld), shell, toTopWorld).exitWorld;
    if (!(exitWorld < toTopWorld)) return topTexels;
    return std::min(
        topTexels,
        startTexels.z + float(std::max(exitWorld, 0.0) * texelsPerWorldToLight) * toLightTexels.z);
}

void SceneTracer::addBorderFaces(std::uint32_t shell, int side) {
    glm::vec3 top[3], bottom[3];
    shellCorners(shell, top, bottom);
    const int from = (side + 1) % 3, to = (side + 2) % 3;
    for (const std::array<glm::vec3, 3>& face : {std::array{top[from], top[to], bottom[to]},
                                                 std::array{top[from], bottom[to], bottom[from]}}) {
        // Away from the prism: from the opposite corner, whose top lies inside.
        glm::vec3 outward = glm::cross(face[1] - face[0], face[2] - face[0]);
        if (glm::dot(outward, top[side] - face[0]) > 0.0f) outward = -outward;
        const float length = glm::length(outward);
        if (!(length > 0.0f)) continue;  // no area: no ray enters there
        borderFaces_.push_back({DoubleTriangle(face[0], face[1], face[2]),
                                {face[0], face[1], face[2]},
                                outward / length,
                                shell,
                                std::uint8_t(side)});
    }
}

void SceneTracer::buildBorders() {
    flatSidesFirst_.assign(scene_.objects.size(), kNoFlatBorder);
    borderGrids_.resize(scene_.objects.size());
    std::uint32_t firstShell = 0;
    for (std::size_t objectIndex = 0; objectIndex < scene_.objects.size(); ++objectIndex) {
        const BaseMesh& mesh = scene_.objects[objectIndex].mesh;
        const auto count = std::uint32_t(mesh.triangles.size());
        const std::span<const ShellTriangle> shells(triangles_.data() + firstShell, count);
        if (std::none_of(shells.begin(), shells.end(),
                         [](const ShellTriangle& shell) { return shell.flatWithDetail(); })) {
            firstShell += count;
            continue;
        }
        // The object's neighbours, numbered within it: the shell map's when it has curved
        // shells (buildShellMap ran), else found here.
        std::vector<std::array<std::uint32_t, 3>> neighbours(count);
        if (std::any_of(shells.begin(), shells.end(),
                        [](const ShellTriangle& shell) { return shell.curved; })) {
            for (std::uint32_t t = 0; t < count; ++t) {
                for (std::size_t side = 0; side < 3; ++side) {
                    const std::uint32_t across = neighbours_[firstShell + t][side];
                    neighbours[t][side] =
                        across == ShellPrisms::kNoNeighbour ? across : across - firstShell;
                }
            }
        } else {
            std::vector<std::array<std::uint8_t, 3>> neighbourCorners(count);
            buildNeighboursInto(mesh, 0, neighbours, neighbourCorners);
        }
        bool openBorder = false;
        std::vector<glm::vec3> flatNormals(count, glm::vec3(0.0f));
        for (std::uint32_t t = 0; t < count; ++t) {
            if (!shells[t].flatWithDetail()) continue;
            flatNormals[t] = shells[t].frameNormal;
            for (const std::uint32_t across : neighbours[t])
                openBorder = openBorder || across == ShellPrisms::kNoNeighbour;
        }
        if (!openBorder) {
            firstShell += count;
            continue;
        }
        const std::vector<float> borderDistances =
            planarBorderDistances(mesh, flatNormals, neighbours, borderGrids_[objectIndex]);
        flatSidesFirst_[objectIndex] = std::uint32_t(flatSides_.size());
        flatSides_.resize(flatSides_.size() + count);
        FlatSides* sides = flatSides_.data() + flatSidesFirst_[objectIndex];
        tbb::parallel_for(std::uint32_t(0), count, [&](std::uint32_t t) {
            if (!shells[t].flatWithDetail()) return;
            for (int side = 0; side < 3; ++side) {
                glm::dvec3 outward;
                double offset = 0.0;
                flatSidePlane(mesh, mesh.triangles[t], glm::dvec3(shells[t].frameNormal), side,
                              outward, offset);
                const glm::dvec3 opposite(mesh.positions[mesh.triangles[t][side]]);
                sides[t].height[side] =
                    float((offset - glm::dot(outward, opposite)) / glm::length(outward));
                sides[t].neighbour[side] = neighbours[t][std::size_t(side)];
            }
            sides[t].borderDistanceWorld = borderDistances[t];
        });
        for (std::uint32_t t = 0; t < count; ++t) {
            if (!shells[t].flatWithDetail()) continue;
            for (int side = 0; side < 3; ++side)
                if (sides[t].neighbour[side] == ShellPrisms::kNoNeighbour)
                    addBorderFaces(firstShell + t, side);
        }
        firstShell += count;
    }
    // The curved shells' sides on an open border: the shell map's neighbours.
    for (std::uint32_t shell = 0; shell < shellCount(); ++shell) {
        if (!triangles_[shell].curved || !triangles_[shell].hasDetail()) continue;
        for (int side = 0; side < 3; ++side)
            if (neighbours_[shell][std::size_t(side)] == ShellPrisms::kNoNeighbour)
                addBorderFaces(shell, side);
    }
    if (borderFaces_.empty()) return;
    std::vector<glm::vec3> corners;
    corners.reserve(borderFaces_.size() * 3);
    for (const BorderFace& face : borderFaces_)
        corners.insert(corners.end(), std::begin(face.corners), std::end(face.corners));
    borderBvh_ = TriangleBvh(std::move(corners));
}

void SceneTracer::entryFaceCorners(std::uint32_t face, glm::vec3 top[3],
                                   glm::vec3 bottom[3]) const {
    if (face < shellCount()) {
        shellCorners(face, top, bottom);
        return;
    }
    for (int corner = 0; corner < 3; ++corner)
        top[corner] = bottom[corner] = borderFaces_[face - shellCount()].corners[corner];
}

bool SceneTracer::enterSide(const Ray& ray, std::uint32_t face, float distanceWorld,
                            SurfaceHit& hit, ShellMarch& march) const {
    const BorderFace& border = borderFaces_[face];
    const ShellTriangle& shell = triangles_[border.shell];
    // In from outside; into a flat shell also down (its straight march descends from there; the
    // curved march follows the ray wherever it goes).
    if (!(glm::dot(ray.direction, border.outward) < 0.0f) ||
        (!shell.curved && !shell.frontFacing(ray.direction)))
        return false;
    const SceneObject& object = scene_.objects[shell.object];
    const glm::uvec3 corners = object.mesh.triangles[shell.localTriangle];
    const int from = (border.side + 1) % 3, to = (border.side + 2) % 3;
    const glm::dvec3 a(object.mesh.positions[corners[from]]);
    const glm::dvec3 b(object.mesh.positions[corners[to]]);
    const glm::dvec3 point =
        glm::dvec3(ray.origin) + glm::dvec3(ray.direction) * double(distanceWorld);
    // The point over the top's edge where the ray enters, and how far below it.
    const double along = std::clamp(glm::dot(point - a, b - a) / glm::dot(b - a, b - a), 0.0, 1.0);
    double weights[3] = {};
    weights[from] = 1.0 - along;
    weights[to] = along;
    startMarch(ray, {border.shell, distanceWorld, weights[1], weights[2]}, hit, march);
    // Below the top along the flat frame's normal; a curved shell's march finds its depth itself
    // (any depth above 0 marks the side).
    march.entryDepthWorld =
        shell.curved ? object.material.depthWorld
                     : float(std::clamp(glm::dot(a - point, glm::dvec3(shell.frameNormal)), 0.0,
                                        double(object.material.depthWorld)));
    return true;
}

bool SceneTracer::enterNearestSide(const Ray& ray, float minDistance, float maxDistance,
                                   SurfaceHit& hit, ShellMarch& march) const {
    if (borderFaces_.empty()) return false;
    // Past sides seen from inside (a ray leaving a prism there), a bounded number of them.
    constexpr int kMaxPassed = 8;
    float from = minDistance;
    TriangleHit faceHit;
    for (int passed = 0; passed <= kMaxPassed; ++passed) {
        if (!borderBvh_.intersect(ray, from, maxDistance, faceHit)) return false;
        if (enterSide(ray, faceHit.triangle, faceHit.distanceWorld, hit, march)) return true;
        from = faceHit.distanceWorld;
    }
    return false;
}

bool SceneTracer::entersFlatShell(std::uint32_t shell) const {
    // takeEntry's jump over the empty layers without the block walk (trilinear), or no occupancy.
    return kSimdLevel >= SimdLevel::Avx2 && triangles_[shell].flatFrame && !options_.reference &&
           (options_.filter == FilterKind::Trilinear || !occupancies_[triangles_[shell].object]);
}

void SceneTracer::takeEntries(std::span<ShellMarch* const> marches) const {
    ShellMarch* flat[kMaxBatchRays];
    std::uint32_t shells[kMaxBatchRays];
    std::size_t flatCount = 0;
    // The curved marches' state, once per thread (most marches are not curved: a ShellMarch
    // does not carry it).
    struct CurvedTraces {
        CurvedMarchRay rays[kMaxBatchRays];
    };
    CurvedMarchRay* curvedTraces = threadScratch<CurvedTraces>().rays;
    std::size_t curvedCount = 0;
    for (ShellMarch* march : marches) {
        if (triangles_[march->baseHit.triangle].curved) {
            takeCurvedEntry(*march, curvedTraces[curvedCount++]);
        } else if (march->entryDepthWorld == 0.0f && entersFlatShell(march->baseHit.triangle)) {
            shells[flatCount] = march->baseHit.triangle;
            flat[flatCount++] = march;
        } else {
            takeEntry(*march);
        }
    }
    forEachGroup(
        std::span<ShellMarch* const>(flat, flatCount),
        std::span<const std::uint32_t>(shells, flatCount),
        [&](std::uint32_t, std::span<ShellMarch* const> sameShell) { takeFlatEntries(sameShell); });
}

void SceneTracer::takeFlatEntries(std::span<ShellMarch* const> sameShell) const {
    const TriangleHit& firstHit = sameShell[0]->baseHit;
    const ShellTriangle& shell = triangles_[firstHit.triangle];
    const SceneObject& object = scene_.objects[shell.object];
    const Material& material = object.material;
    const Size3& size = material.tile->size();
    // The entry every ray of this shell shares (shellEntry's flat frame: every ray that enters
    // meets its front), and the kernel's constants from it.
    ShellEntry shared;
    shellEntry(firstHit, *sameShell[0]->ray, shared);
    detail::FlatShellConstants constants;
    for (int axis = 0; axis < 3; ++axis) {
        constants.tangent[axis] = shared.tangent[axis];
        constants.bitangent[axis] = shared.bitangent[axis];
        constants.normal[axis] = shared.normal[axis];
        constants.texelsPerWorld[axis] = shared.texelsPerWorld[axis];
    }
    const glm::uvec3 corners = object.mesh.triangles[shell.localTriangle];
    for (int corner = 0; corner < 3; ++corner) {
        constants.uvCorners[corner][0] = object.mesh.uvs[corners[corner]].x;
        constants.uvCorners[corner][1] = object.mesh.uvs[corners[corner]].y;
    }
    constants.uvScale[0] = material.uvScale.x;
    constants.uvScale[1] = material.uvScale.y;
    constants.tileWidth = size.width;
    constants.tileHeight = size.height;
    constants.tileDepth = size.depth;
    const TileOccupancy* occupancy = occupancies_[shell.object].get();
    constants.highestTopTexels =
        occupancy ? occupancy->highestTopTexels() : std::numeric_limits<float>::infinity();
    const FlatSides* const sides = flatSidesOf(firstHit.triangle);

    for (std::size_t first = 0; first < sameShell.size(); first += 8) {
        const std::span<ShellMarch* const> eight =
            sameShell.subspan(first, std::min<std::size_t>(8, sameShell.size() - first));
        detail::EntryLanes lanes;
        for (std::size_t lane = 0; lane < 8; ++lane) {
            const ShellMarch& march = *eight[lane < eight.size() ? lane : 0];  // padded
            for (int axis = 0; axis < 3; ++axis) {
                lanes.origin[axis][lane] = march.ray->origin[axis];
                lanes.direction[axis][lane] = march.ray->direction[axis];
            }
            lanes.distanceWorld[lane] = march.baseHit.distanceWorld;
            lanes.b1[lane] = march.baseHit.b1;
            lanes.b2[lane] = march.baseHit.b2;
        }
        detail::enterFlatShell8(constants, lanes);
        for (std::size_t lane = 0; lane < eight.size(); ++lane) {
            ShellMarch& march = *eight[lane];
            SurfaceHit& hit = *march.hit;
            const glm::vec3 position(lanes.position[0][lane], lanes.position[1][lane],
                                     lanes.position[2][lane]);
            hit.entry = shared;
            hit.entry.position = position;
            hit.entry.uv = {lanes.uv[0][lane], lanes.uv[1][lane]};
            atEntry(march.baseHit, position, shared.normal, hit);
            hit.texelsPerWorldAlongRay = lanes.texelsPerWorldAlongRay[lane];
            march.directionTexels = {lanes.directionTexels[0][lane], lanes.directionTexels[1][lane],
                                     lanes.directionTexels[2][lane]};
            march.skippedTexels = lanes.skippedTexels[lane];
            march.startTexels = {lanes.startTexels[0][lane], lanes.startTexels[1][lane],
                                 lanes.startTexels[2][lane]};
            beginMarch(march, sides);
        }
    }
}

bool SceneTracer::traceFlatShell(std::uint32_t shell, std::span<const Ray* const> rays,
                                 std::span<SurfaceHit> hits, std::span<bool> found,
                                 std::span<TraceCounters> counters) const {
    if (shell >= shellCount()) return false;  // a side on an open border
    const ShellTriangle& triangle = triangles_[shell];
    if (triangle.curved || !triangle.hasDetail() || !entersFlatShell(shell) ||
        !isSphereTracing(options_.march.method) ||
        options_.normalFilter != FilterKind::TricubicBSpline)
        return false;
    for (const Ray* ray : rays)
        if (!triangle.frontFacing(ray->direction)) return false;
    // enterShell's test of the top (nothing nearer yet: no upper bound), then the entry.
    struct FlatMarches {
        ShellMarch marches[kMaxBatchRays];
    };
    ShellMarch* marches = threadScratch<FlatMarches>().marches;
    ShellMarch* entered[kMaxBatchRays];
    std::size_t rayOf[kMaxBatchRays];
    std::size_t count = 0;
    if (rays.empty()) return true;
    // What the test of the top takes from the origin alone, once when the rays share it (camera
    // rays from the eye).
    bool oneOrigin = true;
    for (const Ray* ray : rays) oneOrigin = oneOrigin && ray->origin == rays[0]->origin;
    const TriangleFromOrigin shared(rays[0]->origin, triangle.top);
    for (std::size_t r = 0; r < rays.size(); ++r) {
        found[r] = false;
        double distance = 0.0, b1 = 0.0, b2 = 0.0;
        constexpr double kFar = std::numeric_limits<float>::max();
        if (!(oneOrigin ? shared : TriangleFromOrigin(rays[r]->origin, triangle.top))
                 .intersect(rays[r]->direction, 0.0, kFar, distance, b1, b2))
            continue;
        // Front-facing, with detail (above): the march starts.
        startMarch(*rays[r], {shell, float(distance), b1, b2}, hits[r], marches[count]);
        rayOf[count] = r;
        entered[count] = &marches[count];
        ++count;
    }
    if (count == 0) return true;
    takeFlatEntries(std::span<ShellMarch* const>(entered, count));
    // takeMarches and takeGradients on the one tile: the marches interleaved, then the normals'
    // gradients of those that end on detail.
    const TileColumns& tile = *columns(triangle.object);
    takeMarchesOnTile(tile, std::span<ShellMarch* const>(entered, count));
    takeGradientsOnTile(tile, std::span<ShellMarch* const>(entered, count));
    for (std::size_t index = 0; index < count; ++index) {
        const std::size_t r = rayOf[index];
        found[r] = finishShell(*rays[r], marches[index], hits[r], counters[r]);
    }
    return true;
}

void SceneTracer::marchShells(std::span<ShellMarch* const> marches) const {
    takeEntries(marches);
    takeMarches(marches);
    takeGradients(marches);
}

void SceneTracer::takeGradients(std::span<ShellMarch* const> marches) const {
    if (options_.reference || options_.normalFilter != FilterKind::TricubicBSpline) return;
    const TileColumns* tiles[kMaxBatchRays];
    for (std::size_t index = 0; index < marches.size(); ++index)
        tiles[index] = columns(marches[index]->object);
    forEachTile(marches, std::span<const TileColumns* const>(tiles, marches.size()),
                takeGradientsOnTile);
}

void SceneTracer::takeGradientsOnTile(const TileColumns& tile,
                                      std::span<ShellMarch* const> marches) {
    // The marches that end on detail (finishShell takes a gradient there), sixteen at a time.
    ShellMarch* onDetail[kMaxBatchRays];
    std::size_t count = 0;
    for (ShellMarch* march : marches) {
        if (march->gradientKnown || march->result.exitedFloor || march->result.onFloor) continue;
        onDetail[count++] = march;
    }
    using Filter = BasicTricubicBSplineFilter<ColumnTexels>;
    constexpr std::size_t kGroup = Filter::kGroupedGradients;
    const Filter filter(tile);
    for (std::size_t first = 0; first < count; first += kGroup) {
        const std::size_t lanes = std::min(kGroup, count - first);
        glm::vec3 positions[kGroup], gradients[kGroup];
        for (std::size_t lane = 0; lane < kGroup; ++lane)  // padded with the first
            positions[lane] = onDetail[first + (lane < lanes ? lane : 0)]->result.texelPosition;
        filter.gradients(positions, int(lanes), gradients);
        for (std::size_t lane = 0; lane < lanes; ++lane) {
            onDetail[first + lane]->gradientTexels = gradients[lane];
            onDetail[first + lane]->gradientKnown = true;
        }
    }
}

void SceneTracer::takeMarches(std::span<ShellMarch* const> marches) const {
    takeCurvedMarches(marches);
    const bool interleave = !options_.reference && isSphereTracing(options_.march.method);
    if (!interleave) {
        for (ShellMarch* march : marches) {
            if (march->marched) continue;
            const Material& material = scene_.objects[march->object].material;
            march->result =
                withMarchFilter(options_.filter, material, columns(march->object),
                                options_.reference, [&](const auto& filter) {
                                    return distile::march(
                                        filter, march->startTexels, march->directionTexels,
                                        material.floor, march->settings, march->leaveTravelTexels);
                                });
            march->marched = true;
        }
        return;
    }
    ShellMarch* pending[kMaxBatchRays];
    const TileColumns* tiles[kMaxBatchRays];
    std::size_t count = 0;
    for (ShellMarch* march : marches) {
        if (march->marched) continue;
        pending[count] = march;
        tiles[count++] = columns(march->object);
    }
    forEachTile(std::span<ShellMarch* const>(pending, count),
                std::span<const TileColumns* const>(tiles, count),
                [&](const TileColumns& tile, std::span<ShellMarch* const> sameTile) {
                    takeMarchesOnTile(tile, sameTile);
                });
}

void SceneTracer::takeMarchesOnTile(const TileColumns& tile,
                                    std::span<ShellMarch* const> marches) const {
    detail::SphereTraceRay* traces[kMaxBatchRays];
    std::size_t count = 0;
    for (ShellMarch* march : marches)
        if (!march->marched) traces[count++] = &march->trace;
    withFilter(options_.filter, tile, [&](const auto& filter) {
        marchInterleaved(filter, std::span<detail::SphereTraceRay* const>(traces, count));
    });
    for (ShellMarch* march : marches) {
        if (march->marched) continue;
        march->result = march->trace.result();
        march->marched = true;
    }
}

void SceneTracer::takeCurvedMarches(std::span<ShellMarch* const> marches) const {
    CurvedMarchRay* traces[kMaxBatchRays];
    const TileColumns* tiles[kMaxBatchRays];
    ShellMarch* owners[kMaxBatchRays];
    std::size_t count = 0;
    for (ShellMarch* march : marches) {
        if (!march->curved || march->marched) continue;
        if (options_.reference) {  // one at a time, on the truth
            const Material& material = scene_.objects[march->object].material;
            const AnalyticFilter truth(material.analyticDistance);
            CurvedMarchRay& trace = *march->curvedTrace;
            while (trace.advance(truth.distanceTexels(trace.samplePosition()))) {
            }
            finishCurvedMarch(*march);
            continue;
        }
        owners[count] = march;
        traces[count] = march->curvedTrace;
        tiles[count++] = columns(march->object);
    }
    if (count == 0) return;
    marchInterleavedByTile(options_.filter, std::span<CurvedMarchRay* const>(traces, count),
                           std::span<const TileColumns* const>(tiles, count));
    for (std::size_t index = 0; index < count; ++index) finishCurvedMarch(*owners[index]);
}

bool SceneTracer::finishShell(const Ray& ray, const ShellMarch& march, SurfaceHit& hit,
                              TraceCounters& counters, bool withNormal) const {
    const Material& material = scene_.objects[march.object].material;
    // Read from the march's result, not back from the hit just written (a load of a fresh,
    // differently aligned store waits for it).
    const MarchResult& result = march.result;
    const float travelTexels = result.travelTexels + march.skippedTexels;
    hit.march = result;
    hit.march.travelTexels = travelTexels;
    ++counters.shellEntries;
    counters.marchIterations += std::uint64_t(result.iterations);
    if (result.exitedFloor) return false;
    hit.onDetail = true;
    const float distanceWorld =
        march.curved ? march.endDistanceWorld
                     : march.baseHit.distanceWorld + travelTexels / hit.texelsPerWorldAlongRay;
    hit.distanceWorld = distanceWorld;
    hit.position = ray.origin + ray.direction * distanceWorld;
    // The floor shades as the base surface does, smooth: with the vertex normals interpolated at
    // the hit (a curved shell's entry was moved there; a straight prism's normal is one).
    if (result.onFloor) hit.normal = hit.entry.normal;
    if (result.onFloor || !withNormal) return true;
    const glm::vec3 gradient =
        march.gradientKnown
            ? march.gradientTexels
            : withMarchFilter(options_.normalFilter, material, columns(march.object),
                              options_.reference, [&](const auto& normalFilter) {
                                  return normalFilter.gradient(result.texelPosition);
                              });
    if (glm::length(gradient) > 1e-6f)
        hit.normal = glm::normalize(hit.entry.gradientToWorld(gradient));
    return true;
}

void SceneTracer::buildShellMap() {
    bool anyCurved = false;
    for (const ShellTriangle& shell : triangles_) anyCurved |= shell.curved;
    if (!anyCurved) return;
    prisms_.resize(triangles_.size());
    neighbours_.assign(triangles_.size(), {ShellPrisms::kNoNeighbour, ShellPrisms::kNoNeighbour,
                                           ShellPrisms::kNoNeighbour});
    neighbourCorners_.assign(triangles_.size(), {0, 0, 0});
    std::uint32_t firstShell = 0;
    for (std::size_t objectIndex = 0; objectIndex < scene_.objects.size(); ++objectIndex) {
        const SceneObject& object = scene_.objects[objectIndex];
        const BaseMesh& mesh = object.mesh;
        const std::uint32_t shellCount = std::uint32_t(mesh.triangles.size());
        const Tile* tile = object.material.tile.get();
        bool objectCurved = false;
        for (std::uint32_t t = 0; t < shellCount; ++t)
            objectCurved |= triangles_[firstShell + t].curved;
        if (!objectCurved) {
            firstShell += shellCount;
            continue;
        }
        buildShellMeshInto(mesh, object.material.uvScale, tile->size(), object.material.depthWorld,
                           firstShell, std::span(prisms_).subspan(firstShell, shellCount),
                           std::span(neighbours_).subspan(firstShell, shellCount),
                           std::span(neighbourCorners_).subspan(firstShell, shellCount));
        // Per triangle in parallel: the least fold depth and the count of folded triangles are
        // exact whatever the order they are combined in.
        struct Folds {
            double leastWorld = std::numeric_limits<double>::infinity();
            std::size_t triangles = 0;
        };
        const Folds folds = tbb::parallel_reduce(
            tbb::blocked_range<std::uint32_t>(0, shellCount), Folds{},
            [&](const tbb::blocked_range<std::uint32_t>& range, Folds found) {
                for (std::uint32_t t = range.begin(); t != range.end(); ++t) {
                    const ShellPrism& prism = prisms_[firstShell + t];
                    if (prism.straight()) continue;
                    const double fold = prism.foldDepthWorld();
                    found.leastWorld = std::min(found.leastWorld, fold);
                    if (fold <= object.material.depthWorld) ++found.triangles;
                }
                return found;
            },
            [](const Folds& a, const Folds& b) {
                return Folds{std::min(a.leastWorld, b.leastWorld), a.triangles + b.triangles};
            });
        const double foldWorld = folds.leastWorld;
        const std::size_t foldedTriangles = folds.triangles;
        if (foldedTriangles > 0) {
            char text[320];
            std::snprintf(text, sizeof text,
                          "objects[%zu]: the curved shell folds on %zu triangles: its depth %.4g "
                          "is deeper than the base mesh's radius of curvature there; the largest "
                          "depth that does not fold is %.4g",
                          objectIndex, foldedTriangles, double(object.material.depthWorld),
                          foldWorld);
            warnings_.push_back(text);
        }
        firstShell += shellCount;
    }
}

void SceneTracer::takeCurvedEntry(ShellMarch& march, CurvedMarchRay& trace) const {
    const Ray& ray = *march.ray;
    SurfaceHit& hit = *march.hit;
    const TriangleHit& baseHit = march.baseHit;
    const ShellTriangle& shell = triangles_[baseHit.triangle];
    const SceneObject& object = scene_.objects[shell.object];
    const Material& material = object.material;
    baseSurfaceHit(ray, baseHit, hit);
    march.curved = true;
    march.startTexels = glm::vec3(0.0f);
    march.skippedTexels = 0.0f;
    MarchSettings settings = options_.march;
    if (!isSphereTracing(settings.method)) settings.method = MarchMethod::Budgeted;
    // A ray through a curved shell may bend along it for many texels (grazing rays at
    // silhouettes), and its path is not known at the entry: it gets kCurvedBudgetScale x the
    // budget.
    if (!options_.reference) settings.maxIterations *= kCurvedBudgetScale;
    march.curvedTrace = &trace;
    // Through a side: a hair further on, inside the prism, whose bilinear side the two
    // triangles of the entry face only approximate.
    const double entryWorld = double(baseHit.distanceWorld) +
                              (march.entryDepthWorld > 0.0f ? 1e-3 * material.depthWorld : 0.0);
    hit.entry.frontFacing = true;  // the top's front, or a side from outside
    trace.start(shellPrisms_, ray, baseHit.triangle, baseHit.b1, baseHit.b2, entryWorld,
                material.floor, settings);
    if (!trace.needsSample()) finishCurvedMarch(march);
}

void SceneTracer::finishCurvedMarch(ShellMarch& march) const {
    const CurvedMarchEnd& end = march.curvedTrace->end();
    const SceneObject& object = scene_.objects[march.object];
    SurfaceHit& hit = *march.hit;
    march.result = end.march;
    march.marched = true;
    march.endDistanceWorld = float(end.distanceWorld);
    if (end.leftShell) {
        // Rounded outward, so the crossing stays inside the interval in float.
        march.lastInsideWorld = std::nextafter(float(end.lastInsideWorld), 0.0f);
        march.firstOutsideWorld =
            std::nextafter(float(end.firstOutsideWorld), std::numeric_limits<float>::max());
        return;
    }
    // The hit's frame: the base point above it and the map's Jacobian there.
    const ShellPrism& prism = prisms_[end.prism];
    const ShellPrism::Jacobian jacobian = prism.jacobianAt(end.point);
    ShellEntry& entry = hit.entry;
    entry.curved = true;
    for (int axis = 0; axis < 3; ++axis) {
        glm::dvec3 unit(0.0);
        unit[axis] = 1.0;
        entry.texelFromWorld[axis] = glm::vec3(prism.texelDelta(jacobian.solve(unit)));
    }
    const PrismPoint top{end.point.b1, end.point.b2, 0.0};
    entry.position = glm::vec3(prism.worldAt(top));
    entry.normal = glm::vec3(glm::normalize(prism.normalAt(end.point.b1, end.point.b2)));
    const glm::uvec3 corners = object.mesh.triangles[triangles_[end.prism].localTriangle];
    entry.uv = glm::vec2(glm::dvec2(object.mesh.uvs[corners[0]]) * end.point.b0() +
                         glm::dvec2(object.mesh.uvs[corners[1]]) * end.point.b1 +
                         glm::dvec2(object.mesh.uvs[corners[2]]) * end.point.b2);
    hit.texelsPerWorldAlongRay = end.texelsPerWorldAlongRay;
    hit.shellPrism = end.prism;
    hit.shellPoint = end.point;
}

}  // namespace distile
