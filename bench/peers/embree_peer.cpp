// Embree 3 peer (peers.h): the sheet's chain mail as triangles in world space, one rtcIntersect1
// per pixel centre.
#include <cmath>
#include <string>

#include "bench/peers/peers.h"
#include "bench/peers/sheet.h"

#ifdef DISTILE_HAVE_EMBREE
#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <chrono>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "render/coverage.h"
#include "vdb/chainmail.h"
#endif

namespace distile {

#ifndef DISTILE_HAVE_EMBREE

PeerRender renderSheetWithEmbree(const Scene&, int width, int height, int threads) {
    detail::validatePeerRequest(width, height, threads);
    return detail::unavailablePeer("embree", "not available: libembree-dev not installed");
}

#else

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Fewest polygon sides for which a circle of `radiusTexels` strays at most `sagittaTexels` from
/// its inscribed polygon: r (1 - cos(pi / n)) <= sagitta.
int segmentsForSagitta(double radiusTexels, double sagittaTexels) {
    const double halfAngle = std::acos(std::max(1.0 - sagittaTexels / radiusTexels, -1.0));
    return std::clamp(int(std::ceil(kPi / halfAngle)), 3, 4096);
}

double secondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// Owns an Embree device; counts what it allocates.
class Device {
  public:
    explicit Device(int threads) {
        const std::string config = "threads=" + std::to_string(threads) + ",set_affinity=0";
        device_ = rtcNewDevice(config.c_str());
        if (!device_) {
            throw std::runtime_error("embree: rtcNewDevice failed (error " +
                                     std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
        }
        rtcSetDeviceMemoryMonitorFunction(device_, &Device::monitor, &allocatedBytes_);
    }
    ~Device() { rtcReleaseDevice(device_); }
    Device(const Device&) = delete;
    Device& operator=(const Device&) = delete;

    RTCDevice get() const { return device_; }
    std::size_t allocatedBytes() const {
        return std::size_t(std::max<long long>(allocatedBytes_, 0));
    }
    void check(const char* what) const {
        const RTCError error = rtcGetDeviceError(device_);
        if (error != RTC_ERROR_NONE)
            throw std::runtime_error(std::string("embree: ") + what + " failed (error " +
                                     std::to_string(int(error)) + ")");
    }

  private:
    static bool monitor(void* userPointer, ssize_t bytes, bool) {
        *static_cast<std::atomic<long long>*>(userPointer) += bytes;
        return true;
    }
    RTCDevice device_ = nullptr;
    std::atomic<long long> allocatedBytes_{0};
};

/// A triangle geometry with Embree-allocated buffers holding `positions` and `triangles`.
RTCGeometry triangleGeometry(const Device& device, const std::vector<glm::vec3>& positions,
                             const std::vector<glm::uvec3>& triangles) {
    RTCGeometry geometry = rtcNewGeometry(device.get(), RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                3 * sizeof(float), positions.size()));
    auto* indices = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(unsigned), triangles.size()));
    device.check("allocating the geometry buffers");
    std::copy_n(&positions.front().x, 3 * positions.size(), vertices);
    std::copy_n(&triangles.front().x, 3 * triangles.size(), indices);
    return geometry;
}

/// The part of sheet texel space (x, y) rays can reach: distile marches a ray that entered the
/// shell through the base mesh on in the periodic tile until it hits, also past the mesh's edge,
/// so the rectangle is the uv rectangle grown by the farthest a camera ray sideways below the
/// surface before it reaches the floor (largest at a corner of the rectangle).
struct TexelRectangle {
    glm::dvec2 min{0.0}, max{0.0};
};
TexelRectangle reachableRectangle(const detail::SheetPlacement& sheet, const glm::dvec3& eye) {
    const glm::dvec2 tileTexels(sheet.tile.width, sheet.tile.height);
    TexelRectangle rectangle{sheet.uvMin * sheet.uvScale * tileTexels,
                             sheet.uvMax * sheet.uvScale * tileTexels};
    const glm::dvec3 eyeTexel = sheet.texelFromWorld(eye);
    const double heightTexels = eyeTexel.z - sheet.tile.depth;
    double travelTexels = 0.0;
    if (heightTexels <= 0.0) {
        travelTexels = 8.0 * std::max(tileTexels.x, tileTexels.y);  // eye in or under the shell
    } else {
        for (const double x : {rectangle.min.x, rectangle.max.x}) {
            for (const double y : {rectangle.min.y, rectangle.max.y}) {
                const double sideways = glm::length(glm::dvec2(x, y) - glm::dvec2(eyeTexel));
                travelTexels = std::max(travelTexels, sheet.tile.depth * sideways / heightTexels);
            }
        }
        travelTexels = std::min(travelTexels, 8.0 * std::max(tileTexels.x, tileTexels.y));
    }
    rectangle.min -= travelTexels + 1.0;
    rectangle.max += travelTexels + 1.0;
    return rectangle;
}

/// True when `ray` enters the shell through the top inside the base mesh's uv rectangle: the only
/// rays distile marches (it finds the shell through the base mesh).
bool entersThroughTheBase(const detail::SheetPlacement& sheet, const Ray& ray) {
    const glm::dvec3 origin(ray.origin), direction(ray.direction);
    const double descent = glm::dot(direction, sheet.normal);
    if (!(descent < 0.0)) return false;
    const double distance = glm::dot(sheet.originWorld - origin, sheet.normal) / descent;
    return distance >= 0.0 && sheet.inFootprint(origin + direction * distance);
}

/// The rings of every tile repeat that can reach into `reachable`, in world space (float), with
/// their triangles.
void placeRings(const detail::SheetPlacement& sheet, const TriangleSoup& tileRings,
                std::size_t verticesPerRing, const TexelRectangle& reachable,
                std::vector<glm::vec3>& positions, std::vector<glm::uvec3>& triangles) {
    const glm::dvec2 tileTexels(sheet.tile.width, sheet.tile.height);
    const glm::dvec2 footprintMin = reachable.min;
    const glm::dvec2 footprintMax = reachable.max;
    const std::size_t rings = tileRings.positions.size() / verticesPerRing;
    const std::size_t trianglesPerRing = tileRings.triangles.size() / rings;
    // One repeat more on each side: rings centred in a neighbouring tile cross into this one.
    const int firstX = int(std::floor(footprintMin.x / tileTexels.x)) - 1;
    const int lastX = int(std::ceil(footprintMax.x / tileTexels.x));
    const int firstY = int(std::floor(footprintMin.y / tileTexels.y)) - 1;
    const int lastY = int(std::ceil(footprintMax.y / tileTexels.y));
    for (int repeatY = firstY; repeatY <= lastY; ++repeatY) {
        for (int repeatX = firstX; repeatX <= lastX; ++repeatX) {
            const glm::dvec3 shift(repeatX * tileTexels.x, repeatY * tileTexels.y, 0.0);
            for (std::size_t ring = 0; ring < rings; ++ring) {
                const auto begin =
                    tileRings.positions.begin() + std::ptrdiff_t(ring * verticesPerRing);
                glm::dvec3 low(begin[0]), high(begin[0]);
                for (std::size_t v = 0; v < verticesPerRing; ++v) {
                    low = glm::min(low, begin[std::ptrdiff_t(v)]);
                    high = glm::max(high, begin[std::ptrdiff_t(v)]);
                }
                low += shift;
                high += shift;
                if (high.x < footprintMin.x || low.x > footprintMax.x || high.y < footprintMin.y ||
                    low.y > footprintMax.y) {
                    continue;
                }
                const auto offset = unsigned(positions.size()) - unsigned(ring * verticesPerRing);
                for (std::size_t v = 0; v < verticesPerRing; ++v)
                    positions.push_back(
                        glm::vec3(sheet.worldFromTexel(begin[std::ptrdiff_t(v)] + shift)));
                for (std::size_t t = 0; t < trianglesPerRing; ++t)
                    triangles.push_back(tileRings.triangles[ring * trianglesPerRing + t] + offset);
            }
        }
    }
}

}  // namespace

PeerRender renderSheetWithEmbree(const Scene& scene, int width, int height, int threads) {
    detail::validatePeerRequest(width, height, threads);
    validateScene(scene);
    auto found = detail::findSheet(scene);
    if (const auto* reason = std::get_if<std::string>(&found))
        return detail::unavailablePeer("embree", *reason);
    const detail::SheetPlacement& sheet = std::get<detail::SheetPlacement>(found);

    PeerRender result;
    result.name = "embree";
    result.available = true;
    const auto setupStart = std::chrono::steady_clock::now();
    // Half the error budget to each circle: chainmailTessellationErrorTexels is their sum.
    const Chainmail chainmail(sheet.chainmail, sheet.tile);
    const double spacing = double(sheet.tile.width) / sheet.chainmail.ringsPerRow;
    const double ringRadius = sheet.chainmail.ringRadiusSpacings * spacing;
    const double wireRadius = sheet.chainmail.wireRadiusSpacings * spacing;
    const int around =
        segmentsForSagitta(ringRadius + wireRadius, 0.5 * kEmbreeTessellationErrorTexels);
    const int tube = segmentsForSagitta(wireRadius, 0.5 * kEmbreeTessellationErrorTexels);
    assert(chainmailTessellationErrorTexels(chainmail, around, tube) <=
           kEmbreeTessellationErrorTexels);
    const TriangleSoup tileRings = tessellateChainmail(chainmail, around, tube);

    const TexelRectangle reachable = reachableRectangle(sheet, glm::dvec3(scene.camera.eye));
    const glm::dvec2 tilesReached =
        (reachable.max - reachable.min) / glm::dvec2(sheet.tile.width, sheet.tile.height) + 3.0;
    if (tilesReached.x * tilesReached.y * double(tileRings.triangles.size()) > double(1 << 28)) {
        return detail::unavailablePeer(
            "embree", "not available: the sheet would need more than 2^28 triangles");
    }
    std::vector<glm::vec3> ringPositions;
    std::vector<glm::uvec3> ringTriangles;
    placeRings(sheet, tileRings, std::size_t(around) * std::size_t(tube), reachable, ringPositions,
               ringTriangles);
    // The solid floor at the bottom of the shell, as far as rays reach.
    const std::vector<glm::vec3> floorPositions{
        glm::vec3(sheet.worldFromTexel({reachable.min.x, reachable.min.y, 0.0})),
        glm::vec3(sheet.worldFromTexel({reachable.max.x, reachable.min.y, 0.0})),
        glm::vec3(sheet.worldFromTexel({reachable.max.x, reachable.max.y, 0.0})),
        glm::vec3(sheet.worldFromTexel({reachable.min.x, reachable.max.y, 0.0}))};
    const std::vector<glm::uvec3> floorTriangles{{0, 1, 2}, {0, 2, 3}};

    tbb::task_arena arena(threads);
    Device device(threads);
    // Released before the device (declared after it).
    const std::unique_ptr<std::remove_pointer_t<RTCScene>, void (*)(RTCScene)> embreeScene(
        rtcNewScene(device.get()), &rtcReleaseScene);
    arena.execute([&] {
        if (!ringTriangles.empty()) {
            RTCGeometry rings = triangleGeometry(device, ringPositions, ringTriangles);
            rtcCommitGeometry(rings);
            rtcAttachGeometry(embreeScene.get(), rings);
            rtcReleaseGeometry(rings);
        }
        RTCGeometry floor = triangleGeometry(device, floorPositions, floorTriangles);
        rtcCommitGeometry(floor);
        rtcAttachGeometry(embreeScene.get(), floor);
        rtcReleaseGeometry(floor);
        rtcCommitScene(embreeScene.get());
    });
    device.check("building the scene");
    result.setupSeconds = secondsSince(setupStart);
    result.memoryBytes = device.allocatedBytes();

    result.depth = Image(width, height);
    result.normal = Image(width, height);
    const PinholeProjection projection(scene.camera, width, height);
    const auto traceStart = std::chrono::steady_clock::now();
    arena.execute([&] {
        tbb::parallel_for(
            tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
                RTCIntersectContext context;
                rtcInitIntersectContext(&context);
                for (int y = rows.begin(); y != rows.end(); ++y) {
                    for (int x = 0; x < width; ++x) {
                        const Ray ray = projection.ray(float(x) + 0.5f, float(y) + 0.5f);
                        if (!entersThroughTheBase(sheet, ray)) continue;
                        RTCRayHit query{};
                        query.ray.org_x = ray.origin.x;
                        query.ray.org_y = ray.origin.y;
                        query.ray.org_z = ray.origin.z;
                        query.ray.dir_x = ray.direction.x;
                        query.ray.dir_y = ray.direction.y;
                        query.ray.dir_z = ray.direction.z;
                        query.ray.tnear = 0.0f;
                        query.ray.tfar = std::numeric_limits<float>::infinity();
                        query.ray.mask = 0xFFFFFFFFu;
                        query.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                        rtcIntersect1(embreeScene.get(), &context, &query);
                        if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
                        glm::vec3 normal = glm::normalize(
                            glm::vec3(query.hit.Ng_x, query.hit.Ng_y, query.hit.Ng_z));
                        if (glm::dot(normal, ray.direction) > 0.0f) normal = -normal;
                        result.depth.at(x, y) = glm::vec3(query.ray.tfar);
                        result.normal.at(x, y) = normal * 0.5f + 0.5f;
                    }
                }
            });
    });
    result.traceSeconds = secondsSince(traceStart);
    return result;
}

#endif

}  // namespace distile
