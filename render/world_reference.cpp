#include "render/world_reference.h"

#include <embree3/rtcore.h>
#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include "common/error.h"
#include "render/coverage.h"
#include "render/shading.h"
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

/// What a hit on one Embree geometry belongs to.
struct GeometryInfo {
    std::uint32_t object = 0;
    const DisplacedMesh* detail = nullptr;  ///< null: the object's bare base mesh
    bool quads = false;                     ///< the detail's quads (else its triangles)
};

/// An Embree device and scene of every object: the world-space detail meshes of tiled objects,
/// the base meshes of the others. Buffers are shared with the meshes, which must outlive it.
class WorldBvh {
  public:
    WorldBvh() {
        device_ = rtcNewDevice("verbose=0");
        if (!device_) {
            throw std::runtime_error("embree: rtcNewDevice failed (error " +
                                     std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
        }
        rtcSetDeviceMemoryMonitorFunction(device_, &WorldBvh::monitor, &allocatedBytes_);
        scene_ = rtcNewScene(device_);
        // Robust: shared edges are watertight (no ray slips between two triangles).
        rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);
        check("creating the scene");
    }
    ~WorldBvh() {
        if (scene_) rtcReleaseScene(scene_);
        rtcReleaseDevice(device_);
    }
    WorldBvh(const WorldBvh&) = delete;
    WorldBvh& operator=(const WorldBvh&) = delete;

    /// Adds a detail mesh. Precondition: mesh.positions and mesh.texelPositions hold one more
    /// (unused) element than the mesh's vertices (Embree reads vertex buffers 16 bytes at a time).
    void addDetail(std::uint32_t object, const DisplacedMesh& mesh, std::size_t vertexCount) {
        if (!mesh.triangles.empty()) {
            attach(polygons(RTC_GEOMETRY_TYPE_TRIANGLE, mesh, vertexCount, mesh.triangles.data(),
                            RTC_FORMAT_UINT3, sizeof(glm::uvec3), mesh.triangles.size()),
                   {object, &mesh, false});
        }
        if (!mesh.quads.empty()) {
            attach(polygons(RTC_GEOMETRY_TYPE_QUAD, mesh, vertexCount, mesh.quads.data(),
                            RTC_FORMAT_UINT4, sizeof(glm::uvec4), mesh.quads.size()),
                   {object, &mesh, true});
        }
    }

    /// Adds a bare base mesh (its positions are copied).
    void addBase(std::uint32_t object, const BaseMesh& mesh) {
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
        attach(geometry, {object, nullptr, false});
    }

    void commit() {
        rtcCommitScene(scene_);
        check("building the BVH");
    }

    /// The nearest hit of the ray origin + t direction, t in (0, inf); false for a miss.
    bool intersect(const glm::vec3& origin, const glm::vec3& direction, RTCRayHit& rayHit) const {
        setRay(rayHit.ray, origin, direction, std::numeric_limits<float>::infinity());
        rayHit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rayHit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        rtcIntersect1(scene_, &context, &rayHit);
        return rayHit.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }

    /// Whether anything lies on the ray origin + t direction, t in (0, inf).
    bool occluded(const glm::vec3& origin, const glm::vec3& direction) const {
        RTCRay ray;
        setRay(ray, origin, direction, std::numeric_limits<float>::infinity());
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        rtcOccluded1(scene_, &context, &ray);
        return ray.tfar < 0.0f;  // Embree marks an occluded ray with tfar = -inf
    }

    const GeometryInfo& info(unsigned geometryId) const { return infos_[geometryId]; }
    RTCGeometry geometry(unsigned geometryId) const { return rtcGetGeometry(scene_, geometryId); }
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

    void attach(RTCGeometry geometry, const GeometryInfo& info) {
        rtcCommitGeometry(geometry);
        const unsigned id = rtcAttachGeometry(scene_, geometry);
        rtcReleaseGeometry(geometry);
        check("attaching a geometry");
        if (infos_.size() <= id) infos_.resize(id + 1);
        infos_[id] = info;
    }

    static void setRay(RTCRay& ray, const glm::vec3& origin, const glm::vec3& direction,
                       float far) {
        ray.org_x = origin.x;
        ray.org_y = origin.y;
        ray.org_z = origin.z;
        ray.dir_x = direction.x;
        ray.dir_y = direction.y;
        ray.dir_z = direction.z;
        ray.tnear = 0.0f;
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
    std::vector<GeometryInfo> infos_;  ///< by Embree geometry id
    std::atomic<long long> allocatedBytes_{0};
};

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
    bool frontFacing = true;  ///< the base triangle faces the ray
};

/// Barycentric weights of `uv` in a base triangle's uv corners (linear, also outside it).
glm::vec3 uvBarycentrics(const BaseMesh& mesh, const glm::uvec3& triangle, const glm::vec2& uv) {
    const glm::dvec2 c0(mesh.uvs[triangle.x]), c1(mesh.uvs[triangle.y]), c2(mesh.uvs[triangle.z]);
    const auto cross2 = [](const glm::dvec2& a, const glm::dvec2& b) {
        return a.x * b.y - a.y * b.x;
    };
    const double area = cross2(c1 - c0, c2 - c0);
    if (area == 0.0) return glm::vec3(1.0f / 3.0f);
    const glm::dvec2 p(uv);
    const double b1 = cross2(p - c0, c2 - c0) / area;
    const double b2 = cross2(c1 - c0, p - c0) / area;
    return glm::vec3(float(1.0 - b1 - b2), float(b1), float(b2));
}

glm::vec3 geometricNormal(const BaseMesh& mesh, const glm::uvec3& triangle) {
    return glm::cross(mesh.positions[triangle.y] - mesh.positions[triangle.x],
                      mesh.positions[triangle.z] - mesh.positions[triangle.x]);
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
        for (const DirectionalLight& light : scene.lights) {
            const glm::vec3 toLight = -glm::normalize(light.direction);
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

    /// The nearest hit along the ray, from the BVH.
    bool trace(const Ray& ray, WorldHit& hit) const {
        RTCRayHit rayHit;
        if (!bvh_.intersect(ray.origin, ray.direction, rayHit)) return false;
        const GeometryInfo& info = bvh_.info(rayHit.hit.geomID);
        const SceneObject& object = scene_.objects[info.object];
        hit.object = info.object;
        hit.distanceWorld = rayHit.ray.tfar;
        hit.position = ray.origin + ray.direction * rayHit.ray.tfar;
        glm::vec3 normal(rayHit.hit.Ng_x, rayHit.hit.Ng_y, rayHit.hit.Ng_z);
        normal = glm::normalize(normal);
        if (glm::dot(normal, ray.direction) > 0.0f) normal = -normal;
        hit.normal = normal;
        hit.onDetail = info.detail != nullptr;
        const float u = rayHit.hit.u, v = rayHit.hit.v;
        if (!hit.onDetail) {
            const glm::uvec3& triangle = object.mesh.triangles[rayHit.hit.primID];
            const glm::vec3 weights(1.0f - u - v, u, v);
            hit.uv = weights.x * object.mesh.uvs[triangle.x] +
                     weights.y * object.mesh.uvs[triangle.y] +
                     weights.z * object.mesh.uvs[triangle.z];
            hit.baseNormal = interpolatedNormal(object.mesh, triangle, weights);
            hit.normal = hit.baseNormal;  // the renderer shades bare surfaces so
            hit.frontFacing =
                glm::dot(geometricNormal(object.mesh, triangle), ray.direction) < 0.0f;
            hit.texelZ = 0.0f;
            return true;
        }
        float texel[3];
        rtcInterpolate0(bvh_.geometry(rayHit.hit.geomID), rayHit.hit.primID, u, v,
                        RTC_BUFFER_TYPE_VERTEX_ATTRIBUTE, 0, texel, 3);
        const Material& material = object.material;
        const Size3 tile = material.tile->size();
        hit.uv = glm::vec2(texel[0] / (material.uvScale.x * float(tile.width)),
                           texel[1] / (material.uvScale.y * float(tile.height)));
        hit.texelZ = texel[2];
        const std::uint32_t base = info.quads ? info.detail->quadBase[rayHit.hit.primID]
                                              : info.detail->triangleBase[rayHit.hit.primID];
        const glm::uvec3& triangle = object.mesh.triangles[base];
        hit.baseNormal = interpolatedNormal(object.mesh, triangle,
                                            uvBarycentrics(object.mesh, triangle, hit.uv));
        hit.frontFacing = glm::dot(geometricNormal(object.mesh, triangle), ray.direction) < 0.0f;
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
        const glm::vec3 origin = hit.position + hit.normal * offsetWorld;
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
    // Progress: the meshes are the first half of kBuildShare, the BVH the second, then the rows.
    constexpr double kBuildShare = 0.6;

    // 1. The world-space detail meshes (and, for the level-set method, their level sets).
    auto start = std::chrono::steady_clock::now();
    std::vector<DisplacedMesh> meshes(scene.objects.size());
    std::vector<std::size_t> vertexCounts(scene.objects.size(), 0);
    std::vector<std::optional<DisplacedLevelSet>> levelSets(scene.objects.size());
    for (std::size_t index = 0; index < scene.objects.size(); ++index) {
        const SceneObject& object = scene.objects[index];
        const Material& material = object.material;
        if (!material.tile) continue;
        const DisplacementShell shell{object.mesh.positions,
                                      object.mesh.normals,
                                      object.mesh.uvs,
                                      object.mesh.triangles,
                                      glm::dvec2(material.uvScale),
                                      double(material.depthWorld),
                                      material.floor == Floor::Solid};
        try {
            meshes[index] = buildDisplacedMesh(detailDistance(material), material.tile->size(),
                                               shell, options.levelSet.mesh);
            result.meshes.push_back(meshes[index].stats);
            if (options.method == WorldReferenceMethod::LevelSet) {
                const auto levelSetStart = std::chrono::steady_clock::now();
                levelSets[index] = DisplacedLevelSet::build(meshes[index], options.levelSet);
                result.levelSets.push_back(levelSets[index]->stats());
                result.levelSetSeconds += secondsSince(levelSetStart);
            }
        } catch (const InputError& error) {
            throw InputError("objects[" + std::to_string(index) + "]: " + error.what());
        }
        if (progress) progress(kBuildShare * 0.5 * double(index + 1) / scene.objects.size());
        // Embree reads vertex buffers 16 bytes at a time: one unused element past the end.
        vertexCounts[index] = meshes[index].positions.size();
        meshes[index].positions.emplace_back(0.0f);
        meshes[index].texelPositions.emplace_back(0.0f);
    }
    result.meshSeconds = secondsSince(start) - result.levelSetSeconds;

    // 2. One BVH of every object.
    start = std::chrono::steady_clock::now();
    WorldBvh bvh;
    for (std::size_t index = 0; index < scene.objects.size(); ++index) {
        if (scene.objects[index].material.tile) {
            bvh.addDetail(std::uint32_t(index), meshes[index], vertexCounts[index]);
        } else {
            bvh.addBase(std::uint32_t(index), scene.objects[index].mesh);
        }
    }
    bvh.commit();
    result.bvhSeconds = secondsSince(start);
    if (progress) progress(kBuildShare);
    result.bvhBytes = bvh.allocatedBytes();

    // 3. The pixels: one ray through each centre, bands of rows for progress reports.
    start = std::chrono::steady_clock::now();
    const WorldShader shader(scene, bvh, meshes, options.shadowSamples);
    const PinholeProjection projection(scene.camera, options.width, options.height);
    RenderResult& render = result.render;
    render.image = Image(options.width, options.height);
    if (options.outputAovs) {
        render.aovs.emplace(RenderAovs::blank(options.width, options.height));
    }
    std::atomic<std::uint64_t> hits{0};
    constexpr int kBlock = 16;
    constexpr int kBandRows = 64;
    for (int bandStart = 0; bandStart < options.height; bandStart += kBandRows) {
        const int bandEnd = std::min(bandStart + kBandRows, options.height);
        tbb::parallel_for(
            tbb::blocked_range2d<int>(bandStart, bandEnd, kBlock, 0, options.width, kBlock),
            [&](const tbb::blocked_range2d<int>& block) {
                std::uint64_t localHits = 0;
                for (int y = block.rows().begin(); y != block.rows().end(); ++y) {
                    for (int x = block.cols().begin(); x != block.cols().end(); ++x) {
                        const Ray ray = projection.ray(float(x) + 0.5f, float(y) + 0.5f);
                        WorldHit hit;
                        bool found = shader.trace(ray, hit);
                        if (options.method == WorldReferenceMethod::LevelSet) {
                            // Hits and normals from the level sets where one is nearer than
                            // the BVH's bare surfaces; the rest from the BVH's hit.
                            double nearest = found && !hit.onDetail
                                                 ? double(hit.distanceWorld)
                                                 : std::numeric_limits<double>::infinity();
                            std::optional<std::uint32_t> levelSetObject;
                            glm::dvec3 levelSetNormal(0.0);
                            for (std::size_t index = 0; index < levelSets.size(); ++index) {
                                double distance = 0.0;
                                glm::dvec3 normal(0.0);
                                if (levelSets[index] &&
                                    levelSets[index]->intersect(
                                        glm::dvec3(ray.origin), glm::dvec3(ray.direction),
                                        std::numeric_limits<double>::max(), distance, normal) &&
                                    distance < nearest) {
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
                                    hit.texelZ = float(
                                        scene.objects[hit.object].material.tile->size().depth);
                                    hit.baseNormal = glm::vec3(levelSetNormal);
                                }
                                found = true;
                                hit.distanceWorld = float(nearest);
                                hit.position = ray.origin + ray.direction * hit.distanceWorld;
                                hit.normal = glm::vec3(levelSetNormal);
                                if (glm::dot(hit.normal, ray.direction) > 0.0f)
                                    hit.normal = -hit.normal;
                            } else if (found && hit.onDetail) {
                                found = false;  // the level sets saw no detail here
                            }
                        }
                        if (!found) {
                            render.image.at(x, y) = skyColor(ray.direction);
                            continue;
                        }
                        ++localHits;
                        render.image.at(x, y) = shader.shade(ray, hit, pixelRotation(x, y));
                        if (!render.aovs) continue;
                        render.aovs->depth.at(x, y) = glm::vec3(hit.distanceWorld);
                        render.aovs->normal.at(x, y) = hit.normal * 0.5f + 0.5f;
                    }
                }
                hits += localHits;
            });
        if (progress)
            progress(kBuildShare + (1.0 - kBuildShare) * double(bandEnd) / options.height);
    }
    result.traceSeconds = secondsSince(start);
    render.stats.rays = std::uint64_t(options.width) * std::uint64_t(options.height);
    render.stats.baseHits = hits;
    render.stats.converged = hits;
    return result;
}

}  // namespace distile
