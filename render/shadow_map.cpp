#include "render/shadow_map.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <limits>
#include <string>

#include "common/error.h"

namespace distile {

namespace {

constexpr float kTwoPi = 6.28318530717959f;
constexpr int kStrata = 8;  ///< the disk's 8 x 8 grid: 8 angular by 8 radial strata

/// Largest blocker-search radius, in map texels: bounds the work and the blur of one lookup.
constexpr float kMaxSearchTexels = 32.0f;
/// Receivers seen this close to edge-on by the light (cosine) use this cosine for their plane's
/// slope, so the depth reference stays finite at the terminator.
constexpr float kMinFacing = 0.1f;
/// A concave receiver rises toward the light by r^2 / (2 R) at distance r from the shaded point;
/// allowing 0.1 r keeps receivers of radius R >= 5 r clear of their own shadow. Real blockers sit
/// at the receiver-blocker distance d = r / tan(angle / 2) >> 0.1 r, far beyond this slack.
constexpr float kCurvatureSlack = 0.1f;

/// A 32-bit integer hash with good avalanche (the "lowbias32" constants of C. Wellons).
std::uint32_t mixBits(std::uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

/// The top 24 bits of `bits` as a float in [0, 1).
float unitFloat(std::uint32_t bits) {
    return float(bits >> 8) * (1.0f / 16777216.0f);
}

/// Offset in the unit disk of the sample in angular stratum `angular` and radial stratum
/// `radial` (0 at the centre, 7 the outer ring): jittered inside its cell of the 8 x 8 grid by
/// `seed`, then warped to the disk with angle 2 pi u and radius sqrt(v), which keeps the cells'
/// areas equal; `rotation` (radians) turns the whole pattern.
glm::vec2 diskOffset(int angular, int radial, std::uint32_t seed, float rotation) {
    const std::uint32_t bits =
        mixBits(seed ^ mixBits(std::uint32_t(radial * kStrata + angular) + 0x9e3779b9U));
    const float u = (float(angular) + unitFloat(bits)) / float(kStrata);
    const float v = (float(radial) + unitFloat(mixBits(bits))) / float(kStrata);
    const float angle = kTwoPi * u + rotation;
    const float radius = std::sqrt(v);
    return {radius * std::cos(angle), radius * std::sin(angle)};
}

}  // namespace

ShadowMap::ShadowMap(const SceneTracer& tracer, const DirectionalLight& light,
                     int resolutionTexels) {
    if (resolutionTexels < 16 || resolutionTexels > 16384) {
        throw InputError::inField("resolutionTexels", std::to_string(resolutionTexels) +
                                                          " is not accepted; it must be in [16, "
                                                          "16384] texels");
    }
    const Scene& scene = tracer.scene();
    toLight_ = -glm::normalize(light.direction);
    const glm::vec3 helper = std::abs(toLight_.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
    axisX_ = glm::normalize(glm::cross(helper, toLight_));
    axisY_ = glm::cross(toLight_, axisX_);
    tanHalfAngle_ = std::tan(0.5f * glm::radians(light.angleDeg));

    // World bounds of the base meshes, grown by the deepest shell (detail lies below the surface).
    glm::vec3 low(std::numeric_limits<float>::max());
    glm::vec3 high(-std::numeric_limits<float>::max());
    float shellDepth = 0.0f;
    for (const SceneObject& object : scene.objects) {
        for (const glm::vec3& position : object.mesh.positions) {
            low = glm::min(low, position);
            high = glm::max(high, position);
        }
        if (object.material.tile) shellDepth = std::max(shellDepth, object.material.depthWorld);
    }
    low -= glm::vec3(shellDepth);
    high += glm::vec3(shellDepth);

    // The bounds' corners in light coordinates: (across x, across y) and depth along the light.
    glm::vec2 planeLow(std::numeric_limits<float>::max()),
        planeHigh(-std::numeric_limits<float>::max());
    float depthLow = std::numeric_limits<float>::max();
    for (int corner = 0; corner < 8; ++corner) {
        const glm::vec3 p(corner & 1 ? high.x : low.x, corner & 2 ? high.y : low.y,
                          corner & 4 ? high.z : low.z);
        const glm::vec2 plane(glm::dot(p, axisX_), glm::dot(p, axisY_));
        planeLow = glm::min(planeLow, plane);
        planeHigh = glm::max(planeHigh, plane);
        depthLow = std::min(depthLow, -glm::dot(p, toLight_));
    }
    const glm::vec2 extent = planeHigh - planeLow;
    const float longer = std::max({extent.x, extent.y, 1e-6f});
    texelWorld_ = longer / float(resolutionTexels);
    width_ = std::clamp(int(std::ceil(extent.x / texelWorld_)), 1, resolutionTexels);
    height_ = std::clamp(int(std::ceil(extent.y / texelWorld_)), 1, resolutionTexels);
    originPlane_ = planeLow;
    // Rays start a little in front of everything.
    const float startDepth = depthLow - std::max(texelWorld_, 1e-3f * longer);

    depths_.assign(std::size_t(width_) * std::size_t(height_),
                   std::numeric_limits<float>::infinity());
    tbb::parallel_for(tbb::blocked_range<int>(0, height_, 8), [&](const tbb::blocked_range<int>&
                                                                      rows) {
        TraceCounters counters;
        constexpr int kBatch = int(SceneTracer::kMaxBatchRays);
        Ray rays[kBatch];
        SurfaceHit hits[kBatch];
        bool found[kBatch];
        for (int y = rows.begin(); y != rows.end(); ++y) {
            // Runs of a row traced together: their marches interleave (SceneTracer).
            for (int x0 = 0; x0 < width_; x0 += kBatch) {
                const int count = std::min(kBatch, width_ - x0);
                const float along = originPlane_.y + (float(y) + 0.5f) * texelWorld_;
                for (int k = 0; k < count; ++k) {
                    const float across = originPlane_.x + (float(x0 + k) + 0.5f) * texelWorld_;
                    rays[k] = {axisX_ * across + axisY_ * along - toLight_ * startDepth, -toLight_};
                }
                // Only where the rays stop matters here: no detail normals.
                tracer.traceNearestBatch(std::span(rays, std::size_t(count)), 0.0f,
                                         std::span(hits, std::size_t(count)),
                                         std::span(found, std::size_t(count)), counters,
                                         /*withNormals=*/false);
                for (int k = 0; k < count; ++k) {
                    if (!found[k]) continue;
                    depths_[std::size_t(x0 + k) + std::size_t(width_) * std::size_t(y)] =
                        startDepth + hits[k].distanceWorld;
                }
            }
        }
    });
    nearestDepth_ = *std::min_element(depths_.begin(), depths_.end());
}

float ShadowMap::lookup(const glm::vec2& planeWorld) const {
    const float x = std::floor((planeWorld.x - originPlane_.x) / texelWorld_);
    const float y = std::floor((planeWorld.y - originPlane_.y) / texelWorld_);
    if (!(x >= 0.0f && y >= 0.0f && x < float(width_) && y < float(height_))) {
        return std::numeric_limits<float>::infinity();
    }
    return depthAt(int(x), int(y));
}

float ShadowMap::visibility(const ShadowReceiver& receiver, ShadowFilter filter, std::uint32_t seed,
                            std::uint64_t& samples) const {
    // Ch. 17: a surface facing away from the light is in its own shadow; no samples at all.
    const float facing = glm::dot(receiver.normal, toLight_);
    if (!(facing > 0.0f)) return 0.0f;

    const glm::vec2 centre(glm::dot(receiver.surfaceWorld, axisX_),
                           glm::dot(receiver.surfaceWorld, axisY_));
    const float receiverDepth = -glm::dot(receiver.surfaceWorld, toLight_);
    // The receiver's tangent plane, as depth along the light per unit of light-plane offset.
    const glm::vec2 slope =
        glm::vec2(glm::dot(receiver.normal, axisX_), glm::dot(receiver.normal, axisY_)) /
        std::max(facing, kMinFacing);
    // A nearest-texel lookup lands up to 0.71 texel from the asked point; on the slope that is
    // 0.71 texel * |slope| of depth. One texel (plus one of slope) covers it with margin.
    const float quantisationBias = texelWorld_ * (1.0f + glm::length(slope));
    // Depth of the blocker at `offset` from the receiver, or +infinity if nothing there blocks.
    auto blocker = [&](const glm::vec2& offset) {
        const float stored = lookup(centre + offset);
        const float reference = receiverDepth + glm::dot(slope, offset);
        const float bias = quantisationBias + kCurvatureSlack * glm::length(offset);
        return stored < reference - bias ? stored : std::numeric_limits<float>::infinity();
    };

    // The widest penumbra possible here: the nearest blocker anywhere in the map.
    const float searchRadius =
        std::min(tanHalfAngle_ * std::max(receiverDepth - nearestDepth_, 0.0f),
                 kMaxSearchTexels * texelWorld_);
    if (searchRadius < 0.5f * texelWorld_) {  // a disk inside one texel: a hard shadow, one sample
        ++samples;
        return std::isinf(blocker(glm::vec2(0.0f))) ? 1.0f : 0.0f;
    }

    const std::uint32_t pixelSeed = mixBits(seed);
    const float rotation = kTwoPi * unitFloat(mixBits(pixelSeed ^ 0x68bc21ebU));
    // The outer ring: penumbra test and blocker search in one.
    int blocked = 0;
    float blockerDepthSum = 0.0f;
    for (int angular = 0; angular < kStrata; ++angular) {
        const float depth =
            blocker(diskOffset(angular, kStrata - 1, pixelSeed, rotation) * searchRadius);
        if (!std::isinf(depth)) {
            ++blocked;
            blockerDepthSum += depth;
        }
    }
    samples += kShadowRingSamples;
    if (filter == ShadowFilter::Adaptive && (blocked == 0 || blocked == kShadowRingSamples)) {
        return blocked == 0 ? 1.0f : 0.0f;
    }

    // Penumbra radius from the light's angle and the mean receiver-blocker distance.
    const float filterRadius =
        blocked == 0
            ? searchRadius
            : std::clamp(tanHalfAngle_ * (receiverDepth - blockerDepthSum / float(blocked)), 0.0f,
                         searchRadius);
    int lit = 0;
    for (int radial = 0; radial < kStrata; ++radial) {
        for (int angular = 0; angular < kStrata; ++angular) {
            lit +=
                std::isinf(blocker(diskOffset(angular, radial, pixelSeed, rotation) * filterRadius))
                    ? 1
                    : 0;
        }
    }
    samples += kShadowDiskSamples;
    return float(lit) / float(kShadowDiskSamples);
}

bool lightReachesVisibleSurface(const Scene& scene, const DirectionalLight& light) {
    const glm::vec3 toLight = -glm::normalize(light.direction);
    for (const SceneObject& object : scene.objects) {
        const BaseMesh& mesh = object.mesh;
        for (const glm::uvec3& triangle : mesh.triangles) {
            const glm::vec3& p0 = mesh.positions[triangle[0]];
            const glm::vec3 geometricNormal =
                glm::cross(mesh.positions[triangle[1]] - p0, mesh.positions[triangle[2]] - p0);
            if (glm::dot(geometricNormal, scene.camera.eye - p0) <= 0.0f) continue;
            for (int corner = 0; corner < 3; ++corner) {
                if (glm::dot(mesh.normals[triangle[corner]], toLight) > 0.0f) return true;
            }
        }
    }
    return false;
}

bool sceneCastsShadowsBetweenSurfaces(const Scene& scene) {
    if (scene.objects.size() != 1) return true;
    const BaseMesh& mesh = scene.objects[0].mesh;
    if (mesh.positions.empty() || mesh.normals.size() != mesh.positions.size()) return true;
    const glm::vec3 normal = mesh.normals[0];
    glm::vec3 lower = mesh.positions[0], upper = mesh.positions[0];
    for (const glm::vec3& position : mesh.positions) {
        lower = glm::min(lower, position);
        upper = glm::max(upper, position);
    }
    const float tolerance = 1e-5f * glm::length(upper - lower);
    for (std::size_t vertex = 0; vertex < mesh.positions.size(); ++vertex) {
        if (glm::dot(mesh.normals[vertex], normal) < 1.0f - 1e-6f) return true;
        if (std::abs(glm::dot(mesh.positions[vertex] - mesh.positions[0], normal)) > tolerance)
            return true;
    }
    return false;
}

}  // namespace distile
