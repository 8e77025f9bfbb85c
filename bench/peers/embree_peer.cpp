// Embree 3 peer (peers.h): the sheet's chain mail as triangles or quads in world space, the
// camera rays through the pixel centres one at a time or in packets of pixel tiles.
#include <cmath>
#include <cstdio>
#include <string>

#include "bench/peers/peers.h"
#include "bench/peers/sheet.h"

#ifdef DISTILE_HAVE_EMBREE
#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
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

#include "common/error.h"

namespace distile {

std::string embreePeerLabel(const EmbreePeerOptions& options) {
    char label[160];
    std::snprintf(label, sizeof label, "embree %s, %s%s, %g texel",
                  options.raysPerPacket == 1
                      ? "1 ray"
                      : (std::to_string(options.raysPerPacket) + "-wide packets").c_str(),
                  options.quads ? "quads" : "triangles", options.highQualityBvh ? ", high BVH" : "",
                  options.tessellationErrorTexels);
    return label;
}

namespace {

void validateEmbreeOptions(const EmbreePeerOptions& options) {
    if (!(options.tessellationErrorTexels > 0.0) || !std::isfinite(options.tessellationErrorTexels))
        throw InputError("tessellationErrorTexels: " +
                         numberText(options.tessellationErrorTexels) +
                         " is not accepted; it must be a finite number > 0");
    const int rays = options.raysPerPacket;
    if (rays != 1 && rays != 4 && rays != 8 && rays != 16)
        throw InputError("raysPerPacket: " + std::to_string(rays) +
                         " is not accepted; it must be 1, 4, 8 or 16");
    if (options.traceRuns < 1)
        throw InputError("traceRuns: " + std::to_string(options.traceRuns) +
                         " is not accepted; it must be >= 1");
}

}  // namespace

#ifndef DISTILE_HAVE_EMBREE

int embreeNativePacketWidth() {
    return 1;
}

PeerRender renderSheetWithEmbree(const Scene&, int width, int height, int threads,
                                 const EmbreePeerOptions& options) {
    detail::validatePeerRequest(width, height, threads);
    validateEmbreeOptions(options);
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

/// A triangle (`Polygon` glm::uvec3) or quad (glm::uvec4) geometry with Embree-allocated buffers
/// holding `positions` and `polygons`.
template <typename Polygon>
RTCGeometry meshGeometry(const Device& device, const std::vector<glm::vec3>& positions,
                         const std::vector<Polygon>& polygons) {
    constexpr bool kQuads = Polygon::length() == 4;
    RTCGeometry geometry = rtcNewGeometry(
        device.get(), kQuads ? RTC_GEOMETRY_TYPE_QUAD : RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                3 * sizeof(float), positions.size()));
    auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_INDEX, 0, kQuads ? RTC_FORMAT_UINT4 : RTC_FORMAT_UINT3,
        sizeof(Polygon), polygons.size()));
    device.check("allocating the geometry buffers");
    std::copy_n(&positions.front().x, 3 * positions.size(), vertices);
    std::copy_n(&polygons.front().x, Polygon::length() * polygons.size(), indices);
    return geometry;
}

/// The quads of tessellateChainmail's triangles: it emits each quad (a, b, c, d) as the triangles
/// (a, b, c) and (a, c, d), one after the other.
std::vector<glm::uvec4> quadsOf(const std::vector<glm::uvec3>& triangles) {
    std::vector<glm::uvec4> quads;
    quads.reserve(triangles.size() / 2);
    for (std::size_t t = 0; t + 1 < triangles.size(); t += 2) {
        assert(triangles[t].x == triangles[t + 1].x && triangles[t].z == triangles[t + 1].y);
        quads.emplace_back(triangles[t].x, triangles[t].y, triangles[t].z, triangles[t + 1].z);
    }
    return quads;
}

/// The base mesh's uv rectangle in sheet texel space (x, y): where the shell is. distile's march
/// ends where a ray leaves it through the mesh's open border, so the rings are cut there.
struct TexelRectangle {
    glm::dvec2 min{0.0}, max{0.0};
};
TexelRectangle footprintRectangle(const detail::SheetPlacement& sheet) {
    const glm::dvec2 tileTexels(sheet.tile.width, sheet.tile.height);
    return {sheet.uvMin * sheet.uvScale * tileTexels, sheet.uvMax * sheet.uvScale * tileTexels};
}

/// `polygon` (texel space, convex) cut to the rectangle's x and y ranges (Sutherland-Hodgman; z
/// interpolated along the cut edges): empty when nothing of it lies inside.
std::vector<glm::dvec3> clippedToRectangle(std::vector<glm::dvec3> polygon,
                                           const TexelRectangle& rectangle) {
    for (int axis = 0; axis < 2; ++axis) {
        for (const double sign : {1.0, -1.0}) {
            // Inside: sign * (p[axis] - bound) >= 0, the bound the min (sign 1) or the max (-1).
            const double bound = sign > 0.0 ? rectangle.min[axis] : rectangle.max[axis];
            std::vector<glm::dvec3> kept;
            for (std::size_t k = 0; k < polygon.size(); ++k) {
                const glm::dvec3& from = polygon[k];
                const glm::dvec3& to = polygon[(k + 1) % polygon.size()];
                const double fromSide = sign * (from[axis] - bound);
                const double toSide = sign * (to[axis] - bound);
                if (fromSide >= 0.0) kept.push_back(from);
                if ((fromSide >= 0.0) != (toSide >= 0.0))
                    kept.push_back(from + (to - from) * (fromSide / (fromSide - toSide)));
            }
            polygon = std::move(kept);
            if (polygon.empty()) return polygon;
        }
    }
    return polygon;
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

/// The rings of every tile repeat over `footprint`, in world space (float): the polygons wholly
/// inside it as they are (the tile's `tilePolygons`, triangles or quads, indexing
/// `tilePositions`) into `positions` and `polygons`, those across its edge cut there into
/// triangles (`cutPositions`, `cutTriangles`), those outside dropped.
template <typename Polygon>
void placeRings(const detail::SheetPlacement& sheet, const std::vector<glm::dvec3>& tilePositions,
                const std::vector<Polygon>& tilePolygons, std::size_t verticesPerRing,
                const TexelRectangle& footprint, std::vector<glm::vec3>& positions,
                std::vector<Polygon>& polygons, std::vector<glm::vec3>& cutPositions,
                std::vector<glm::uvec3>& cutTriangles) {
    const glm::dvec2 tileTexels(sheet.tile.width, sheet.tile.height);
    const std::size_t rings = tilePositions.size() / verticesPerRing;
    const std::size_t polygonsPerRing = tilePolygons.size() / rings;
    const auto inside = [&](const glm::dvec3& point) {
        return point.x >= footprint.min.x && point.x <= footprint.max.x &&
               point.y >= footprint.min.y && point.y <= footprint.max.y;
    };
    // One repeat more on each side: rings centred in a neighbouring tile cross into this one.
    const int firstX = int(std::floor(footprint.min.x / tileTexels.x)) - 1;
    const int lastX = int(std::ceil(footprint.max.x / tileTexels.x));
    const int firstY = int(std::floor(footprint.min.y / tileTexels.y)) - 1;
    const int lastY = int(std::ceil(footprint.max.y / tileTexels.y));
    for (int repeatY = firstY; repeatY <= lastY; ++repeatY) {
        for (int repeatX = firstX; repeatX <= lastX; ++repeatX) {
            const glm::dvec3 shift(repeatX * tileTexels.x, repeatY * tileTexels.y, 0.0);
            for (std::size_t ring = 0; ring < rings; ++ring) {
                const auto begin = tilePositions.begin() + std::ptrdiff_t(ring * verticesPerRing);
                glm::dvec3 low(begin[0]), high(begin[0]);
                for (std::size_t v = 0; v < verticesPerRing; ++v) {
                    low = glm::min(low, begin[std::ptrdiff_t(v)]);
                    high = glm::max(high, begin[std::ptrdiff_t(v)]);
                }
                low += shift;
                high += shift;
                if (high.x < footprint.min.x || low.x > footprint.max.x ||
                    high.y < footprint.min.y || low.y > footprint.max.y) {
                    continue;
                }
                const auto offset = unsigned(positions.size()) - unsigned(ring * verticesPerRing);
                for (std::size_t v = 0; v < verticesPerRing; ++v)
                    positions.push_back(
                        glm::vec3(sheet.worldFromTexel(begin[std::ptrdiff_t(v)] + shift)));
                for (std::size_t p = 0; p < polygonsPerRing; ++p) {
                    const Polygon& polygon = tilePolygons[ring * polygonsPerRing + p];
                    std::vector<glm::dvec3> corners;
                    for (int corner = 0; corner < Polygon::length(); ++corner)
                        corners.push_back(tilePositions[polygon[corner]] + shift);
                    if (std::all_of(corners.begin(), corners.end(), inside)) {
                        polygons.push_back(polygon + offset);
                        continue;
                    }
                    const std::vector<glm::dvec3> cut = clippedToRectangle(corners, footprint);
                    if (cut.size() < 3) continue;
                    const auto first = unsigned(cutPositions.size());
                    for (const glm::dvec3& corner : cut)
                        cutPositions.push_back(glm::vec3(sheet.worldFromTexel(corner)));
                    for (unsigned k = 1; k + 1 < cut.size(); ++k)
                        cutTriangles.emplace_back(first, first + k, first + k + 1);
                }
            }
        }
    }
}

/// Embree's packet type, call and pixel tile by width N (4, 8 or 16): 2 x 2, 4 x 2 or 4 x 4.
template <int N>
struct Packet {
    static_assert(N == 4 || N == 8 || N == 16);
    using RayHit = std::conditional_t<N == 4, RTCRayHit4,
                                      std::conditional_t<N == 8, RTCRayHit8, RTCRayHit16>>;
    static constexpr int kWidth = N == 4 ? 2 : 4;
    static void intersect(const int* valid, RTCScene scene, RTCIntersectContext* context,
                          RayHit* rays) {
        if constexpr (N == 4)
            rtcIntersect4(valid, scene, context, rays);
        else if constexpr (N == 8)
            rtcIntersect8(valid, scene, context, rays);
        else
            rtcIntersect16(valid, scene, context, rays);
    }
};

/// What a trace writes for a hit: the distance along the ray and the geometric normal facing the
/// ray, n * 0.5 + 0.5 (peers.h PeerRender).
void storeHit(PeerRender& result, int x, int y, const Ray& ray, float distance,
              const glm::vec3& geometricNormal) {
    glm::vec3 normal = glm::normalize(geometricNormal);
    if (glm::dot(normal, ray.direction) > 0.0f) normal = -normal;
    result.depth.at(x, y) = glm::vec3(distance);
    result.normal.at(x, y) = normal * 0.5f + 0.5f;
}

/// Traces every pixel centre one ray at a time, rows in parallel.
void traceSingleRays(RTCScene scene, const detail::SheetPlacement& sheet,
                     const PinholeProjection& projection, PeerRender& result) {
    const int width = result.depth.width;
    tbb::parallel_for(tbb::blocked_range<int>(0, result.depth.height),
                      [&](const tbb::blocked_range<int>& rows) {
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
                rtcIntersect1(scene, &context, &query);
                if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
                storeHit(result, x, y, ray, query.ray.tfar,
                         {query.hit.Ng_x, query.hit.Ng_y, query.hit.Ng_z});
            }
        }
    });
}

/// Traces every pixel centre in packets of N rays, one per pixel of a Packet<N>::kWidth x
/// (N / kWidth) tile (coherent camera rays), rows of tiles in parallel. Lanes outside the image or
/// whose ray does not enter through the base are masked off.
template <int N>
void tracePackets(RTCScene scene, const detail::SheetPlacement& sheet,
                  const PinholeProjection& projection, PeerRender& result) {
    constexpr int kTileWidth = Packet<N>::kWidth;
    constexpr int kTileHeight = N / kTileWidth;
    const int width = result.depth.width;
    const int height = result.depth.height;
    const int tileRows = (height + kTileHeight - 1) / kTileHeight;
    tbb::parallel_for(tbb::blocked_range<int>(0, tileRows), [&](const tbb::blocked_range<int>&
                                                                    range) {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        alignas(64) typename Packet<N>::RayHit packet;
        alignas(64) int valid[N];
        std::array<Ray, N> rays;
        for (int tileRow = range.begin(); tileRow != range.end(); ++tileRow) {
            for (int tileX = 0; tileX < width; tileX += kTileWidth) {
                bool any = false;
                for (int lane = 0; lane < N; ++lane) {
                    const int x = tileX + lane % kTileWidth;
                    const int y = tileRow * kTileHeight + lane / kTileWidth;
                    valid[lane] = 0;
                    packet.ray.tnear[lane] = 0.0f;
                    packet.ray.tfar[lane] = std::numeric_limits<float>::infinity();
                    packet.ray.mask[lane] = 0xFFFFFFFFu;
                    packet.ray.time[lane] = 0.0f;
                    packet.ray.flags[lane] = 0;
                    packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
                    if (x >= width || y >= height) continue;
                    rays[lane] = projection.ray(float(x) + 0.5f, float(y) + 0.5f);
                    const Ray& ray = rays[lane];
                    if (!entersThroughTheBase(sheet, ray)) continue;
                    valid[lane] = -1;
                    any = true;
                    packet.ray.org_x[lane] = ray.origin.x;
                    packet.ray.org_y[lane] = ray.origin.y;
                    packet.ray.org_z[lane] = ray.origin.z;
                    packet.ray.dir_x[lane] = ray.direction.x;
                    packet.ray.dir_y[lane] = ray.direction.y;
                    packet.ray.dir_z[lane] = ray.direction.z;
                }
                if (!any) continue;
                Packet<N>::intersect(valid, scene, &context, &packet);
                for (int lane = 0; lane < N; ++lane) {
                    if (!valid[lane] || packet.hit.geomID[lane] == RTC_INVALID_GEOMETRY_ID)
                        continue;
                    storeHit(result, tileX + lane % kTileWidth,
                             tileRow * kTileHeight + lane / kTileWidth, rays[lane],
                             packet.ray.tfar[lane],
                             {packet.hit.Ng_x[lane], packet.hit.Ng_y[lane], packet.hit.Ng_z[lane]});
                }
            }
        }
    });
}

/// The tessellated rings placed over the footprint and cut at its edge, with their polygons,
/// then the floor under the footprint, attached to `scene` and committed.
template <typename Polygon>
void buildScene(const Device& device, RTCScene scene, const detail::SheetPlacement& sheet,
                const TriangleSoup& tileRings, const std::vector<Polygon>& tilePolygons,
                std::size_t verticesPerRing, const TexelRectangle& footprint) {
    std::vector<glm::vec3> ringPositions, cutPositions;
    std::vector<Polygon> ringPolygons;
    std::vector<glm::uvec3> cutTriangles;
    placeRings(sheet, tileRings.positions, tilePolygons, verticesPerRing, footprint, ringPositions,
               ringPolygons, cutPositions, cutTriangles);
    const auto attach = [&](RTCGeometry geometry) {
        rtcCommitGeometry(geometry);
        rtcAttachGeometry(scene, geometry);
        rtcReleaseGeometry(geometry);
    };
    if (!ringPolygons.empty()) attach(meshGeometry(device, ringPositions, ringPolygons));
    if (!cutTriangles.empty()) attach(meshGeometry(device, cutPositions, cutTriangles));
    // The solid floor at the bottom of the shell.
    const std::vector<glm::vec3> floorPositions{
        glm::vec3(sheet.worldFromTexel({footprint.min.x, footprint.min.y, 0.0})),
        glm::vec3(sheet.worldFromTexel({footprint.max.x, footprint.min.y, 0.0})),
        glm::vec3(sheet.worldFromTexel({footprint.max.x, footprint.max.y, 0.0})),
        glm::vec3(sheet.worldFromTexel({footprint.min.x, footprint.max.y, 0.0}))};
    const std::vector<glm::uvec3> floorTriangles{{0, 1, 2}, {0, 2, 3}};
    attach(meshGeometry(device, floorPositions, floorTriangles));
    rtcCommitScene(scene);
}

}  // namespace

int embreeNativePacketWidth() {
    Device device(1);
    for (const auto& [property, width] :
         {std::pair{RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED, 16},
          std::pair{RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED, 8},
          std::pair{RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED, 4}}) {
        if (rtcGetDeviceProperty(device.get(), property) != 0) return width;
    }
    return 1;
}

PeerRender renderSheetWithEmbree(const Scene& scene, int width, int height, int threads,
                                 const EmbreePeerOptions& options) {
    detail::validatePeerRequest(width, height, threads);
    validateEmbreeOptions(options);
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
    const double errorTexels = options.tessellationErrorTexels;
    const Chainmail chainmail(sheet.chainmail, sheet.tile);
    const double spacing = double(sheet.tile.width) / sheet.chainmail.ringsPerRow;
    const double ringRadius = sheet.chainmail.ringRadiusSpacings * spacing;
    const double wireRadius = sheet.chainmail.wireRadiusSpacings * spacing;
    const int around = segmentsForSagitta(ringRadius + wireRadius, 0.5 * errorTexels);
    const int tube = segmentsForSagitta(wireRadius, 0.5 * errorTexels);
    assert(chainmailTessellationErrorTexels(chainmail, around, tube) <= errorTexels);
    const TriangleSoup tileRings = tessellateChainmail(chainmail, around, tube);

    const TexelRectangle footprint = footprintRectangle(sheet);
    const glm::dvec2 tilesReached =
        (footprint.max - footprint.min) / glm::dvec2(sheet.tile.width, sheet.tile.height) + 3.0;
    if (tilesReached.x * tilesReached.y * double(tileRings.triangles.size()) > double(1 << 28)) {
        return detail::unavailablePeer(
            "embree", "not available: the sheet would need more than 2^28 triangles");
    }

    tbb::task_arena arena(threads);
    Device device(threads);
    if (options.raysPerPacket > 1) {
        const RTCDeviceProperty native =
            options.raysPerPacket == 16  ? RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED
            : options.raysPerPacket == 8 ? RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED
                                         : RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED;
        if (rtcGetDeviceProperty(device.get(), native) == 0)
            return detail::unavailablePeer(
                "embree", "not available: this Embree build has no native " +
                              std::to_string(options.raysPerPacket) + "-wide packets");
    }
    // Released before the device (declared after it).
    const std::unique_ptr<std::remove_pointer_t<RTCScene>, void (*)(RTCScene)> embreeScene(
        rtcNewScene(device.get()), &rtcReleaseScene);
    rtcSetSceneBuildQuality(embreeScene.get(),
                            options.highQualityBvh ? RTC_BUILD_QUALITY_HIGH
                                                   : RTC_BUILD_QUALITY_MEDIUM);
    const std::size_t verticesPerRing = std::size_t(around) * std::size_t(tube);
    arena.execute([&] {
        if (options.quads) {
            buildScene(device, embreeScene.get(), sheet, tileRings, quadsOf(tileRings.triangles),
                       verticesPerRing, footprint);
        } else {
            buildScene(device, embreeScene.get(), sheet, tileRings, tileRings.triangles,
                       verticesPerRing, footprint);
        }
    });
    device.check("building the scene");
    result.setupSeconds = secondsSince(setupStart);
    result.memoryBytes = device.allocatedBytes();

    const PinholeProjection projection(scene.camera, width, height);
    std::vector<double> traceSeconds;
    for (int run = 0; run < options.traceRuns; ++run) {
        if (options.beforeEachTrace) options.beforeEachTrace();
        result.depth = Image(width, height);
        result.normal = Image(width, height);
        const auto traceStart = std::chrono::steady_clock::now();
        arena.execute([&] {
            switch (options.raysPerPacket) {
                case 4:
                    tracePackets<4>(embreeScene.get(), sheet, projection, result);
                    break;
                case 8:
                    tracePackets<8>(embreeScene.get(), sheet, projection, result);
                    break;
                case 16:
                    tracePackets<16>(embreeScene.get(), sheet, projection, result);
                    break;
                default:
                    traceSingleRays(embreeScene.get(), sheet, projection, result);
            }
        });
        traceSeconds.push_back(secondsSince(traceStart));
    }
    device.check("tracing");
    result.traceSeconds = *std::min_element(traceSeconds.begin(), traceSeconds.end());
    return result;
}

#endif

}  // namespace distile
