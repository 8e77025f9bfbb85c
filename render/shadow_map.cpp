#include "render/shadow_map.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <glm/vec4.hpp>
#include <limits>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "common/error.h"
#include "render/coverage.h"
#include "render/detail/disk_pattern.h"

namespace distile {

namespace {

constexpr float kTwoPi = 6.28318530717959f;
using detail::DiskPattern;
using detail::mixBits;
using detail::unitFloat;
constexpr int kStrata = DiskPattern::kStrata;

/// Largest blocker-search radius, in base-level texels: bounds the work and the blur of a lookup.
constexpr float kMaxSearchTexels = 32.0f;
/// Receivers seen this close to edge-on by the light (cosine) use this cosine for their plane's
/// slope, so the depth reference stays finite at the terminator.
constexpr float kMinFacing = 0.1f;
/// A concave receiver rises toward the light by r^2 / (2 R) at distance r from the shaded point;
/// allowing 0.1 r keeps receivers of radius R >= 5 r clear of their own shadow. Real blockers sit
/// at the receiver-blocker distance d = r / tan(angle / 2) >> 0.1 r, far beyond this slack.
constexpr float kCurvatureSlack = 0.1f;
/// The line test's step along a line of the disk: this share of the offset (at least a texel of
/// the level read, whose texels are this share of the offset too).
constexpr float kLineStepShare = 0.35f;
/// The same where a ray may meet a blocker's edge (ShadowMap::blockedOnLine). At 0.35 everywhere
/// rays that cross a floating square near its edge came out under it: 0.22 of a disk lit against
/// 0.07 (render_test's exact shares).
constexpr float kEdgeStepShare = 0.1f;
/// The depth the line test takes for the rim of an object the light meets between `front` and
/// `back`: half way, where a ball's rim lies (a thin slab's is both).
float rimDepth(float front, float back) {
    return 0.5f * (front + back);
}

/// The depths of the line test's 8 rays of one line at one offset along it, and bit masks of
/// them (bit r for ray r): with SSE2 four rays at a time, the same floats as one at a time.
class LineRayDepths {
  public:
    static constexpr int kRays = 8;
    /// receiverDepth - offset x rises[r].
    LineRayDepths(float receiverDepth, float offset, const std::array<float, kRays>& rises) {
#if defined(__SSE2__)
        for (int half = 0; half < 2; ++half)
            depths_[half] =
                _mm_sub_ps(_mm_set1_ps(receiverDepth),
                           _mm_mul_ps(_mm_set1_ps(offset), _mm_loadu_ps(&rises[4 * half])));
#else
        for (int ray = 0; ray < kRays; ++ray) depths_[ray] = receiverDepth - offset * rises[ray];
#endif
    }
    /// The rays nearer to the light than `depth`.
    unsigned nearer(float depth) const {
#if defined(__SSE2__)
        return mask([&](__m128 rays) { return _mm_cmplt_ps(rays, _mm_set1_ps(depth)); });
#else
        return mask([&](float ray) { return ray < depth; });
#endif
    }
    /// The rays farther from the light than `depth`.
    unsigned farther(float depth) const {
#if defined(__SSE2__)
        return mask([&](__m128 rays) { return _mm_cmpgt_ps(rays, _mm_set1_ps(depth)); });
#else
        return mask([&](float ray) { return ray > depth; });
#endif
    }
    /// The rays that rose past `rim` (are nearer to the light than it here) in the first half of
    /// the step from `before`: 2 (before - rim) < before - here.
    unsigned rosePast(float rim, const LineRayDepths& before) const {
#if defined(__SSE2__)
        int half = 0;
        return mask([&](__m128 rays) {
            const __m128 was = before.depths_[half++];
            const __m128 rimDepth = _mm_set1_ps(rim);
            return _mm_and_ps(_mm_cmplt_ps(rays, rimDepth),
                              _mm_cmplt_ps(_mm_mul_ps(_mm_set1_ps(2.0f), _mm_sub_ps(was, rimDepth)),
                                           _mm_sub_ps(was, rays)));
        });
#else
        int ray = 0;
        return mask([&](float here) {
            const float was = before.depths_[ray++];
            return here < rim && 2.0f * (was - rim) < was - here;
        });
#endif
    }

  private:
#if defined(__SSE2__)
    template <class Compare>
    unsigned mask(Compare&& compare) const {
        const unsigned low = unsigned(_mm_movemask_ps(compare(depths_[0])));
        return low | unsigned(_mm_movemask_ps(compare(depths_[1]))) << 4;
    }
    __m128 depths_[2];
#else
    template <class Compare>
    unsigned mask(Compare&& compare) const {
        unsigned bits = 0;
        for (int ray = 0; ray < kRays; ++ray) bits |= unsigned(compare(depths_[ray])) << ray;
        return bits;
    }
    float depths_[kRays];
#endif
};

/// A rectangle of the light's plane (light coordinates along axisX and axisY) and the depths
/// along the light of the surfaces over it.
struct LightPlaneRegion {
    glm::vec2 low{std::numeric_limits<float>::max()}, high{-std::numeric_limits<float>::max()};
    float depthLow = std::numeric_limits<float>::max();
    float depthHigh = -std::numeric_limits<float>::max();

    bool empty() const { return !(low.x <= high.x && low.y <= high.y); }
    /// The longer side of the rectangle (at least 1e-6).
    float side() const { return std::max({high.x - low.x, high.y - low.y, 1e-6f}); }
    void add(const LightPlaneRegion& other) {
        low = glm::min(low, other.low);
        high = glm::max(high, other.high);
        depthLow = std::min(depthLow, other.depthLow);
        depthHigh = std::max(depthHigh, other.depthHigh);
    }
    LightPlaneRegion intersection(const LightPlaneRegion& other) const {
        LightPlaneRegion both;
        both.low = glm::max(low, other.low);
        both.high = glm::min(high, other.high);
        return both;
    }
    /// The distance between the two rectangles (0 where they overlap).
    float gapTo(const LightPlaneRegion& other) const {
        return glm::length(glm::max(glm::max(other.low - high, low - other.high), glm::vec2(0.0f)));
    }
};

/// A map over a region of the scene spans at least 1 / kMaxMapOverRegion of its resolution.
constexpr float kMaxMapOverRegion = 4.0f;
/// Groups of receivers this close, as a share of the wider one's side, share a map: a lookup
/// near a map's edge reads texels up to a coarse texel beyond it (kLevels, kMaxMapOverRegion).
constexpr float kGroupMarginShare = 0.05f;
/// Scenes whose shadowable region has more parts than this take one map over all of them (the
/// grouping compares every part with every group).
constexpr std::size_t kMaxGroupedParts = 2048;
/// Groups beyond this many are merged into one before the pairwise merging, which compares every
/// pair at each step.
constexpr std::size_t kMaxMergedGroups = 64;

/// Light-plane axes of the light toward `toLight` (unit): across and along its maps.
std::pair<glm::vec3, glm::vec3> lightPlaneAxes(const glm::vec3& toLight) {
    const glm::vec3 helper = std::abs(toLight.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
    const glm::vec3 axisX = glm::normalize(glm::cross(helper, toLight));
    return {axisX, glm::cross(toLight, axisX)};
}

}  // namespace

/// The areas of the light's maps: one per group of receivers that can be shadowed, their
/// footprints as the light sees them (base meshes grown by the deepest shell, detail lying
/// below the surface). A flat slab (isFlatSlab) is a receiver's blocker only over the footprints
/// of the other objects reaching behind its lit side: it shadows nothing in front of it, nor
/// itself in the map (its own detail shadows itself by rays). Parts whose rectangles come closer
/// than twice the widest penumbra between them (the light's tan(angle / 2) times their depths'
/// span, down to the deepest surface under them) plus kGroupMarginShare of their side form one
/// group: no blocker of one group can shadow a receiver that takes another's map, so each has a
/// map of its own, at most kMaxShadowMapsPerLight of them (far groups merged first). A map spans
/// the whole scene's box, as one map over the scene did, unless that is more than kMaxMapOverRegion
/// times as wide as its group: there, the group, spanning kMaxMapOverRegion times its side. So a
/// ground plane far wider than the objects on it, or two groups of objects far apart, do not spread
/// the map's texels over all of it (a 2e5-unit plane held a sphere of radius 0.8 in less than a
/// texel: no shadow).
std::vector<ShadowMapArea> shadowMapAreas(const Scene& scene, const DirectionalLight& light,
                                          const PinholeProjection* view) {
    const glm::vec3 toLight = -unitDirection(light.direction);
    glm::vec3 axisX, axisY;  // not a structured binding: lambdas below capture them
    std::tie(axisX, axisY) = lightPlaneAxes(toLight);
    const float tanHalfAngle = std::tan(0.5f * glm::radians(light.angleDeg));
    float shellDepth = 0.0f;
    for (const SceneObject& object : scene.objects)
        if (object.material.tile) shellDepth = std::max(shellDepth, object.material.depthWorld);
    // Corner `index` (bits x, y, z) of the box [low, high].
    const auto boxCorner = [](const glm::vec3& low, const glm::vec3& high, int index) {
        return glm::vec3(index & 1 ? high.x : low.x, index & 2 ? high.y : low.y,
                         index & 4 ? high.z : low.z);
    };
    // The light's view of the box [low, high]: its corners' light coordinates and depths.
    const auto footprintOf = [&](const glm::vec3& low, const glm::vec3& high) {
        LightPlaneRegion footprint;
        for (int corner = 0; corner < 8; ++corner) {
            const glm::vec3 p = boxCorner(low, high, corner);
            const glm::vec2 plane(glm::dot(p, axisX), glm::dot(p, axisY));
            footprint.low = glm::min(footprint.low, plane);
            footprint.high = glm::max(footprint.high, plane);
            footprint.depthLow = std::min(footprint.depthLow, -glm::dot(p, toLight));
            footprint.depthHigh = std::max(footprint.depthHigh, -glm::dot(p, toLight));
        }
        return footprint;
    };
    const std::size_t count = scene.objects.size();
    // Per object: its base mesh's box grown by the deepest shell, and that box's footprint.
    std::vector<glm::vec3> lows(count, glm::vec3(std::numeric_limits<float>::max()));
    std::vector<glm::vec3> highs(count, glm::vec3(-std::numeric_limits<float>::max()));
    std::vector<LightPlaneRegion> footprints(count);
    std::vector<bool> flat(count);
    // Per flat slab: how fast its planes' depth along the light grows per unit of light-plane
    // offset, at most (the L1 norm of the gradient; infinity where the light grazes it).
    std::vector<float> slabSlopes(count, 0.0f);
    for (std::size_t object = 0; object < count; ++object) {
        for (const glm::vec3& position : scene.objects[object].mesh.positions) {
            lows[object] = glm::min(lows[object], position);
            highs[object] = glm::max(highs[object], position);
        }
        lows[object] -= glm::vec3(shellDepth);
        highs[object] += glm::vec3(shellDepth);
        footprints[object] = footprintOf(lows[object], highs[object]);
        flat[object] = isFlatSlab(scene.objects[object]);
        if (flat[object]) {
            const glm::vec3 normal = scene.objects[object].mesh.normals[0];
            slabSlopes[object] =
                (std::abs(glm::dot(axisX, normal)) + std::abs(glm::dot(axisY, normal))) /
                std::abs(glm::dot(toLight, normal));
        }
    }
    // Whether `object` has a corner of its footprint's box behind slab `slab`'s side that faces
    // the light (its top, or its floor when the light comes from below).
    const auto behindSlab = [&](std::size_t object, std::size_t slab) {
        const BaseMesh& mesh = scene.objects[slab].mesh;
        glm::vec3 facing = mesh.normals[0];
        glm::vec3 origin = mesh.positions[0];
        if (glm::dot(facing, toLight) < 0.0f) {
            origin -= facing * scene.objects[slab].material.depthWorld;
            facing = -facing;
        }
        for (int corner = 0; corner < 8; ++corner) {
            if (glm::dot(boxCorner(lows[object], highs[object], corner) - origin, facing) < 0.0f)
                return true;
        }
        return false;
    };
    // The least and greatest depths of object `object` over the corners of `over`: a flat slab's
    // from its top and floor planes (a slab much wider than the region would put the rays' start,
    // and so the rounding of the depths they store, as far away as its own far corners), within
    // its footprint's (where the light grazes it); any other object's, its footprint's.
    const auto depthsOver = [&](std::size_t object, const LightPlaneRegion& over) {
        const LightPlaneRegion& footprint = footprints[object];
        if (!flat[object]) return std::pair(footprint.depthLow, footprint.depthHigh);
        const BaseMesh& mesh = scene.objects[object].mesh;
        const glm::vec3 normal = mesh.normals[0];
        const float facing = glm::dot(toLight, normal);
        if (!(std::abs(facing) > 1e-3f)) return std::pair(footprint.depthLow, footprint.depthHigh);
        float least = std::numeric_limits<float>::max();
        float greatest = -std::numeric_limits<float>::max();
        for (const float offset : {0.0f, shellDepth}) {
            const float planeOffset = glm::dot(mesh.positions[0] - normal * offset, normal);
            for (int corner = 0; corner < 4; ++corner) {
                const glm::vec2 q(corner & 1 ? over.high.x : over.low.x,
                                  corner & 2 ? over.high.y : over.low.y);
                // The point q.x axisX + q.y axisY - depth toLight on the plane.
                const float depth =
                    (q.x * glm::dot(axisX, normal) + q.y * glm::dot(axisY, normal) - planeOffset) /
                    facing;
                least = std::min(least, depth);
                greatest = std::max(greatest, depth);
            }
        }
        return std::pair(std::max(least, footprint.depthLow),
                         std::min(greatest, footprint.depthHigh));
    };
    // The whole scene's box (not the union of the objects' footprints, which can be smaller).
    glm::vec3 low(std::numeric_limits<float>::max());
    glm::vec3 high(-std::numeric_limits<float>::max());
    for (std::size_t object = 0; object < count; ++object) {
        low = glm::min(low, lows[object]);
        high = glm::max(high, highs[object]);
    }
    const LightPlaneRegion all = footprintOf(low, high);
    // The parts of the region a receiver can be shadowed in.
    std::vector<LightPlaneRegion> parts;
    for (std::size_t object = 0; object < count; ++object) {
        if (!flat[object]) {
            parts.push_back(footprints[object]);
            continue;
        }
        for (std::size_t other = 0; other < count; ++other) {
            if (other == object || !behindSlab(other, object)) continue;
            LightPlaneRegion over = footprints[object].intersection(footprints[other]);
            if (over.empty()) continue;
            const auto [slabLow, slabHigh] = depthsOver(object, over);
            over.depthLow = slabLow;
            over.depthHigh = std::max(slabHigh, depthsOver(other, over).second);
            parts.push_back(over);
        }
    }
    if (parts.size() > kMaxGroupedParts) {
        LightPlaneRegion merged;
        for (const LightPlaneRegion& part : parts) merged.add(part);
        parts.assign(1, merged);
    }
    // A part's receivers lie, as the light sees them, in the penumbrae of its blockers: at a
    // light-plane distance x from its rectangle, a receiver is at least x / tan(angle / 2) deeper
    // than the part's surface nearest to the light. Its depths reach down to the deepest surface
    // of any object with such a receiver. An object's footprint box qualifies when its gap to the
    // part is within the penumbra of its deepest corner. A flat slab's planes deepen linearly
    // away from the part (by slabSlopes per unit of x at most), so where the light does not graze
    // it, the x it qualifies out to is bounded in closed form. (Bounding every object by the
    // scene's deepest point instead let a wide ground plane, seen obliquely, join every part into
    // one group, with a map too coarse for any of them.)
    for (LightPlaneRegion& part : parts) {
        float depthHigh = part.depthHigh;
        for (std::size_t object = 0; object < count; ++object) {
            const LightPlaneRegion& footprint = footprints[object];
            if (!flat[object]) {
                const float reach = tanHalfAngle * (footprint.depthHigh - part.depthLow);
                if (part.gapTo(footprint) <= reach)
                    depthHigh = std::max(depthHigh, footprint.depthHigh);
                continue;
            }
            const float below = std::max(depthsOver(object, part).second - part.depthLow, 0.0f);
            const float grazing = 1.0f - tanHalfAngle * slabSlopes[object];
            float reach = tanHalfAngle * std::max(footprint.depthHigh - part.depthLow, 0.0f);
            if (grazing > 0.0f) reach = std::min(reach, tanHalfAngle * below / grazing);
            LightPlaneRegion reached = part;
            reached.low -= reach;
            reached.high += reach;
            const LightPlaneRegion over = reached.intersection(footprint);
            if (!over.empty()) depthHigh = std::max(depthHigh, depthsOver(object, over).second);
        }
        part.depthHigh = depthHigh;
    }
    // The parts none of whose receivers a camera ray meets.
    if (view) {
        std::erase_if(parts, [&](const LightPlaneRegion& part) {
            const float reach = tanHalfAngle * std::max(part.depthHigh - part.depthLow, 0.0f);
            glm::vec3 corners[8];
            for (int corner = 0; corner < 8; ++corner) {
                const float across = corner & 1 ? part.high.x + reach : part.low.x - reach;
                const float along = corner & 2 ? part.high.y + reach : part.low.y - reach;
                const float depth = corner & 4 ? part.depthHigh : part.depthLow;
                corners[corner] = axisX * across + axisY * along - toLight * depth;
            }
            return view->seesNoneOf(corners);
        });
    }
    // Groups: each absorbs every group near it, again after each merge (a larger group may reach
    // more), so no two groups left are near. Two are near where a receiver may lie in the
    // penumbra of one (within tan(angle / 2) times their span of depths of it) and as near to
    // the other, whose map it would take: a gap up to twice that.
    const auto near = [&](const LightPlaneRegion& a, const LightPlaneRegion& b) {
        const float depthSpan =
            std::max(a.depthHigh, b.depthHigh) - std::min(a.depthLow, b.depthLow);
        return a.gapTo(b) <= 2.0f * tanHalfAngle * std::max(depthSpan, 0.0f) +
                                 kGroupMarginShare * std::max(a.side(), b.side());
    };
    std::vector<LightPlaneRegion> groups;
    const auto addGroup = [&](LightPlaneRegion group) {
        for (std::size_t index = 0; index < groups.size();) {
            if (!near(group, groups[index])) {
                ++index;
                continue;
            }
            group.add(groups[index]);
            groups.erase(groups.begin() + std::ptrdiff_t(index));
            index = 0;
        }
        groups.push_back(group);
    };
    for (const LightPlaneRegion& part : parts) addGroup(part);
    // The distance from the eye to a group's box (1 without a view): the width of the camera's
    // pixels there, and so of the texels its receivers need, grows with it.
    const glm::vec3 eye = view ? view->eye() : glm::vec3(0.0f);
    const glm::vec3 eyeLight(glm::dot(eye, axisX), glm::dot(eye, axisY), -glm::dot(eye, toLight));
    const auto viewDistance = [&](const LightPlaneRegion& group) {
        if (!view) return 1.0f;
        const glm::vec3 boxLow(group.low, group.depthLow), boxHigh(group.high, group.depthHigh);
        return std::max(glm::length(eyeLight - glm::clamp(eyeLight, boxLow, boxHigh)),
                        1e-3f * group.side());
    };
    // More groups than the pairwise merging takes in good time: the nearest to the eye keep
    // theirs, the others merge into one.
    if (groups.size() > kMaxMergedGroups) {
        std::vector<std::pair<float, std::size_t>> byDistance;
        for (std::size_t index = 0; index < groups.size(); ++index)
            byDistance.emplace_back(viewDistance(groups[index]), index);
        std::sort(byDistance.begin(), byDistance.end());
        std::vector<LightPlaneRegion> nearest;
        LightPlaneRegion others;
        for (std::size_t rank = 0; rank < byDistance.size(); ++rank) {
            const LightPlaneRegion& group = groups[byDistance[rank].second];
            if (rank + 1 < kMaxMergedGroups)
                nearest.push_back(group);
            else
                others.add(group);
        }
        groups = std::move(nearest);
        addGroup(others);
    }
    // Too many groups: merge the pair whose union is smallest beside the distance to the nearer
    // of the two, so the groups far from the eye share maps first (without a view, the pair whose
    // union is smallest).
    while (groups.size() > std::size_t(kMaxShadowMapsPerLight)) {
        std::vector<float> distances;
        for (const LightPlaneRegion& group : groups) distances.push_back(viewDistance(group));
        std::size_t first = 0, second = 1;
        float cheapest = std::numeric_limits<float>::max();
        for (std::size_t a = 0; a < groups.size(); ++a)
            for (std::size_t b = a + 1; b < groups.size(); ++b) {
                LightPlaneRegion both = groups[a];
                both.add(groups[b]);
                const float cost = both.side() / std::min(distances[a], distances[b]);
                if (cost < cheapest) {
                    cheapest = cost;
                    first = a;
                    second = b;
                }
            }
        LightPlaneRegion both = groups[first];
        both.add(groups[second]);
        groups.erase(groups.begin() + std::ptrdiff_t(second));
        groups.erase(groups.begin() + std::ptrdiff_t(first));
        addGroup(both);
    }
    // The area over `covered` spanning `side`, serving the receivers over `receivers`, the
    // nearest of them `distance` from the eye (unused without a view).
    const auto areaOf = [&](const LightPlaneRegion& covered, float side,
                            const LightPlaneRegion& receivers, float distance) {
        ShadowMapArea area{covered.low,
                           covered.high,
                           covered.depthLow,
                           side,
                           receivers.low,
                           receivers.high,
                           view ? distance * view->pixelAngleRadians() : 0.0f,
                           0.0f,
                           {}};
        LightPlaneRegion nearby = covered;
        nearby.low -= side;
        nearby.high += side;
        for (std::size_t object = 0; object < count; ++object) {
            const LightPlaneRegion& footprint = footprints[object];
            area.objectsNear.push_back(!nearby.intersection(footprint).empty());
            if (flat[object] || receivers.intersection(footprint).empty()) continue;
            const glm::vec2 extent = footprint.high - footprint.low;
            const float width = std::min(extent.x, extent.y);
            if (area.blockerWorld == 0.0f || width < area.blockerWorld) area.blockerWorld = width;
        }
        return area;
    };
    if (groups.empty()) return {areaOf(all, all.side(), all, 0.0f)};
    // Texels for the whole scene while they are at most kMaxMapOverRegion times as large as the
    // group's would be (so the maps of most scenes are what they were before the groups), else
    // the group. The groups that take the whole scene share one map, after the others: a receiver
    // in one of those others' rectangles takes its finer map (LightShadowMaps::mapFor).
    std::vector<ShadowMapArea> areas;
    LightPlaneRegion wholeSceneReceivers;
    float wholeSceneDistance = std::numeric_limits<float>::max();
    for (const LightPlaneRegion& group : groups) {
        if (all.side() <= kMaxMapOverRegion * group.side()) {
            wholeSceneReceivers.add(group);
            wholeSceneDistance = std::min(wholeSceneDistance, viewDistance(group));
        } else {
            areas.push_back(
                areaOf(group, kMaxMapOverRegion * group.side(), group, viewDistance(group)));
        }
    }
    if (!wholeSceneReceivers.empty())
        areas.push_back(areaOf(all, all.side(), wholeSceneReceivers, wholeSceneDistance));
    return areas;
}

ShadowMap::ShadowMap(const SceneTracer& tracer, const DirectionalLight& light, int resolutionTexels,
                     const ShadowMapArea& area)
    : tracer_(tracer) {
    if (resolutionTexels < 16 || resolutionTexels > kMaxResolution) {
        throw InputError::inField("resolutionTexels", std::to_string(resolutionTexels) +
                                                          " is not accepted; it must be in [16, "
                                                          "16384] texels");
    }
    toLight_ = -unitDirection(light.direction);
    std::tie(axisX_, axisY_) = lightPlaneAxes(toLight_);
    tanHalfAngle_ = std::tan(0.5f * glm::radians(light.angleDeg));
    lineTest_ = light.angleDeg >= kLineTestMinAngleDeg;
    receiversLow_ = area.receiversLowPlane;
    receiversHigh_ = area.receiversHighPlane;
    objectsNear_ = area.objectsNear;

    const glm::vec2 planeLow = area.lowPlane, planeHigh = area.highPlane;
    const float depthLow = area.depthLowWorld;
    const glm::vec2 extent = planeHigh - planeLow;
    const float longer = area.sideWorld;
    originPlane_ = planeLow;
    // Finer levels below the base while its texels are wider than the nearest receivers' pixels
    // allow (kMaxTexelOverPixel); a lookup reads the coarsest level its receiver needs, so they
    // are traced only near the eye. For the line test's wide lights, only while they are also
    // coarse beside the smallest blocker: their penumbrae, not the texels, set how sharp their
    // shadows are (on vase.json finer levels doubled the render and changed 0.7% of the pixels by
    // 0.03 codes), but a blocker a few texels wide casts none (a torus 56 units wide under a sun
    // 30 degrees wide and 11 above the horizon, whose penumbra spread over 6000 units).
    const float baseTexelWorld = longer / float(resolutionTexels);
    constexpr float kNone = std::numeric_limits<float>::infinity();
    float coarsestWanted = area.pixelWorld > 0.0f ? kMaxTexelOverPixel * area.pixelWorld : kNone;
    if (lineTest_)
        coarsestWanted = area.blockerWorld > 0.0f
                             ? std::max(coarsestWanted, area.blockerWorld / kMinTexelsPerBlocker)
                             : kNone;
    int finer = 0;
    while (finer < kMaxFinerLevels && (resolutionTexels << (finer + 1)) <= kMaxFinerResolution &&
           baseTexelWorld / float(1 << finer) > coarsestWanted)
        ++finer;
    levels_.resize(std::size_t(finer + kLevels));
    boundLevel_ = std::size_t(finer);
    for (int index = 0; index < finer + kLevels; ++index) {
        Level& level = levels_[std::size_t(index)];
        const int resolution = std::max((resolutionTexels << finer) >> index, 1);
        // Powers of two: the base level's texels are those of a map without finer levels.
        level.texelWorld = baseTexelWorld * float(1 << index) / float(1 << finer);
        level.width = std::clamp(int(std::ceil(extent.x / level.texelWorld)), 1, resolution);
        level.height = std::clamp(int(std::ceil(extent.y / level.texelWorld)), 1, resolution);
        level.tilesX = (level.width + kTileTexels - 1) / kTileTexels;
        level.tilesY = (level.height + kTileTexels - 1) / kTileTexels;
        const std::size_t tiles = std::size_t(level.tilesX) * std::size_t(level.tilesY);
        level.depths =
            std::make_unique_for_overwrite<float[]>(tiles * std::size_t(kTileTexels * kTileTexels));
        if (lineTest_)
            level.layers = std::make_unique_for_overwrite<LineLayers[]>(
                tiles * std::size_t(kTileTexels * kTileTexels));
        level.tileOnce = std::make_unique<std::once_flag[]>(tiles);
        level.tileDone = std::make_unique<std::atomic<bool>[]>(tiles);
        for (std::size_t tile = 0; tile < tiles; ++tile) level.tileDone[tile].store(false);
    }
    // Rays start a little in front of everything.
    startDepth_ = depthLow - std::max(boundLevel().texelWorld, 1e-3f * longer);
    boundDepths();
    if (lineTest_) buildBoundLevels();
}

float ShadowMap::distanceToReceivers(const glm::vec3& world) const {
    const glm::vec2 plane(glm::dot(world, axisX_), glm::dot(world, axisY_));
    return glm::length(plane - glm::clamp(plane, receiversLow_, receiversHigh_));
}

LightShadowMaps::LightShadowMaps(const SceneTracer& tracer, const DirectionalLight& light,
                                 int resolutionTexels, const PinholeProjection* view) {
    for (const ShadowMapArea& area : shadowMapAreas(tracer.scene(), light, view))
        maps_.push_back(std::make_unique<ShadowMap>(tracer, light, resolutionTexels, area));
}

const ShadowMap& LightShadowMaps::mapFor(const glm::vec3& world) const {
    const ShadowMap* nearest = maps_.front().get();
    if (maps_.size() == 1) return *nearest;
    float least = nearest->distanceToReceivers(world);
    for (std::size_t index = 1; index < maps_.size() && least > 0.0f; ++index) {
        const float distance = maps_[index]->distanceToReceivers(world);
        if (distance < least) {
            least = distance;
            nearest = maps_[index].get();
        }
    }
    return *nearest;
}

std::uint64_t LightShadowMaps::tracedTexels() const {
    std::uint64_t texels = 0;
    for (const std::unique_ptr<ShadowMap>& map : maps_) texels += map->tracedTexels();
    return texels;
}

std::uint64_t LightShadowMaps::texelCount() const {
    std::uint64_t texels = 0;
    for (const std::unique_ptr<ShadowMap>& map : maps_) texels += map->texelCount();
    return texels;
}

void ShadowMap::boundDepths() {
    const Level& base = boundLevel();
    // A lower bound of the depths of each tile from every shell over it. A shell's points are
    // bilinear in its six corners, so they project into the corners' bounds on the light plane and
    // lie no nearer than the nearest corner. A flat shell (its bottom the top moved by one vector)
    // is bounded more tightly, as a large one must be: its depth over a light-plane point is the
    // top's plane, or the bottom's, whichever is nearer, least at a corner of the tile's square.
    // Rounding of a stored depth (start + distance along the ray) is allowed for.
    const float rounding =
        1e-5f * (std::abs(startDepth_) + base.texelWorld * float(base.width + base.height)) +
        1e-3f * base.texelWorld;
    const std::size_t tileCount = std::size_t(base.tilesX) * std::size_t(base.tilesY);
    const Scene& scene = tracer_.scene();
    std::vector<bool> flatSlab(scene.objects.size());
    for (std::size_t object = 0; object < scene.objects.size(); ++object)
        flatSlab[object] = objectsNear_[object] && isFlatSlab(scene.objects[object]);
    const float tileWorld = base.texelWorld * float(kTileTexels);
    // Lowers `bounds` over the tiles under shell `shell`.
    auto boundShell = [&](std::uint32_t shell, std::vector<CasterBounds>& bounds) {
        const std::uint32_t object = tracer_.shellObject(shell);
        if (!objectsNear_[object]) return;  // no tile under it
        glm::vec3 corners[6];
        tracer_.shellCorners(shell, corners, corners + 3);
        glm::vec2 plane[6];
        float depth[6];
        glm::vec2 low(std::numeric_limits<float>::max()), high(-std::numeric_limits<float>::max());
        float nearestCorner = std::numeric_limits<float>::infinity();
        for (int corner = 0; corner < 6; ++corner) {
            plane[corner] = {glm::dot(corners[corner], axisX_), glm::dot(corners[corner], axisY_)};
            depth[corner] = -glm::dot(corners[corner], toLight_);
            low = glm::min(low, plane[corner]);
            high = glm::max(high, plane[corner]);
            nearestCorner = std::min(nearestCorner, depth[corner]);
        }
        // The top's depth as a + b u + c v over light-plane points (u, v), when the shell is flat
        // and the top is not seen edge-on by the light.
        const glm::vec3 offset = corners[3] - corners[0];
        const bool flat = glm::length(corners[4] - corners[1] - offset) <= 1e-6f * tileWorld &&
                          glm::length(corners[5] - corners[2] - offset) <= 1e-6f * tileWorld;
        const glm::vec2 edge1 = plane[1] - plane[0], edge2 = plane[2] - plane[0];
        const double determinant = double(edge1.x) * edge2.y - double(edge1.y) * edge2.x;
        const bool planar = flat && std::abs(determinant) > 1e-6 * double(tileWorld) * tileWorld;
        double slopeU = 0.0, slopeV = 0.0;
        if (planar) {
            const double rise1 = depth[1] - depth[0], rise2 = depth[2] - depth[0];
            slopeU = (rise1 * edge2.y - rise2 * edge1.y) / determinant;
            slopeV = (rise2 * edge1.x - rise1 * edge2.x) / determinant;
        }
        const float bottomShift = std::min(depth[3] - depth[0], 0.0f);
        // Tiles whose square touches the bounds, one tile of margin for rounding.
        const glm::ivec4 tiles = boundTiles(low, high, 1);
        for (int y = tiles.y; y <= tiles.w; ++y)
            for (int x = tiles.x; x <= tiles.z; ++x) {
                float least = nearestCorner;
                if (planar) {
                    // The plane's least value over the square: at the corner its slopes point away
                    // from.
                    const double u =
                        originPlane_.x + (slopeU > 0.0 ? x : x + 1) * double(tileWorld);
                    const double v =
                        originPlane_.y + (slopeV > 0.0 ? y : y + 1) * double(tileWorld);
                    const double top =
                        depth[0] + slopeU * (u - plane[0].x) + slopeV * (v - plane[0].y);
                    least = std::max(least, float(top) + bottomShift);
                }
                CasterBounds& tile =
                    bounds[std::size_t(x) + std::size_t(base.tilesX) * std::size_t(y)];
                if (!flatSlab[object]) {
                    tile.others = std::min(tile.others, least - rounding);
                    continue;
                }
                tile.flat = std::min(tile.flat, least - rounding);
                tile.flatObject = CasterBounds::mergedFlatObject(tile.flatObject, object);
            }
    };
    // The shells in parallel, each thread's into bounds of its own, then merged by least values
    // and the union of flat slabs: the same bounds in any order, on any number of threads.
    tbb::enumerable_thread_specific<std::vector<CasterBounds>> threadBounds(
        [&] { return std::vector<CasterBounds>(tileCount); });
    tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, tracer_.shellCount(), 256),
                      [&](const tbb::blocked_range<std::uint32_t>& shells) {
                          std::vector<CasterBounds>& bounds = threadBounds.local();
                          for (std::uint32_t shell = shells.begin(); shell != shells.end(); ++shell)
                              boundShell(shell, bounds);
                      });
    casterBounds_.assign(tileCount, {});
    threadBounds.combine_each([&](const std::vector<CasterBounds>& bounds) {
        for (std::size_t tile = 0; tile < tileCount; ++tile) {
            CasterBounds& merged = casterBounds_[tile];
            merged.others = std::min(merged.others, bounds[tile].others);
            merged.flat = std::min(merged.flat, bounds[tile].flat);
            merged.flatObject =
                CasterBounds::mergedFlatObject(merged.flatObject, bounds[tile].flatObject);
        }
    });
}

float ShadowMap::nearestDepth() const {
    std::call_once(nearestOnce_, [&] {
        // Traced until the nearest depth found is below every bound left: the least depth of the
        // whole map, from the few tiles near the surface nearest the light.
        // The tiles with a finite bound, by increasing bound (ties by index).
        std::vector<std::pair<float, int>> search;
        for (std::size_t tile = 0; tile < casterBounds_.size(); ++tile) {
            const float bound = std::min(casterBounds_[tile].others, casterBounds_[tile].flat);
            if (!std::isinf(bound)) search.emplace_back(bound, int(tile));
        }
        std::sort(search.begin(), search.end());
        const Level& base = boundLevel();
        float nearest = std::numeric_limits<float>::infinity();
        for (const auto& [bound, tile] : search) {
            if (bound >= nearest) break;
            traceTileOnce(base, tile);
            const int x0 = (tile % base.tilesX) * kTileTexels;
            const int y0 = (tile / base.tilesX) * kTileTexels;
            for (int y = y0; y < std::min(y0 + kTileTexels, base.height); ++y)
                for (int x = x0; x < std::min(x0 + kTileTexels, base.width); ++x)
                    nearest = std::min(nearest, base.depths[base.index(x, y)]);
        }
        nearestDepth_ = nearest;
    });
    return nearestDepth_;
}

void ShadowMap::traceTile(const Level& level, int tile) const {
    const int x0 = (tile % level.tilesX) * kTileTexels;
    const int y0 = (tile / level.tilesX) * kTileTexels;
    const int x1 = std::min(x0 + kTileTexels, level.width);
    const int y1 = std::min(y0 + kTileTexels, level.height);
    TraceCounters counters;
    constexpr int kBatch = int(SceneTracer::kMaxBatchRays);
    Ray rays[kBatch];
    SurfaceHit hits[kBatch];
    bool found[kBatch];
    std::size_t texels[kBatch];
    // The tile's texels in batches traced together: their marches interleave, and each 16 of
    // them meet the base triangles together (SceneTracer), so they go in blocks of 4 x 4, near
    // one another. A ray's hit does not depend on the others in its batch.
    constexpr int kBlock = 4;
    glm::ivec2 order[kTileTexels * kTileTexels];
    int count = 0;
    for (int blockY = y0; blockY < y1; blockY += kBlock)
        for (int blockX = x0; blockX < x1; blockX += kBlock)
            for (int y = blockY; y < std::min(blockY + kBlock, y1); ++y)
                for (int x = blockX; x < std::min(blockX + kBlock, x1); ++x)
                    order[count++] = {x, y};
    for (int first = 0; first < count; first += kBatch) {
        const int batch = std::min(kBatch, count - first);
        for (int k = 0; k < batch; ++k) {
            const int x = order[first + k].x, y = order[first + k].y;
            const float across = originPlane_.x + (float(x) + 0.5f) * level.texelWorld;
            const float along = originPlane_.y + (float(y) + 0.5f) * level.texelWorld;
            rays[k] = {axisX_ * across + axisY_ * along - toLight_ * startDepth_, -toLight_};
            texels[k] = level.index(x, y);
        }
        // Only where the rays stop matters here: no detail normals.
        tracer_.traceNearestBatch(std::span(rays, std::size_t(batch)), 0.0f,
                                  std::span(hits, std::size_t(batch)),
                                  std::span(found, std::size_t(batch)), counters,
                                  /*withNormals=*/false);
        for (int k = 0; k < batch; ++k) {
            level.depths[texels[k]] = found[k] ? startDepth_ + hits[k].distanceWorld
                                               : std::numeric_limits<float>::infinity();
        }
        if (lineTest_)
            traceLayers(level, std::span(rays, std::size_t(batch)),
                        std::span(hits, std::size_t(batch)), std::span(found, std::size_t(batch)),
                        std::span(texels, std::size_t(batch)), counters);
    }
    tracedTexels_.fetch_add(std::uint64_t(count), std::memory_order_relaxed);
    level.tileDone[std::size_t(tile)].store(true, std::memory_order_release);
}

void ShadowMap::traceLayers(const Level& level, std::span<Ray> rays, std::span<SurfaceHit> hits,
                            std::span<bool> found, std::span<const std::size_t> texels,
                            TraceCounters& counters) const {
    constexpr float kInfinity = std::numeric_limits<float>::infinity();
    // Where `ray`, which met `hit` (its object) `startDepth` along the light from its origin,
    // leaves that object: the back face of a closed base mesh (its detail lies inside), else (an
    // open mesh) the depth of the detail's shell below the hit.
    const auto backDepth = [&](const Ray& ray, const SurfaceHit& hit, float startDepth) {
        // From a hair past the hit: a bare surface's own triangle is not met again.
        const float exit =
            tracer_.exitDistance(ray, hit.distanceWorld + 1e-4f * level.texelWorld, hit.object);
        const Material& material = tracer_.scene().objects[hit.object].material;
        return startDepth + (std::isinf(exit)
                                 ? hit.distanceWorld + (material.tile ? material.depthWorld : 0.0f)
                                 : exit);
    };
    // Each layer's objects, then the same light rays on from a hair past where they leave them
    // (packed to the front of `rays`) to the next layer's.
    std::array<std::size_t, SceneTracer::kMaxBatchRays> rayTexels;
    std::array<float, SceneTracer::kMaxBatchRays> rayStarts;  // depth of each ray's origin
    for (std::size_t k = 0; k < rays.size(); ++k) {
        LineLayers& layers = level.layers[texels[k]];
        for (int layer = 0; layer < kLineLayers; ++layer) {
            layers.front[layer] = layers.back[layer] = kInfinity;
            layers.object[layer] = ShadowReceiver::kNoObject;
        }
        rayTexels[k] = texels[k];
        rayStarts[k] = startDepth_;
    }
    std::size_t count = rays.size();
    for (int layer = 0; layer < kLineLayers; ++layer) {
        if (layer > 0)
            tracer_.traceNearestBatch(rays.first(count), 0.0f, hits.first(count),
                                      found.first(count), counters, /*withNormals=*/false);
        std::size_t next = 0;
        for (std::size_t k = 0; k < count; ++k) {
            if (!found[k]) continue;
            LineLayers& layers = level.layers[rayTexels[k]];
            layers.object[layer] = hits[k].object;
            layers.front[layer] = rayStarts[k] + hits[k].distanceWorld;
            layers.back[layer] = backDepth(rays[k], hits[k], rayStarts[k]);
            if (layer + 1 == kLineLayers) continue;  // no layer after the last to trace
            const float from = layers.back[layer] + 1e-3f * level.texelWorld;
            rays[next] = {rays[k].origin + rays[k].direction * (from - rayStarts[k]),
                          rays[k].direction};
            rayStarts[next] = from;
            rayTexels[next++] = rayTexels[k];
        }
        count = next;
        if (count == 0) return;
    }
}

std::uint64_t ShadowMap::texelCount() const {
    std::uint64_t texels = 0;
    for (const Level& level : levels_)
        texels += std::uint64_t(level.width) * std::uint64_t(level.height);
    return texels;
}

float ShadowMap::lookup(const Level& level, const glm::vec2& planeWorld) const {
    const glm::ivec2 texel = texelOf(level, planeWorld);
    return texel.x < 0 ? std::numeric_limits<float>::infinity() : depthAt(level, texel.x, texel.y);
}

glm::ivec4 ShadowMap::boundTiles(const glm::vec2& low, const glm::vec2& high,
                                 int marginTiles) const {
    const Level& level = boundLevel();
    const float tileWorld = level.texelWorld * float(kTileTexels);
    const glm::vec2 first = glm::floor((low - originPlane_) / tileWorld) - float(marginTiles);
    const glm::vec2 last = glm::floor((high - originPlane_) / tileWorld) + float(marginTiles);
    // Clipped while still floats: a float beyond int's range (a box far off the map) has no int
    // conversion. A box that is not a number has no tiles.
    if (std::isnan(first.x) || std::isnan(first.y) || std::isnan(last.x) || std::isnan(last.y))
        return {0, 0, -1, -1};
    constexpr float kFar = float(1 << 30);  // past any level's tiles, either way
    return {int(std::clamp(first.x, 0.0f, kFar)), int(std::clamp(first.y, 0.0f, kFar)),
            int(std::clamp(last.x, -kFar, float(level.tilesX - 1))),
            int(std::clamp(last.y, -kFar, float(level.tilesY - 1)))};
}

bool ShadowMap::nothingNearerThan(const glm::vec2& centre, float reachWorld, float depth,
                                  std::uint32_t receiverObject) const {
    // Outside the map every lookup reads +infinity, no blocker: only the tiles inside count.
    const glm::ivec4 tiles = boundTiles(centre - reachWorld, centre + reachWorld, 0);
    for (int y = tiles.y; y <= tiles.w; ++y)
        for (int x = tiles.x; x <= tiles.z; ++x) {
            const CasterBounds& tile =
                casterBounds_[std::size_t(x) + std::size_t(boundLevel().tilesX) * std::size_t(y)];
            // The receiver's own flat slab lies behind its plane: only other slabs count (the
            // flat bound is +infinity where no slab is).
            if (!(casterBound(tile, receiverObject) >= depth)) return false;
        }
    return true;
}

void ShadowMap::buildBoundLevels() {
    const Level& base = boundLevel();
    boundLevels_.push_back({base.tilesX, base.tilesY, 1, casterBounds_});
    while (boundLevels_.back().width > 1 || boundLevels_.back().height > 1) {
        const BoundLevel& parts = boundLevels_.back();
        BoundLevel blocks;
        blocks.width = (parts.width + kBoundBlock - 1) / kBoundBlock;
        blocks.height = (parts.height + kBoundBlock - 1) / kBoundBlock;
        blocks.tiles = parts.tiles * kBoundBlock;
        blocks.bounds.assign(std::size_t(blocks.width) * std::size_t(blocks.height), {});
        for (int y = 0; y < parts.height; ++y) {
            for (int x = 0; x < parts.width; ++x) {
                const CasterBounds& part = parts.bounds[std::size_t(x + parts.width * y)];
                CasterBounds& block =
                    blocks.bounds[std::size_t(x / kBoundBlock + blocks.width * (y / kBoundBlock))];
                block.others = std::min(block.others, part.others);
                block.flat = std::min(block.flat, part.flat);
                block.flatObject =
                    CasterBounds::mergedFlatObject(block.flatObject, part.flatObject);
            }
        }
        boundLevels_.push_back(std::move(blocks));
    }
}

bool ShadowMap::blockMayBlock(const LineReceiver& receiver, std::size_t level, int x, int y) const {
    const BoundLevel& blocks = boundLevels_[level];
    const CasterBounds& block = blocks.bounds[std::size_t(x + blocks.width * y)];
    const float bound = casterBound(block, receiver.object);
    if (bound >= receiver.depth) return false;
    // A surface at offset s from the receiver blocks a ray toward the disk only if it lies in
    // front of the lowest of them there: depth below receiver.depth - s / tan(angle / 2).
    const float blockWorld = boundLevel().texelWorld * float(kTileTexels * blocks.tiles);
    const glm::vec2 low = originPlane_ + glm::vec2(float(x), float(y)) * blockWorld;
    const glm::vec2 nearest = glm::clamp(receiver.centre, low, low + blockWorld) - receiver.centre;
    // bound >= receiver.depth - |nearest| / tan(angle / 2), squared: no root, no division.
    const float reach = (receiver.depth - bound) * tanHalfAngle_;
    if (glm::dot(nearest, nearest) >= reach * reach) return false;
    if (level == 0) return true;
    const BoundLevel& parts = boundLevels_[level - 1];
    for (int partY = y * kBoundBlock; partY < std::min((y + 1) * kBoundBlock, parts.height);
         ++partY)
        for (int partX = x * kBoundBlock; partX < std::min((x + 1) * kBoundBlock, parts.width);
             ++partX)
            if (blockMayBlock(receiver, level - 1, partX, partY)) return true;
    return false;
}

bool ShadowMap::nothingCanBlockLines(const LineReceiver& receiver) const {
    // From the level whose blocks are about the size of the reach.
    const glm::ivec4 tiles =
        boundTiles(receiver.centre - receiver.reachWorld, receiver.centre + receiver.reachWorld, 0);
    std::size_t level = 0;
    while (level + 1 < boundLevels_.size() &&
           boundLevels_[level].tiles * 2 < std::max(tiles.z - tiles.x, tiles.w - tiles.y))
        ++level;
    const int side = boundLevels_[level].tiles;
    for (int y = tiles.y / side; y <= tiles.w / side; ++y)
        for (int x = tiles.x / side; x <= tiles.z / side; ++x)
            if (blockMayBlock(receiver, level, x, y)) return false;
    return true;
}

const ShadowMap::Level& ShadowMap::levelFor(float texelWorld) const {
    std::size_t index = 0;
    while (index + 1 < levels_.size() && levels_[index + 1].texelWorld <= texelWorld) ++index;
    return levels_[index];
}

float ShadowMap::visibility(const ShadowReceiver& receiver, ShadowFilter filter, std::uint32_t seed,
                            std::uint64_t& samples) const {
    // Ch. 17: a surface facing away from the light is in its own shadow; no samples at all.
    const float facing = glm::dot(receiver.normal, toLight_);
    if (!(facing > 0.0f)) return 0.0f;

    const glm::vec2 centre(glm::dot(receiver.surfaceWorld, axisX_),
                           glm::dot(receiver.surfaceWorld, axisY_));
    const float receiverDepth = -glm::dot(receiver.surfaceWorld, toLight_);
    // A point at infinity is off every map: nothing in it shadows the point. (The renderer looks
    // a detail hit up where the light ray from it leaves its shell: the hit's depth below the top
    // over the light's facing, along the light; infinite for a light grazing the base at a
    // denormal angle.)
    if (!std::isfinite(centre.x) || !std::isfinite(centre.y) || !std::isfinite(receiverDepth))
        return 1.0f;
    // The receiver's tangent plane, as depth along the light per unit of light-plane offset.
    const glm::vec2 slope =
        glm::vec2(glm::dot(receiver.normal, axisX_), glm::dot(receiver.normal, axisY_)) /
        std::max(facing, kMinFacing);
    // A nearest-texel lookup lands up to 0.71 texel (of the level read) from the asked point; on
    // the slope that is 0.71 texel * |slope| of depth. One texel (plus one of slope) covers it
    // with margin.
    const float slopeLength = glm::length(slope);
    // Depth of the blocker at `offset` from the receiver in `level`, or +infinity if nothing
    // there blocks.
    auto blocker = [&](const Level& level, const glm::vec2& offset) {
        const float stored = lookup(level, centre + offset);
        const float reference = receiverDepth + glm::dot(slope, offset);
        const float bias =
            level.texelWorld * (1.0f + slopeLength) + kCurvatureSlack * glm::length(offset);
        return stored < reference - bias ? stored : std::numeric_limits<float>::infinity();
    };
    const float finestTexelWorld = levels_[0].texelWorld;
    const float baseTexelWorld = boundLevel().texelWorld;
    const float footprint = receiver.footprintWorld;
    if (lineTest_) {
        LineReceiver line{centre,
                          receiverDepth,
                          slope,
                          slopeLength,
                          footprint,
                          facing >= kMinFacing ? receiver.object : ShadowReceiver::kNoObject,
                          tanHalfAngle_ * std::max(receiverDepth - nearestDepth(), 0.0f)};
        if (nothingCanBlockLines(line)) return 1.0f;
        return lineVisibility(line, filter, seed, samples);
    }

    // The widest penumbra possible here: from the surface nearest to the light anywhere.
    const float searchRadius =
        std::min(tanHalfAngle_ * std::max(receiverDepth - nearestDepth(), 0.0f),
                 kMaxSearchTexels * baseTexelWorld);
    // A sample blocks where the stored depth is below the receiver's plane there (less a bias):
    // nowhere if no surface over the texels the samples may read (their centres are within one
    // texel of the level read of the disk) can be nearer than the plane's nearest point on it.
    // The receiver's own flat slab lies behind the plane only where the plane is its surface's:
    // not where the light grazes it (the slope is limited there, kMinFacing).
    // The ring's level is the coarsest any sample reads (the disk's radius is at most the ring's).
    const Level& ringLevel = levelFor(std::max(footprint, searchRadius / kTexelsPerFilterRadius));
    const std::uint32_t slabBehind =
        facing >= kMinFacing ? receiver.object : ShadowReceiver::kNoObject;
    if (nothingNearerThan(centre, searchRadius + ringLevel.texelWorld,
                          receiverDepth + slopeLength * searchRadius, slabBehind)) {
        return 1.0f;
    }
    // A disk inside one texel: a hard shadow, one sample.
    if (searchRadius < 0.5f * finestTexelWorld) {
        ++samples;
        return std::isinf(blocker(levelFor(footprint), glm::vec2(0.0f))) ? 1.0f : 0.0f;
    }

    const std::uint32_t pixelSeed = mixBits(seed);
    const DiskPattern disk(pixelSeed, kTwoPi * unitFloat(mixBits(pixelSeed ^ 0x68bc21ebU)));
    // The outer ring and its centre: penumbra test and blocker search in one. The radius reaches
    // the penumbra of the surface nearest to the light anywhere in the map, and a low blocker's
    // shadow may lie inside the ring, beside all of its samples: the centre finds it.
    int blocked = 0;
    float blockerDepthSum = 0.0f;
    const auto search = [&](const glm::vec2& offset) {
        const float depth = blocker(ringLevel, offset);
        if (std::isinf(depth)) return;
        ++blocked;
        blockerDepthSum += depth;
    };
    for (int angular = 0; angular < kStrata; ++angular)
        search(disk.offset(angular, kStrata - 1) * searchRadius);
    search(glm::vec2(0.0f));
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
    const Level& diskLevel = levelFor(std::max(footprint, filterRadius / kTexelsPerFilterRadius));
    int lit = 0;
    for (int radial = 0; radial < kStrata; ++radial) {
        for (int angular = 0; angular < kStrata; ++angular) {
            lit +=
                std::isinf(blocker(diskLevel, disk.offset(angular, radial) * filterRadius)) ? 1 : 0;
        }
    }
    samples += kShadowDiskSamples;
    return float(lit) / float(kShadowDiskSamples);
}

float ShadowMap::lineVisibility(const LineReceiver& receiver, ShadowFilter filter,
                                std::uint32_t seed, std::uint64_t& samples) const {
    const std::uint32_t pixelSeed = mixBits(seed);
    const DiskPattern disk(pixelSeed, kTwoPi * unitFloat(mixBits(pixelSeed ^ 0x68bc21ebU)));
    // The disk's samples along each angular stratum's middle: radii stratified by area, one jitter
    // for the lookup. The ray toward the disk point at radius rho rises 1 / (rho tan(angle / 2))
    // of depth toward the light per unit of light-plane offset.
    const float radialJitter = unitFloat(mixBits(pixelSeed ^ 0x2c1b3c6dU));
    LineRises rises;
    for (int radial = 0; radial < kLineRadii; ++radial)
        rises[std::size_t(radial)] =
            1.0f / (tanHalfAngle_ * std::sqrt((float(radial) + radialJitter) / float(kLineRadii)));
    // Every ray starts at the receiver: below the first or the second object over it (as the
    // light sees it) or below none; inside one it sees nothing.
    std::uint64_t reads = 0;
    LineGaps start;
    const Level& own = levelFor(receiver.footprintWorld);
    const glm::ivec2 texel = texelOf(own, receiver.centre);
    const int tile = boundTileAt(receiver.centre);
    if (texel.x >= 0 && tile >= 0 &&
        casterBound(casterBounds_[std::size_t(tile)], receiver.object) < receiver.depth) {
        ++reads;
        const float above = receiver.depth - own.texelWorld * (1.0f + receiver.slopeLength);
        const float front = depthAt(own, texel.x, texel.y);
        if (front < above) {
            // The receiver lies under the deepest layer in front of it, or inside it.
            const LineLayers& layers = own.layers[own.index(texel.x, texel.y)];
            int under = 0;
            while (under + 1 < kLineLayers && layers.front[under + 1] < above) ++under;
            if (!(receiver.depth > layers.back[under])) {
                samples += reads;
                return 0.0f;
            }
            start.count = 1;
            start.gaps[1] = kAllLineRays;
            start.objects[0] = layers.object[under];
            start.rims[0] = rimDepth(layers.front[under], layers.back[under]);
        }
    }
    // Every other angular stratum first: where their lines agree (all lit or all blocked), the
    // adaptive filter takes that as the answer, as visibility() does its ring.
    int blockedRays = 0;
    for (int line = 0; line < kStrata; ++line) {
        if (line == kStrata / 2 && filter == ShadowFilter::Adaptive &&
            (blockedRays == 0 || blockedRays == kStrata / 2 * kLineRadii)) {
            samples += reads;
            return blockedRays == 0 ? 1.0f : 0.0f;
        }
        const int angular = 2 * line % kStrata + 2 * line / kStrata;
        blockedRays +=
            std::popcount(blockedOnLine(receiver, disk.direction(angular), rises, start, reads));
    }
    samples += reads;
    return 1.0f - float(blockedRays) / float(kStrata * kLineRadii);
}

unsigned ShadowMap::blockedOnLine(const LineReceiver& receiver, const glm::vec2& along,
                                  const LineRises& rises, const LineGaps& start,
                                  std::uint64_t& reads) const {
    constexpr float kInfinity = std::numeric_limits<float>::infinity();
    const float lowestRise = rises[kLineRadii - 1];
    unsigned blocked = 0;  // a bit per ray: it met a blocker
    // Where the rays were at the previous offset and are at this one: two buffers taking turns
    // (copying one into the other at every step stalled on the stores of its last writes).
    LineGaps buffers[2] = {start, {}};
    LineGaps* wasGaps = &buffers[0];
    LineGaps* nowGaps = &buffers[1];
    // The caster bound of the bound level's tile under the offset (consecutive offsets share
    // tiles).
    int boundTile = -2;
    float bound = kInfinity;
    // Steps are kLineStepShare of the offset over open ground and kEdgeStepShare where a ray may
    // meet a blocker's edge: while a ray is under a blocker (where it comes out, under its edge
    // or in front of it), and over the step from the last open offset to the first with a blocker
    // (a ray that rose in front of it there may have passed under its edge first). Past the reach
    // every ray is in front of all there is: the first offset beyond it is the last one that can
    // show a ray coming out in front of a blocker it was under.
    float fineUntil = 0.0f;
    for (float offset = std::max(0.5f * levels_[0].texelWorld, receiver.footprintWorld),
               previous = 0.0f;
         previous <= receiver.reachWorld && blocked != kAllLineRays;) {
        unsigned wasUnder = 0;
        const LineGaps& was = *wasGaps;
        for (int gap = 1; gap <= was.count; ++gap) wasUnder |= was.gaps[std::size_t(gap)];
        const bool open = (was.gaps[0] | wasUnder) == 0;
        const bool fine = wasUnder != 0 || offset < fineUntil;
        const float share = fine ? kEdgeStepShare : kLineStepShare;
        const Level& level = levelFor(std::max(receiver.footprintWorld, share * offset));
        const glm::vec2 at = receiver.centre + offset * along;
        const int tile = boundTileAt(at);
        if (tile != boundTile) {
            boundTile = tile;
            bound = tile < 0 ? kInfinity
                             : casterBound(casterBounds_[std::size_t(tile)], receiver.object);
        }
        // A texel is read where a surface may lie in front of the lowest ray (after open ground:
        // of the lowest ray at the open offset, which may have passed under a blocker beginning
        // here), or where a ray was under a blocker. Elsewhere every ray is in front of all there
        // is, and the tile need not be traced.
        const float lowestRay = receiver.depth - (open ? previous : offset) * lowestRise;
        float front = kInfinity;
        glm::ivec2 texel(-1);
        if (wasUnder != 0 || !(bound >= lowestRay)) {
            texel = texelOf(level, at);
            if (texel.x >= 0) {
                front = depthAt(level, texel.x, texel.y);
                ++reads;
            }
        }
        // Only what lies in front of the receiver's tangent plane blocks (as in visibility()).
        const float plane = receiver.depth + glm::dot(receiver.slope, offset * along);
        const float bias =
            level.texelWorld * (1.0f + receiver.slopeLength) + kCurvatureSlack * offset;
        const bool blocker = front < plane - bias;
        if (blocker && !fine && previous > 0.0f && open) {
            // The first blocker after open ground, a coarse step on: that step again, finely
            // (the open offset's state stands).
            const float fineStep = std::max(
                levelFor(std::max(receiver.footprintWorld, kEdgeStepShare * previous)).texelWorld,
                kEdgeStepShare * previous);
            if (previous + fineStep < offset) {
                fineUntil = offset;
                offset = previous + fineStep;
                continue;
            }
        }
        LineGaps& now = *nowGaps;
        now.count = 0;
        now.gaps[0] = 0;
        if (blocker || wasUnder != 0) {
            // The layers in front of the receiver's plane (the first one's front is `front`),
            // read only where it is a blocker.
            const LineLayers* layers =
                blocker ? &level.layers[level.index(texel.x, texel.y)] : nullptr;
            int layerCount = 0;
            if (blocker) {
                while (layerCount < kLineLayers && layers->front[layerCount] < plane - bias) {
                    now.objects[std::size_t(layerCount)] = layers->object[layerCount];
                    now.rims[std::size_t(layerCount)] =
                        rimDepth(layers->front[layerCount], layers->back[layerCount]);
                    ++layerCount;
                }
            }
            now.count = layerCount;
            // Each ray's depth here, and a bit per ray where it is nearer to the light than a
            // depth or farther.
            const LineRayDepths rays(receiver.depth, offset, rises);
            // The gaps between the layers, the rays inside one, and per layer the rays in front
            // of it and behind it (with those inside another layer, which are blocked anyway).
            unsigned inside = 0;
            std::array<unsigned, kLineLayers> inFrontOf{}, behind{};
            if (layerCount > 0) {
                unsigned pastAbove = kAllLineRays;  // behind the layer above (all: none above)
                for (int layer = 0; layer < layerCount; ++layer) {
                    const unsigned inFront = rays.nearer(layers->front[layer]);
                    const unsigned past = rays.farther(layers->back[layer]);
                    now.gaps[std::size_t(layer)] = pastAbove & inFront;
                    inside |= pastAbove & ~inFront & ~past;
                    pastAbove = past;
                    inFrontOf[std::size_t(layer)] = inFront;
                    behind[std::size_t(layer)] = past;
                }
                now.gaps[std::size_t(layerCount)] = pastAbove;
            }
            // Between two offsets a ray crossed a blocker's surface where the object it was under
            // is now below it (in front of its deepest layer here), or the object it was over is
            // now above it (behind its nearest layer here). An object it was under that is now in
            // no layer ended between the two (as the light sees it): the ray came out under its
            // edge unless it rose past the object's rim in the first half of the step (where in
            // the step the edge lies is not known).
            const auto rose = [&](std::uint32_t object, unsigned under, float rim) {
                if (under == 0) return 0U;
                for (int layer = layerCount - 1; layer >= 0; --layer)
                    if (now.objects[std::size_t(layer)] == object)
                        return under & inFrontOf[std::size_t(layer)];
                return under & rays.rosePast(rim, LineRayDepths(receiver.depth, previous, rises));
            };
            const auto sank = [&](std::uint32_t object, unsigned over) {
                if (over == 0) return 0U;
                for (int layer = 0; layer < layerCount; ++layer)
                    if (now.objects[std::size_t(layer)] == object)
                        return over & behind[std::size_t(layer)];
                return 0U;
            };
            blocked |= inside;
            for (std::size_t layer = 0; layer < std::size_t(was.count); ++layer) {
                blocked |= rose(was.objects[layer], was.gaps[layer + 1], was.rims[layer]) |
                           sank(was.objects[layer], was.gaps[layer]);
            }
        }
        std::swap(wasGaps, nowGaps);
        previous = offset;
        offset += std::max(level.texelWorld, share * offset);
    }
    return blocked;
}

bool lightReachesVisibleSurface(const Scene& scene, const DirectionalLight& light) {
    const glm::vec3 toLight = -unitDirection(light.direction);
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
    return scene.objects.size() != 1 || !isFlatSlab(scene.objects[0]);
}

bool isFlatSlab(const SceneObject& object) {
    const BaseMesh& mesh = object.mesh;
    if (mesh.positions.empty() || mesh.normals.size() != mesh.positions.size()) return false;
    const glm::vec3 normal = mesh.normals[0];
    glm::vec3 lower = mesh.positions[0], upper = mesh.positions[0];
    for (const glm::vec3& position : mesh.positions) {
        lower = glm::min(lower, position);
        upper = glm::max(upper, position);
    }
    const float tolerance = 1e-5f * glm::length(upper - lower);
    for (std::size_t vertex = 0; vertex < mesh.positions.size(); ++vertex) {
        if (glm::dot(mesh.normals[vertex], normal) < 1.0f - 1e-6f) return false;
        if (std::abs(glm::dot(mesh.positions[vertex] - mesh.positions[0], normal)) > tolerance)
            return false;
    }
    return true;
}

}  // namespace distile
