#include "render/world_reference.h"

#include <embree3/rtcore.h>
#include <tbb/blocked_range2d.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "common/error.h"
#include "common/image_blocks.h"
#include "common/shell_map.h"
#include "render/analytic_filter.h"
#include "render/coverage.h"
#include "render/shading.h"
#include "render/shell_march.h"
#include "sampler/filters.h"

namespace distile {

namespace {

constexpr float kPi = 3.14159265358979f;

double secondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

DetailDistanceFunction detailDistance(const Material& material) {
    if (material.analyticDistance) return material.analyticDistance;
    const std::shared_ptr<const Tile> tile = material.tile;
    return [tile](const glm::dvec3& texel) {
        return double(TrilinearFilter(*tile).distanceTexels(glm::vec3(texel)));
    };
}

/// A tiled object's base mesh and material as buildDisplacedMesh takes them (views of the
/// object's arrays).
DisplacementShell displacementShell(const SceneObject& object) {
    const Material& material = object.material;
    return {
        object.mesh.positions,         object.mesh.normals,          object.mesh.uvs,
        object.mesh.triangles,         glm::dvec2(material.uvScale), double(material.depthWorld),
        material.floor == Floor::Solid};
}

/// What a hit on one Embree geometry belongs to.
struct GeometryInfo {
    enum class Kind {
        Detail,     ///< a tiled object's world-space detail mesh
        Bare,       ///< the base mesh of an object without a tile
        TiledBase,  ///< the base mesh of a tiled object: only its back faces stop camera rays
    };
    Kind kind = Kind::Bare;
    std::uint32_t object = 0;
    const DisplacedMesh* detail = nullptr;  ///< Kind::Detail: the mesh
    bool quads = false;                     ///< Kind::Detail: its quads (else its triangles)
    const BaseMesh* base = nullptr;         ///< Kind::TiledBase: the base mesh
    /// Kind::TiledBase: per triangle, 1 where its uvs are degenerate (texelsPerWorldUv is 0): it
    /// carries no detail and is a bare surface, as the renderer shows it.
    const std::vector<std::uint8_t>* bareTriangles = nullptr;
    bool bare(unsigned triangle) const {
        return kind == Kind::Bare || (bareTriangles && (*bareTriangles)[triangle] != 0);
    }
};

/// What a query lets through (the Embree filter functions read it): the context of every
/// intersect and occluded call, Embree's own first.
struct QueryContext {
    enum class Mode {
        Camera,  ///< detail (but that of `object`), bare surfaces, back faces of tiled bases
        Shadow,  ///< detail and bare surfaces
        BaseOf,  ///< the base triangles of tiled object `object`, either side
    };
    static constexpr std::uint32_t kNoObject = ~0u;
    RTCIntersectContext embree;
    Mode mode = Mode::Camera;
    std::uint32_t object = kNoObject;
    glm::vec3 direction{0.0f};  ///< the ray's (Mode::Camera)

    QueryContext(Mode queryMode, const glm::vec3& rayDirection, std::uint32_t queryObject)
        : mode(queryMode), object(queryObject), direction(rayDirection) {
        rtcInitIntersectContext(&embree);
    }
};

glm::vec3 geometricNormal(const BaseMesh& mesh, const glm::uvec3& triangle) {
    return glm::cross(mesh.positions[triangle.y] - mesh.positions[triangle.x],
                      mesh.positions[triangle.z] - mesh.positions[triangle.x]);
}

/// An Embree device and scene of every object: the world-space detail meshes of tiled objects
/// and their base meshes (whose back faces stop camera rays, as in the renderer), the base meshes
/// of the others; and a second scene of the tiled base meshes alone (to look back along a ray
/// for the base triangle it came in through). Buffers are shared with the meshes, which must
/// outlive it.
class WorldBvh {
  public:
    WorldBvh() {
        device_ = rtcNewDevice("verbose=0");
        if (!device_) {
            throw std::runtime_error("embree: rtcNewDevice failed (error " +
                                     std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
        }
        rtcSetDeviceMemoryMonitorFunction(device_, &WorldBvh::monitor, &allocatedBytes_);
        for (RTCScene* scene : {&scene_, &bases_}) {
            *scene = rtcNewScene(device_);
            // Robust: shared edges are watertight (no ray slips between two triangles).
            rtcSetSceneFlags(*scene, RTC_SCENE_FLAG_ROBUST);
        }
        check("creating the scenes");
    }
    ~WorldBvh() {
        if (scene_) rtcReleaseScene(scene_);
        if (bases_) rtcReleaseScene(bases_);
        rtcReleaseDevice(device_);
    }
    WorldBvh(const WorldBvh&) = delete;
    WorldBvh& operator=(const WorldBvh&) = delete;

    /// Adds a detail mesh. Precondition: mesh.positions and mesh.texelPositions hold one more
    /// (unused) element than the mesh's vertices (Embree reads vertex buffers 16 bytes at a time).
    void addDetail(std::uint32_t object, const DisplacedMesh& mesh, std::size_t vertexCount) {
        GeometryInfo info{GeometryInfo::Kind::Detail, object, &mesh, false, nullptr};
        if (!mesh.triangles.empty()) {
            attach(scene_,
                   polygons(RTC_GEOMETRY_TYPE_TRIANGLE, mesh, vertexCount, mesh.triangles.data(),
                            RTC_FORMAT_UINT3, sizeof(glm::uvec3), mesh.triangles.size()),
                   info);
        }
        if (!mesh.quads.empty()) {
            info.quads = true;
            attach(scene_,
                   polygons(RTC_GEOMETRY_TYPE_QUAD, mesh, vertexCount, mesh.quads.data(),
                            RTC_FORMAT_UINT4, sizeof(glm::uvec4), mesh.quads.size()),
                   info);
        }
    }

    /// Adds a bare base mesh (its positions are copied).
    void addBare(std::uint32_t object, const BaseMesh& mesh) {
        attach(scene_, baseGeometry(mesh),
               {GeometryInfo::Kind::Bare, object, nullptr, false, nullptr});
    }

    /// Adds a tiled object's base mesh (its positions are copied), to both scenes.
    void addTiledBase(std::uint32_t object, const BaseMesh& mesh,
                      const std::vector<std::uint8_t>& bareTriangles) {
        const GeometryInfo info{
            GeometryInfo::Kind::TiledBase, object, nullptr, false, &mesh, &bareTriangles};
        attach(scene_, baseGeometry(mesh), info);
        attach(bases_, baseGeometry(mesh), info);
    }

    void commit() {
        rtcCommitScene(scene_);
        rtcCommitScene(bases_);
        check("building the BVH");
    }

    /// The nearest hit of the ray origin + t direction, t in (minDistance, inf), that `context`
    /// lets through; false for a miss.
    bool intersect(const glm::vec3& origin, const glm::vec3& direction, float minDistance,
                   QueryContext& context, RTCRayHit& rayHit) const {
        setRay(rayHit.ray, origin, direction, minDistance, std::numeric_limits<float>::infinity());
        rayHit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rayHit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(context.mode == QueryContext::Mode::BaseOf ? bases_ : scene_, &context.embree,
                      &rayHit);
        return rayHit.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }

    /// The nearest base triangle of tiled object `object` on the ray origin + t direction, t in
    /// (minDistance, maxDistance); false for none.
    bool intersectBase(std::uint32_t object, const glm::vec3& origin, const glm::vec3& direction,
                       float minDistance, float maxDistance, RTCRayHit& rayHit) const {
        QueryContext context(QueryContext::Mode::BaseOf, direction, object);
        setRay(rayHit.ray, origin, direction, minDistance, maxDistance);
        rayHit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rayHit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(bases_, &context.embree, &rayHit);
        return rayHit.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }

    /// Whether detail or a bare surface lies on the ray origin + t direction, t in (0, inf).
    bool occluded(const glm::vec3& origin, const glm::vec3& direction) const {
        RTCRay ray;
        setRay(ray, origin, direction, 0.0f, std::numeric_limits<float>::infinity());
        QueryContext context(QueryContext::Mode::Shadow, direction, QueryContext::kNoObject);
        rtcOccluded1(scene_, &context.embree, &ray);
        return ray.tfar < 0.0f;  // Embree marks an occluded ray with tfar = -inf
    }

    const GeometryInfo& info(unsigned geometryId) const { return *infos_[geometryId]; }
    RTCGeometry geometry(unsigned geometryId) const { return rtcGetGeometry(scene_, geometryId); }
    const GeometryInfo& baseInfo(unsigned geometryId) const { return *baseInfos_[geometryId]; }
    std::size_t allocatedBytes() const {
        return std::size_t(std::max<long long>(allocatedBytes_, 0));
    }

  private:
    RTCGeometry polygons(RTCGeometryType type, const DisplacedMesh& mesh, std::size_t vertexCount,
                         const void* indices, RTCFormat indexFormat, std::size_t indexStride,
                         std::size_t count) {
        RTCGeometry geometry = rtcNewGeometry(device_, type);
        rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                   mesh.positions.data(), 0, sizeof(glm::vec3), vertexCount);
        rtcSetGeometryVertexAttributeCount(geometry, 1);
        rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX_ATTRIBUTE, 0, RTC_FORMAT_FLOAT3,
                                   mesh.texelPositions.data(), 0, sizeof(glm::vec3), vertexCount);
        rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, indexFormat, indices, 0,
                                   indexStride, count);
        check("sharing a detail mesh's buffers");
        return geometry;
    }

    RTCGeometry baseGeometry(const BaseMesh& mesh) {
        RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
        auto* vertices = static_cast<float*>(
            rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                    3 * sizeof(float), mesh.positions.size()));
        auto* indices = static_cast<unsigned*>(
            rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                    3 * sizeof(unsigned), mesh.triangles.size()));
        check("allocating a base mesh's buffers");
        std::copy_n(&mesh.positions.front().x, 3 * mesh.positions.size(), vertices);
        std::copy_n(&mesh.triangles.front().x, 3 * mesh.triangles.size(), indices);
        return geometry;
    }

    void attach(RTCScene scene, RTCGeometry geometry, const GeometryInfo& info) {
        auto owned = std::make_unique<GeometryInfo>(info);
        rtcSetGeometryUserData(geometry, owned.get());
        if (info.kind != GeometryInfo::Kind::Bare) {
            rtcSetGeometryIntersectFilterFunction(geometry, &WorldBvh::filter);
            rtcSetGeometryOccludedFilterFunction(geometry, &WorldBvh::filter);
        }
        rtcCommitGeometry(geometry);
        const unsigned id = rtcAttachGeometry(scene, geometry);
        rtcReleaseGeometry(geometry);
        check("attaching a geometry");
        auto& infos = scene == scene_ ? infos_ : baseInfos_;
        if (infos.size() <= id) infos.resize(id + 1);
        infos[id] = std::move(owned);
    }

    /// Embree's filter of detail and tiled-base hits: what the query's context lets through.
    static void filter(const RTCFilterFunctionNArguments* arguments) {
        const auto& info = *static_cast<const GeometryInfo*>(arguments->geometryUserPtr);
        // QueryContext starts with Embree's context, which is what Embree hands back.
        const auto& context = *reinterpret_cast<const QueryContext*>(arguments->context);
        for (unsigned lane = 0; lane < arguments->N; ++lane) {
            if (arguments->valid[lane] != -1) continue;
            bool accepted = false;
            switch (context.mode) {
                case QueryContext::Mode::Shadow:
                    accepted = info.kind == GeometryInfo::Kind::Detail ||
                               info.bare(RTCHitN_primID(arguments->hit, arguments->N, lane));
                    break;
                case QueryContext::Mode::BaseOf:
                    accepted = info.object == context.object;
                    break;
                case QueryContext::Mode::Camera:
                    if (info.kind == GeometryInfo::Kind::Detail) {
                        accepted = info.object != context.object;
                    } else {  // a tiled base triangle: its back face, or a bare one
                        const unsigned primitive =
                            RTCHitN_primID(arguments->hit, arguments->N, lane);
                        const glm::uvec3& triangle = info.base->triangles[primitive];
                        accepted =
                            info.bare(primitive) || glm::dot(geometricNormal(*info.base, triangle),
                                                             context.direction) > 0.0f;
                    }
                    break;
            }
            if (!accepted) arguments->valid[lane] = 0;
        }
    }

    static void setRay(RTCRay& ray, const glm::vec3& origin, const glm::vec3& direction, float near,
                       float far) {
        ray.org_x = origin.x;
        ray.org_y = origin.y;
        ray.org_z = origin.z;
        ray.dir_x = direction.x;
        ray.dir_y = direction.y;
        ray.dir_z = direction.z;
        ray.tnear = near;
        ray.tfar = far;
        ray.time = 0.0f;
        ray.mask = ~0u;
        ray.id = 0;
        ray.flags = 0;
    }

    void check(const char* what) const {
        const RTCError error = rtcGetDeviceError(device_);
        if (error != RTC_ERROR_NONE) {
            throw std::runtime_error(std::string("embree: ") + what + " failed (error " +
                                     std::to_string(int(error)) + ")");
        }
    }

    static bool monitor(void* userPointer, ssize_t bytes, bool) {
        *static_cast<std::atomic<long long>*>(userPointer) += bytes;
        return true;
    }

    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    RTCScene bases_ = nullptr;
    std::vector<std::unique_ptr<GeometryInfo>> infos_;      ///< by Embree geometry id in scene_
    std::vector<std::unique_ptr<GeometryInfo>> baseInfos_;  ///< the same in bases_
    std::atomic<long long> allocatedBytes_{0};
};

/// A tiled object's shell maps and exact detail, for refining hits on its world-space mesh.
class ObjectShell {
  public:
    /// Precondition: the object has a tile.
    explicit ObjectShell(const SceneObject& object)
        : analytic_(object.material.analyticDistance),
          tile_(object.material.tile.get()),
          depthTexels_(object.material.tile->size().depth),
          solidFloor_(object.material.floor == Floor::Solid),
          shell_(buildShellMesh(object.mesh, object.material.uvScale, tile_->size(),
                                object.material.depthWorld)) {}

    const ShellPrism& prism(std::uint32_t triangle) const { return shell_.prisms[triangle]; }

    /// The clipped detail (the surface the world mesh approximates) at a texel position, texels.
    double distanceTexels(const glm::dvec3& texel) const {
        return clippedDetailTexels(detailTexels(texel), texel.z, depthTexels_, solidFloor_);
    }

    /// The gradient of distanceTexels in texel space: central differences of the analytic
    /// distance (AnalyticFilter's step), else the tile's trilinear gradient, or the floor's or
    /// top's where the clipping decides.
    glm::dvec3 gradientTexels(const glm::dvec3& texel) const {
        if (analytic_) {
            const double h = AnalyticFilter::kGradientStepTexels;
            const auto difference = [&](const glm::dvec3& step) {
                return (distanceTexels(texel + step) - distanceTexels(texel - step)) / (2.0 * h);
            };
            return {difference({h, 0.0, 0.0}), difference({0.0, h, 0.0}),
                    difference({0.0, 0.0, h})};
        }
        const double detail = detailTexels(texel);
        const double clipped = clippedDetailTexels(detail, texel.z, depthTexels_, solidFloor_);
        if (clipped == detail)
            return glm::dvec3(TrilinearFilter(*tile_).gradient(glm::vec3(texel)));
        // The floor's slab bottom faces down; the floor, the open floor's cut and the top face up.
        return {0.0, 0.0, clipped == -(texel.z + kFloorSlabTexels) ? -1.0 : 1.0};
    }

    /// The prism point of world position `world`, starting from `triangle` and `point` (a guess)
    /// and moving to the neighbouring triangle while the point lies outside the current one
    /// (render/shell_march.h detail::locate; above the top counts: the clipped detail is defined
    /// there). False when the map cannot be inverted there or the point lies beyond an open
    /// border.
    bool locate(const glm::dvec3& world, std::uint32_t& triangle, PrismPoint& point) const {
        detail::CurvedCursor cursor;
        cursor.prism = triangle;
        cursor.point = point;
        cursor.originOffset = world - shell_.prisms[triangle].corner0;
        const detail::Located where =
            detail::locate(shell_.view(), world, glm::dvec3(0.0), 0.0, cursor);
        triangle = cursor.prism;
        point = cursor.point;
        return where == detail::Located::Inside || where == detail::Located::AboveTop;
    }

    /// Whether the clipped detail at `texel` is the solid floor's top (z = 0) rather than the
    /// detail.
    bool onSolidFloor(const glm::dvec3& texel) const {
        if (!solidFloor_) return false;
        const double detail = detailTexels(texel);
        const double clipped = clippedDetailTexels(detail, texel.z, depthTexels_, solidFloor_);
        return clipped != detail && clipped == texel.z;
    }

  private:
    double detailTexels(const glm::dvec3& texel) const {
        return analytic_ ? analytic_(texel)
                         : double(TrilinearFilter(*tile_).distanceTexels(glm::vec3(texel)));
    }

    DetailDistanceFunction analytic_;
    const Tile* tile_;
    double depthTexels_;
    bool solidFloor_;
    ShellMesh shell_;  ///< by base triangle
};

/// A hit on the exact detail surface, refined from a hit on its world mesh (refineHit).
struct ExactHit {
    double distanceWorld = 0.0;
    std::uint32_t triangle = 0;  ///< the base triangle whose prism holds it
    PrismPoint point;
    glm::dvec3 texel{0.0};
    glm::dvec3 normal{0.0};  ///< unit world normal of the detail, not yet facing the ray
};

/// Moves a hit on an object's world mesh (or level set) at `meshDistanceWorld` along the unit
/// ray onto the exact detail surface: the first zero of the detail's texel distance d(t) of the
/// ray's point mapped into the shell within 1.5 texels (along the ray) of the mesh hit, which is
/// a fraction of a texel off. From the start of that bracket: sphere-tracing steps (t += d /
/// |dtexel/dt|), stretched toward the secant's root once close, until d changes sign or
/// |d| < 1e-4 texel; then regula falsi (Illinois) on the sign change. Starting ahead of the hit
/// and marching forward, the hits of two traced surfaces a little apart (the mesh and its level
/// set) end on the same zero. `triangle` and `point` locate the mesh hit (a guess). False, with
/// `exact` undefined, when the bracket's start lies in the detail, no zero is found in the
/// bracket within 96 steps, or the ray leaves the shell's chart (an open border).
bool refineHit(const ObjectShell& shell, const glm::dvec3& origin, const glm::dvec3& direction,
               double meshDistanceWorld, std::uint32_t triangle, PrismPoint point,
               ExactHit& exact) {
    constexpr double kConvergedTexels = 1e-4;
    constexpr double kBracketTexels = 1.5;
    /// Below this distance (texels) a step may go up to kMaxStretch sphere steps, toward the
    /// secant's root: sphere steps alone crawl where the ray meets the surface at a low angle.
    constexpr double kNearTexels = 0.05;
    constexpr double kMaxStretch = 4.0;
    constexpr int kMaxSteps = 96;
    struct Sample {
        double distanceWorld = 0.0, distanceTexels = 0.0, texelsPerWorld = 0.0;
    };
    const auto evaluate = [&](double distanceWorld, Sample& sample) {
        if (!shell.locate(origin + distanceWorld * direction, triangle, point)) return false;
        const ShellPrism& prism = shell.prism(triangle);
        const ShellPrism::Jacobian jacobian = prism.jacobianAt(point);
        sample = {distanceWorld, shell.distanceTexels(prism.texelAt(point)),
                  glm::length(prism.texelDelta(jacobian.solve(direction)))};
        return std::isfinite(sample.distanceTexels) && sample.texelsPerWorld > 0.0 &&
               std::isfinite(sample.texelsPerWorld);
    };
    Sample current;
    if (!evaluate(meshDistanceWorld, current)) return false;
    const double reachWorld = kBracketTexels / current.texelsPerWorld;
    const double low = meshDistanceWorld - reachWorld, high = meshDistanceWorld + reachWorld;
    if (!evaluate(std::max(low, 0.0), current) || !(current.distanceTexels > 0.0)) return false;
    Sample outside = current, inside, previous;
    bool bracketed = false, hasPrevious = false;
    int lastSide = 0;  ///< +1: the last step moved the outside end, -1: the inside end
    for (int step = 0;; ++step) {
        if (std::abs(current.distanceTexels) < kConvergedTexels) break;
        if (step == kMaxSteps) return false;
        double next = 0.0;
        if (bracketed) {
            next = outside.distanceWorld - outside.distanceTexels *
                                               (inside.distanceWorld - outside.distanceWorld) /
                                               (inside.distanceTexels - outside.distanceTexels);
        } else {
            const double sphereStep = current.distanceTexels / current.texelsPerWorld;
            next = current.distanceWorld + sphereStep;
            if (hasPrevious && current.distanceTexels < kNearTexels &&
                current.distanceTexels < previous.distanceTexels) {
                const double secant =
                    current.distanceWorld - current.distanceTexels *
                                                (current.distanceWorld - previous.distanceWorld) /
                                                (current.distanceTexels - previous.distanceTexels);
                next = std::clamp(secant, next, current.distanceWorld + kMaxStretch * sphereStep);
            }
            if (!(next <= high)) return false;
        }
        previous = current;
        hasPrevious = true;
        if (!evaluate(next, current)) return false;
        // Illinois: an end kept twice in a row counts half, so the false position moves on.
        if (current.distanceTexels > 0.0) {
            if (bracketed && lastSide == 1) inside.distanceTexels *= 0.5;
            outside = current;
            lastSide = 1;
        } else {
            if (bracketed && lastSide == -1) outside.distanceTexels *= 0.5;
            inside = current;
            lastSide = -1;
            bracketed = true;
        }
    }
    const ShellPrism& prism = shell.prism(triangle);
    exact.distanceWorld = current.distanceWorld;
    exact.triangle = triangle;
    exact.point = point;
    exact.texel = prism.texelAt(point);
    // n ~ J^-T (d texel / d prism)^T grad d: the gradient of d in world space; on the solid
    // floor, the vertex normals interpolated at the hit, as the renderer shades the floor (its
    // facets are flat: the smooth base surface they stand for is not).
    const glm::dvec3 normal =
        shell.onSolidFloor(exact.texel)
            ? prism.normalAt(point.b1, point.b2)
            : prism.jacobianAt(point).solveTransposed(
                  prism.texelGradientToPrism(shell.gradientTexels(exact.texel)));
    const double length = glm::length(normal);
    if (!(length > 0.0) || !std::isfinite(length)) return false;
    exact.normal = normal / length;
    return true;
}

/// A camera ray's hit, with what shading needs.
struct WorldHit {
    std::uint32_t object = 0;
    float distanceWorld = 0.0f;
    glm::vec3 position{0.0f};
    glm::vec3 normal{0.0f};      ///< unit, facing the ray (the base mesh's shading normal if bare)
    glm::vec3 baseNormal{0.0f};  ///< unit interpolated vertex normal of the base mesh there
    glm::vec2 uv{0.0f};          ///< base-mesh uv
    float texelZ = 0.0f;         ///< texel height in the shell (detail only)
    bool onDetail = false;
    bool frontFacing = true;  ///< false: a base triangle met from behind (its back face)
    /// Detail hits: the base triangle whose prism holds the hit and the hit's point in it (the
    /// mesh's interpolation until refined).
    std::uint32_t baseTriangle = 0;
    PrismPoint prismPoint;
    bool refined = false;  ///< on the exact detail surface (refineHit), else on its mesh
    /// Where shadow rays start from, off the traced surface (the world mesh or the level set)
    /// along its normal: the exact surface may lie a fraction of a texel inside that mesh.
    glm::vec3 shadowFrom{0.0f};
    glm::vec3 shadowNormal{0.0f};
    /// A ray that met an object's detail from below its shell (the underside of a solid floor)
    /// ignores that object's detail from there on, as the renderer, which enters shells only
    /// through their tops, never sees it: the object, or QueryContext::kNoObject.
    std::uint32_t ignoredDetailOf = QueryContext::kNoObject;
    float ignoredDetailFromWorld = 0.0f;
};

/// Barycentric weights of `uv` in a base triangle's uv corners (linear, also outside it).
glm::dvec3 uvBarycentrics(const BaseMesh& mesh, const glm::uvec3& triangle, const glm::dvec2& uv) {
    const glm::dvec2 c0(mesh.uvs[triangle.x]), c1(mesh.uvs[triangle.y]), c2(mesh.uvs[triangle.z]);
    const auto cross2 = [](const glm::dvec2& a, const glm::dvec2& b) {
        return a.x * b.y - a.y * b.x;
    };
    const double area = cross2(c1 - c0, c2 - c0);
    if (area == 0.0) return glm::dvec3(1.0 / 3.0);
    const double b1 = cross2(uv - c0, c2 - c0) / area;
    const double b2 = cross2(c1 - c0, uv - c0) / area;
    return {1.0 - b1 - b2, b1, b2};
}

/// The unit normal interpolated from a base triangle's vertex normals.
glm::vec3 interpolatedNormal(const BaseMesh& mesh, const glm::uvec3& triangle,
                             const glm::vec3& weights) {
    const glm::vec3 normal = weights.x * mesh.normals[triangle.x] +
                             weights.y * mesh.normals[triangle.y] +
                             weights.z * mesh.normals[triangle.z];
    const float length = glm::length(normal);
    return length > 0.0f ? normal / length : mesh.normals[triangle.x];
}

/// `count` points on the unit disk, a Vogel spiral (even cover, no two at the same radius).
std::vector<glm::vec2> diskSamples(int count) {
    constexpr float kGoldenAngle = 2.39996323f;
    std::vector<glm::vec2> samples;
    for (int index = 0; index < count; ++index) {
        const float radius = std::sqrt((float(index) + 0.5f) / float(count));
        const float angle = float(index) * kGoldenAngle;
        samples.emplace_back(radius * std::cos(angle), radius * std::sin(angle));
    }
    return samples;
}

/// A per-pixel angle in [0, 2 pi) that turns the disk samples, so penumbrae show noise rather
/// than the sample pattern's bands; fixed per pixel, so renders are repeatable.
float pixelRotation(int x, int y) {
    std::uint32_t hash = std::uint32_t(x) * 0x9e3779b1U ^ std::uint32_t(y) * 0x85ebca77U;
    hash ^= hash >> 16;
    hash *= 0x7feb352dU;
    hash ^= hash >> 15;
    return float(hash) * (2.0f * kPi / 4294967296.0f);
}

class WorldShader {
  public:
    WorldShader(const Scene& scene, const WorldBvh& bvh, const std::vector<DisplacedMesh>& meshes,
                int shadowSamples)
        : scene_(scene), bvh_(bvh), meshes_(meshes), disk_(diskSamples(shadowSamples)) {
        shells_.resize(scene.objects.size());
        for (std::size_t index = 0; index < scene.objects.size(); ++index) {
            if (scene.objects[index].material.tile)
                shells_[index] = std::make_unique<const ObjectShell>(scene.objects[index]);
        }
        for (const DirectionalLight& light : scene.lights) {
            const glm::vec3 toLight = -unitDirection(light.direction);
            toLights_.push_back(toLight);
            // As the renderer: the light's angular radius, at least 1e-3 radians.
            tanHalfAngles_.push_back(
                std::max(std::tan(0.5f * light.angleDeg * kPi / 180.0f), 1e-3f));
            const glm::vec3 axis = std::abs(toLight.x) < 0.9f ? glm::vec3(1.0f, 0.0f, 0.0f)
                                                              : glm::vec3(0.0f, 1.0f, 0.0f);
            const glm::vec3 tangent = glm::normalize(glm::cross(toLight, axis));
            lightFrames_.push_back({tangent, glm::cross(toLight, tangent)});
        }
        glm::vec3 low(std::numeric_limits<float>::max()), high(-low);
        for (const SceneObject& object : scene.objects) {
            for (const glm::vec3& p : object.mesh.positions) {
                low = glm::min(low, p);
                high = glm::max(high, p);
            }
        }
        sceneOffsetWorld_ = 1e-5f * glm::length(high - low);
    }

    /// The nearest hit along the ray as the renderer sees it, from the BVH: detail, a bare
    /// surface, or a tiled base triangle from behind (unless the ray is leaving a shell through
    /// its top; see wayOut). Detail hits are not refined yet (refine).
    bool trace(const Ray& ray, WorldHit& hit, std::uint64_t& backFaceStops) const {
        // Each pass goes past one hit that does not count; a few are plenty.
        constexpr int kMaxPasses = 16;
        QueryContext context(QueryContext::Mode::Camera, ray.direction, QueryContext::kNoObject);
        float from = 0.0f;
        float ignoredFromWorld = 0.0f;
        for (int pass = 0; pass < kMaxPasses; ++pass) {
            RTCRayHit rayHit;
            if (!bvh_.intersect(ray.origin, ray.direction, from, context, rayHit)) return false;
            const GeometryInfo& info = bvh_.info(rayHit.hit.geomID);
            const SceneObject& object = scene_.objects[info.object];
            const float distance = rayHit.ray.tfar;
            const float u = rayHit.hit.u, v = rayHit.hit.v;
            if (info.kind != GeometryInfo::Kind::Detail) {
                const glm::uvec3& triangle = object.mesh.triangles[rayHit.hit.primID];
                // A tiled base triangle seen from the front is a bare one (the filter lets no
                // other through); from behind it stops the ray as the renderer's back faces do.
                const bool backFace =
                    info.kind == GeometryInfo::Kind::TiledBase &&
                    glm::dot(geometricNormal(object.mesh, triangle), ray.direction) >= 0.0f;
                if (backFace && info.object != context.object &&
                    wayOut(ray, info.object, rayHit.hit.primID, distance)) {
                    from = std::nextafter(distance, std::numeric_limits<float>::infinity());
                    continue;
                }
                hit = WorldHit{};
                hit.object = info.object;
                hit.distanceWorld = distance;
                hit.position = ray.origin + ray.direction * distance;
                const glm::vec3 weights(1.0f - u - v, u, v);
                hit.uv = weights.x * object.mesh.uvs[triangle.x] +
                         weights.y * object.mesh.uvs[triangle.y] +
                         weights.z * object.mesh.uvs[triangle.z];
                hit.baseNormal = interpolatedNormal(object.mesh, triangle, weights);
                hit.normal = hit.baseNormal;  // the renderer shades bare surfaces so
                hit.frontFacing =
                    glm::dot(geometricNormal(object.mesh, triangle), ray.direction) < 0.0f;
                hit.shadowFrom = hit.position;
                hit.shadowNormal = hit.frontFacing ? hit.baseNormal : -hit.baseNormal;
                if (backFace) {
                    ++backFaceStops;
                    if (context.object != QueryContext::kNoObject) {
                        hit.ignoredDetailOf = context.object;
                        hit.ignoredDetailFromWorld = ignoredFromWorld;
                    }
                }
                return true;
            }
            float texel[3];
            rtcInterpolate0(bvh_.geometry(rayHit.hit.geomID), rayHit.hit.primID, u, v,
                            RTC_BUFFER_TYPE_VERTEX_ATTRIBUTE, 0, texel, 3);
            const Material& material = object.material;
            if (material.floor == Floor::Solid && texel[2] < -0.5 * kFloorSlabTexels) {
                // The solid floor's slab from below: the ray came from inside the object.
                if (context.object == QueryContext::kNoObject) ignoredFromWorld = distance;
                context.object = info.object;
                from = std::nextafter(distance, std::numeric_limits<float>::infinity());
                continue;
            }
            hit = WorldHit{};
            hit.object = info.object;
            hit.distanceWorld = distance;
            hit.position = ray.origin + ray.direction * distance;
            glm::vec3 normal =
                glm::normalize(glm::vec3(rayHit.hit.Ng_x, rayHit.hit.Ng_y, rayHit.hit.Ng_z));
            if (glm::dot(normal, ray.direction) > 0.0f) normal = -normal;
            hit.normal = normal;
            hit.onDetail = true;
            const Size3 tile = material.tile->size();
            hit.uv = glm::vec2(texel[0] / (material.uvScale.x * float(tile.width)),
                               texel[1] / (material.uvScale.y * float(tile.height)));
            hit.texelZ = texel[2];
            hit.baseTriangle = info.quads ? info.detail->quadBase[rayHit.hit.primID]
                                          : info.detail->triangleBase[rayHit.hit.primID];
            const glm::uvec3& triangle = object.mesh.triangles[hit.baseTriangle];
            const glm::dvec3 weights = uvBarycentrics(object.mesh, triangle, glm::dvec2(hit.uv));
            hit.baseNormal = interpolatedNormal(object.mesh, triangle, glm::vec3(weights));
            hit.prismPoint = {
                weights.y, weights.z,
                double(material.depthWorld) * (1.0 - double(texel[2]) / double(tile.depth))};
            hit.shadowFrom = hit.position;
            hit.shadowNormal = hit.normal;
            return true;
        }
        return false;
    }

    /// Whether a ray that meets tiled object `object`'s base triangle from behind at
    /// `distanceWorld` is leaving the object's shell through its top, having come in through a
    /// front face nearer without meeting the detail (the renderer's curved march goes on there):
    /// the nearest of the object's base triangles back along the ray faces it. A ray that left
    /// the shell through an open floor and came back up from inside is not told apart.
    bool wayOut(const Ray& ray, std::uint32_t object, std::uint32_t triangle,
                float distanceWorld) const {
        const glm::vec3 at = ray.origin + ray.direction * distanceWorld;
        // Past the base triangle the ray leaves by (a thousandth of a texel; at a low angle the
        // rounding of `at` can put it farther, so that triangle is passed over too).
        float fromWorld = 1e-3f * float(meshes_[object].stats.texelSizeWorld);
        const BaseMesh& mesh = scene_.objects[object].mesh;
        RTCRayHit rayHit;
        for (int pass = 0; pass < 4; ++pass) {
            if (!bvh_.intersectBase(object, at, -ray.direction, fromWorld, distanceWorld, rayHit))
                return false;
            if (rayHit.hit.primID != triangle) {
                return glm::dot(geometricNormal(mesh, mesh.triangles[rayHit.hit.primID]),
                                ray.direction) < 0.0f;
            }
            fromWorld = std::nextafter(rayHit.ray.tfar, std::numeric_limits<float>::infinity());
        }
        return false;
    }

    /// Moves a detail hit onto the exact detail surface (refineHit), from its distance along
    /// the ray, base triangle and prism point; its position, normal, uv, texel height and base
    /// normal follow. False (the hit unchanged) when the refinement fails.
    bool refine(const Ray& ray, WorldHit& hit) const {
        const SceneObject& object = scene_.objects[hit.object];
        ExactHit exact;
        if (!refineHit(*shells_[hit.object], glm::dvec3(ray.origin), glm::dvec3(ray.direction),
                       double(hit.distanceWorld), hit.baseTriangle, hit.prismPoint, exact)) {
            return false;
        }
        hit.refined = true;
        hit.distanceWorld = float(exact.distanceWorld);
        hit.position =
            glm::vec3(glm::dvec3(ray.origin) + exact.distanceWorld * glm::dvec3(ray.direction));
        glm::vec3 normal(exact.normal);
        if (glm::dot(normal, ray.direction) > 0.0f) normal = -normal;
        hit.normal = normal;
        hit.baseTriangle = exact.triangle;
        hit.prismPoint = exact.point;
        hit.texelZ = float(exact.texel.z);
        const glm::uvec3& triangle = object.mesh.triangles[exact.triangle];
        const glm::vec3 weights(float(exact.point.b0()), float(exact.point.b1),
                                float(exact.point.b2));
        hit.uv = weights.x * object.mesh.uvs[triangle.x] + weights.y * object.mesh.uvs[triangle.y] +
                 weights.z * object.mesh.uvs[triangle.z];
        hit.baseNormal = interpolatedNormal(object.mesh, triangle, weights);
        return true;
    }

    /// The hit's colour, as the renderer shades its hits (render/renderer.cpp), with shadows
    /// from disk samples of each light traced through the BVH.
    glm::vec3 shade(const Ray& ray, const WorldHit& hit, float rotation) const {
        const Material& material = scene_.objects[hit.object].material;
        if (!hit.frontFacing) return backFaceColor(material.color);
        const glm::vec3 albedo = albedoAt(material, hit.uv);
        glm::vec3 color = albedo * kAmbientStrength;
        float offsetWorld = sceneOffsetWorld_;
        if (hit.onDetail) {
            color = albedo *
                    (kAmbientStrength * openness(hit.texelZ, float(material.tile->size().depth)));
            offsetWorld =
                std::max(offsetWorld, 0.02f * float(meshes_[hit.object].stats.texelSizeWorld));
        }
        const glm::vec3 origin = hit.shadowFrom + hit.shadowNormal * offsetWorld;
        const float cosRotation = std::cos(rotation), sinRotation = std::sin(rotation);
        for (std::size_t index = 0; index < scene_.lights.size(); ++index) {
            const glm::vec3& toLight = toLights_[index];
            // The base surface facing away from the light is in its own shadow; detail facing
            // away from it gets no direct light.
            if (glm::dot(hit.baseNormal, toLight) <= 0.0f) continue;
            if (hit.onDetail && glm::dot(hit.normal, toLight) <= 0.0f) continue;
            const auto& [tangent, bitangent] = lightFrames_[index];
            int unblocked = 0;
            for (const glm::vec2& sample : disk_) {
                const glm::vec2 turned(cosRotation * sample.x - sinRotation * sample.y,
                                       sinRotation * sample.x + cosRotation * sample.y);
                const glm::vec3 direction = glm::normalize(
                    toLight + tanHalfAngles_[index] * (turned.x * tangent + turned.y * bitangent));
                if (!bvh_.occluded(origin, direction)) ++unblocked;
            }
            if (unblocked == 0) continue;
            const float visibility = float(unblocked) / float(disk_.size());
            color += directLight(hit.normal, toLight, ray.direction, albedo) *
                     scene_.lights[index].color * visibility;
        }
        return color;
    }

  private:
    struct LightFrame {
        glm::vec3 tangent, bitangent;
    };
    const Scene& scene_;
    const WorldBvh& bvh_;
    const std::vector<DisplacedMesh>& meshes_;  ///< by object (empty for bare objects)
    std::vector<std::unique_ptr<const ObjectShell>> shells_;  ///< by object (null if bare)
    std::vector<glm::vec2> disk_;
    std::vector<glm::vec3> toLights_;
    std::vector<float> tanHalfAngles_;
    std::vector<LightFrame> lightFrames_;
    float sceneOffsetWorld_ = 0.0f;  ///< shadow rays start this far off a bare surface
};

void validateOptions(const WorldReferenceOptions& options) {
    if (options.width < 1 || options.width > 16384 || options.height < 1 ||
        options.height > 16384) {
        throw InputError("world reference: image size " + std::to_string(options.width) + "x" +
                         std::to_string(options.height) +
                         " is not accepted; each side must be in [1, 16384] pixels");
    }
    if (std::int64_t(options.width) * options.height > kMaxRenderSamples) {
        throw InputError("world reference: image size " + std::to_string(options.width) + "x" +
                         std::to_string(options.height) +
                         " is not accepted; width x height must be at most 2^24 pixels");
    }
    if (options.shadowSamples < 1 || options.shadowSamples > 256) {
        throw InputError("world reference: shadow samples " +
                         std::to_string(options.shadowSamples) +
                         " is not accepted; it must be in [1, 256]");
    }
}

}  // namespace

WorldReferenceResult renderWorldReference(const Scene& scene, const WorldReferenceOptions& options,
                                          const ProgressCallback& progress) {
    validateScene(scene);
    validateOptions(options);
    WorldReferenceResult result;
    // Progress: the meshes (and their level sets, half of it) are the first half of kBuildShare,
    // the BVH the second, then the rows.
    constexpr double kBuildShare = 0.6;
    const double meshShare =
        kBuildShare * (options.method == WorldReferenceMethod::LevelSet ? 0.25 : 0.5);

    // 1. The world-space detail meshes (and, for the level-set method, their level sets).
    auto start = std::chrono::steady_clock::now();
    std::vector<DisplacedMesh> meshes(scene.objects.size());
    std::vector<std::size_t> vertexCounts(scene.objects.size(), 0);
    std::vector<std::optional<DisplacedLevelSet>> levelSets(scene.objects.size());
    // The meshes and the BVH over them share the mesh options' memory budget: every object's
    // estimate is checked before the first mesh is mapped.
    DisplacedMeshOptions meshOptions = options.levelSet.mesh;
    meshOptions.estimateOnly = true;
    double earlierBytes = 0.0;
    for (std::size_t index = 0; index < scene.objects.size(); ++index) {
        const SceneObject& object = scene.objects[index];
        if (!object.material.tile) continue;
        try {
            meshOptions.memoryBudgetBytes = options.levelSet.mesh.memoryBudgetBytes - earlierBytes;
            earlierBytes +=
                buildDisplacedMesh(detailDistance(object.material), object.material.tile->size(),
                                   displacementShell(object), meshOptions)
                    .stats.estimatedBytes;
        } catch (const InputError& error) {
            char earlier[120] = "";
            if (earlierBytes > 0.0) {
                std::snprintf(earlier, sizeof earlier,
                              " (of %.1f GB for all objects, the objects before it take %.1f GB)",
                              options.levelSet.mesh.memoryBudgetBytes / 1e9, earlierBytes / 1e9);
            }
            throw InputError("objects[" + std::to_string(index) + "]: " + error.what() + earlier);
        }
    }
    for (std::size_t index = 0; index < scene.objects.size(); ++index) {
        const SceneObject& object = scene.objects[index];
        const Material& material = object.material;
        if (!material.tile) continue;
        try {
            meshes[index] = buildDisplacedMesh(detailDistance(material), material.tile->size(),
                                               displacementShell(object), options.levelSet.mesh);
            result.meshes.push_back(meshes[index].stats);
            // Every level set's budget is checked before the first takes its minutes.
            if (options.method == WorldReferenceMethod::LevelSet)
                DisplacedLevelSet::voxelsPerTexel(meshes[index], options.levelSet);
        } catch (const InputError& error) {
            throw InputError("objects[" + std::to_string(index) + "]: " + error.what());
        }
        if (progress) progress(meshShare * double(index + 1) / scene.objects.size());
    }
    result.meshSeconds = secondsSince(start);
    for (std::size_t index = 0; index < scene.objects.size(); ++index) {
        if (!scene.objects[index].material.tile) continue;
        if (options.method == WorldReferenceMethod::LevelSet) {
            const auto levelSetStart = std::chrono::steady_clock::now();
            try {
                levelSets[index] = DisplacedLevelSet::build(meshes[index], options.levelSet);
            } catch (const InputError& error) {
                throw InputError("objects[" + std::to_string(index) + "]: " + error.what());
            }
            result.levelSets.push_back(levelSets[index]->stats());
            result.levelSetSeconds += secondsSince(levelSetStart);
            if (progress) {
                progress(meshShare + (kBuildShare * 0.5 - meshShare) * double(index + 1) /
                                         scene.objects.size());
            }
        }
        // Embree reads vertex buffers 16 bytes at a time: one unused element past the end.
        vertexCounts[index] = meshes[index].positions.size();
        meshes[index].positions.emplace_back(0.0f);
        meshes[index].texelPositions.emplace_back(0.0f);
    }

    // 2. One BVH of every object.
    start = std::chrono::steady_clock::now();
    WorldBvh bvh;
    std::vector<std::vector<std::uint8_t>> bareTriangles(scene.objects.size());
    for (std::size_t index = 0; index < scene.objects.size(); ++index) {
        const SceneObject& object = scene.objects[index];
        if (object.material.tile) {
            for (const glm::uvec3& triangle : object.mesh.triangles) {
                bareTriangles[index].push_back(texelsPerWorldUv(object.mesh, triangle,
                                                                object.material.uvScale,
                                                                object.material.tile->size())
                                                   .x == 0.0f);
            }
            bvh.addDetail(std::uint32_t(index), meshes[index], vertexCounts[index]);
            bvh.addTiledBase(std::uint32_t(index), object.mesh, bareTriangles[index]);
        } else {
            bvh.addBare(std::uint32_t(index), scene.objects[index].mesh);
        }
    }
    bvh.commit();
    result.bvhSeconds = secondsSince(start);
    if (progress) progress(kBuildShare);
    result.bvhBytes = bvh.allocatedBytes();

    // 3. The pixels: one ray through each centre.
    start = std::chrono::steady_clock::now();
    const WorldShader shader(scene, bvh, meshes, options.shadowSamples);
    const PinholeProjection projection(scene.camera, options.width, options.height);
    RenderResult& render = result.render;
    render.image = Image(options.width, options.height);
    if (options.outputAovs) {
        render.aovs.emplace(RenderAovs::blank(options.width, options.height));
    }
    std::atomic<std::uint64_t> hits{0}, detailHits{0}, refined{0}, unrefined{0}, backFaces{0};
    constexpr int kBlock = 16;
    forEachImageBlock(
        options.width, options.height, kBlock, progress, kBuildShare, 1.0,
        [&](const tbb::blocked_range2d<int>& block) {
            std::uint64_t localHits = 0, localDetailHits = 0, localRefined = 0, localUnrefined = 0,
                          localBackFaces = 0;
            for (int y = block.rows().begin(); y != block.rows().end(); ++y) {
                for (int x = block.cols().begin(); x != block.cols().end(); ++x) {
                    const Ray ray = projection.ray(float(x) + 0.5f, float(y) + 0.5f);
                    WorldHit hit;
                    bool found = shader.trace(ray, hit, localBackFaces);
                    bool refinable = found && hit.onDetail;
                    if (options.method == WorldReferenceMethod::LevelSet) {
                        // Hits and normals from the level sets where one is nearer than
                        // the BVH's bare surfaces and back faces; the rest from the BVH's
                        // hit. A level set's hit is refined from the BVH's base triangle when
                        // the BVH hit the same object's detail.
                        double nearest = found && !hit.onDetail
                                             ? double(hit.distanceWorld)
                                             : std::numeric_limits<double>::infinity();
                        std::optional<std::uint32_t> levelSetObject;
                        glm::dvec3 levelSetNormal(0.0);
                        for (std::size_t index = 0; index < levelSets.size(); ++index) {
                            double distance = 0.0;
                            glm::dvec3 normal(0.0);
                            // Detail the BVH's ray ignored (seen from below its shell), with
                            // a margin of two texels for the two surfaces' difference.
                            const double ignoredFrom =
                                found && hit.ignoredDetailOf == index
                                    ? double(hit.ignoredDetailFromWorld) -
                                          2.0 * meshes[index].stats.texelSizeWorld
                                    : std::numeric_limits<double>::infinity();
                            if (levelSets[index] &&
                                levelSets[index]->intersect(
                                    glm::dvec3(ray.origin), glm::dvec3(ray.direction),
                                    std::numeric_limits<double>::max(), distance, normal) &&
                                distance < nearest && distance < ignoredFrom) {
                                nearest = distance;
                                levelSetNormal = normal;
                                levelSetObject = std::uint32_t(index);
                            }
                        }
                        if (levelSetObject) {
                            if (!found || hit.object != *levelSetObject) {
                                // The BVH saw another surface: no texel attributes here.
                                hit = WorldHit{};
                                hit.object = *levelSetObject;
                                hit.onDetail = true;
                                hit.texelZ =
                                    float(scene.objects[hit.object].material.tile->size().depth);
                                hit.baseNormal = glm::vec3(levelSetNormal);
                                refinable = false;
                            } else {
                                refinable = hit.onDetail;
                            }
                            found = true;
                            // Shadow rays are traced through the BVH: from the mesh's hit
                            // when it is the level set's (within half a texel), else from
                            // the level set's.
                            const bool meshHitNear =
                                refinable && std::abs(nearest - double(hit.distanceWorld)) <
                                                 0.5 * meshes[hit.object].stats.texelSizeWorld;
                            hit.distanceWorld = float(nearest);
                            hit.position = ray.origin + ray.direction * hit.distanceWorld;
                            hit.normal = glm::vec3(levelSetNormal);
                            if (glm::dot(hit.normal, ray.direction) > 0.0f)
                                hit.normal = -hit.normal;
                            if (!meshHitNear) {
                                hit.shadowFrom = hit.position;
                                hit.shadowNormal = hit.normal;
                            }
                        } else if (found && hit.onDetail) {
                            found = false;  // the level sets saw no detail here
                            refinable = false;
                        }
                    }
                    if (refinable) {
                        if (shader.refine(ray, hit)) {
                            ++localRefined;
                        } else {
                            ++localUnrefined;
                        }
                    }
                    if (!found) {
                        render.image.at(x, y) = skyColor(ray.direction);
                        continue;
                    }
                    ++localHits;
                    localDetailHits += hit.onDetail;
                    render.image.at(x, y) = shader.shade(ray, hit, pixelRotation(x, y));
                    if (!render.aovs) continue;
                    render.aovs->depth.at(x, y) = glm::vec3(hit.distanceWorld);
                    render.aovs->normal.at(x, y) = hit.normal * 0.5f + 0.5f;
                }
            }
            hits += localHits;
            detailHits += localDetailHits;
            refined += localRefined;
            unrefined += localUnrefined;
            backFaces += localBackFaces;
        });
    result.traceSeconds = secondsSince(start);
    render.stats.rays = std::uint64_t(options.width) * std::uint64_t(options.height);
    render.stats.baseHits = hits;
    // The reference's hits on detail are exact: all of them converged.
    render.stats.detailHits = detailHits;
    render.stats.converged = detailHits;
    result.refinedHits = refined;
    result.unrefinedHits = unrefined;
    result.backFaceStops = backFaces;
    return result;
}

}  // namespace distile
