/// @file
/// Shadow maps for directional lights with adaptive percentage-closer soft shadows (GPU Gems 2,
/// ch. 17), so objects shadow each other; the detail's shadows on itself stay with the in-tile
/// shadow rays of the renderer.
///
/// A map is an orthographic grid of rays along the light direction over the scene's bounds (or,
/// where those are far wider, over the part of the light's view where a receiver can be shadowed;
/// groups of receivers that cannot shadow each other get a map each: shadowMapAreas),
/// each traced with SceneTracer::traceNearest, so the displaced detail (not only the base mesh)
/// casts the shadow. A texel stores the depth of the nearest hit along the light direction, in
/// world units. The map is traced in square tiles of kTileTexels, each the first time a lookup
/// reaches it: only where a receiver looks (a view sees a fraction of the scene, and its
/// receivers' filter disks a fraction of the light's view of it). The map has kLevels levels of
/// doubling texel size, each traced the same lazy way, and a lookup reads the coarsest level its
/// receiver needs: texels no larger than the receiver's pixel footprint, or than half the radius
/// of the disk the samples spread over, whichever is larger (the 64 samples of a disk of radius
/// r blur the shadow over r: texels much finer than that change little). Where the camera's
/// nearest receivers have pixels much finer than the map's texels (a close view of a wide scene),
/// the map adds finer levels below them (kMaxFinerLevels). Lookups filter with 64
/// jittered samples warped to a disk (an 8 x 8 stratified grid, polar warp); the adaptive filter
/// first takes the 8 samples of the outer ring and its centre, and stops when they agree.
///
/// Lights at least kLineTestMinAngleDeg wide take the *line test* instead: each of 64 directions
/// toward the light's disk (8 angular strata, 8 radii) is followed through the map, on the line
/// of light-plane offsets its ray passes over, against the blocker stored there, so a blocker
/// shadows a direction only where the ray really meets it (near a contact, a blocker overhead
/// covers the directions that rise into it, not those that leave under it). For that the map also
/// keeps kLineLayers layers per texel: the first objects each light ray meets, nearest first,
/// where it enters and where it leaves each (the back face of a closed mesh; LineLayers).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <limits>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

#include "render/scene.h"
#include "render/tracer.h"

namespace distile {

class PinholeProjection;

/// How shadow maps are filtered. None: no shadow map (objects do not shadow each other).
/// Full: every lookup takes the 8 blocker-search samples and the 64 filter samples.
/// Adaptive (ch. 17): the 8 outer-ring samples first; the 64 only where they disagree.
enum class ShadowFilter { None, Full, Adaptive };
inline constexpr ShadowFilter kShadowFilters[] = {ShadowFilter::None, ShadowFilter::Full,
                                                  ShadowFilter::Adaptive};

/// "none", "full", "adaptive": the names programs show and accept.
inline const char* shadowFilterName(ShadowFilter filter) {
    return filter == ShadowFilter::None   ? "none"
           : filter == ShadowFilter::Full ? "full"
                                          : "adaptive";
}

/// Samples per lookup: the outer ring and its centre (blocker search and penumbra test), and
/// the full disk.
constexpr int kShadowRingSamples = 9;
constexpr int kShadowDiskSamples = 64;

/// Lights at least this wide (angle_deg) take the line test (file note). Percentage-closer
/// filtering tests each disk sample at one light-plane offset whatever the blocker's depth, and
/// searches at most 32 base texels: near a contact it lights what a blocker overhead covers and
/// darkens what rays leave from under. Against the world reference's 16 shadow rays (a sphere
/// resting on a plane, 320 x 256, 16 samples per pixel, mean absolute sRGB difference over the
/// image), filtering and the line test differ by 0.110 and 0.107 codes at 3 degrees, 0.145 and
/// 0.105 at 6, 0.223 and 0.107 at 10, 0.412 and 0.136 at 20, 0.652 and 0.233 at 45; the line test
/// takes 2.4 times the render of that scene at 45 degrees, where shadows are most of the work.
constexpr float kLineTestMinAngleDeg = 5.0f;

/// A surface point asking how much of a light it sees. Positions in world units.
struct ShadowReceiver {
    glm::vec3 surfaceWorld;  ///< on the base surface above the shaded point (the top of its shell)
    glm::vec3 normal;        ///< base-surface normal there, unit, outward
    /// The smallest width of the receiver's pixel as the light sees it, world units: texels
    /// finer than this are not resolved by the image. 0: the finest level is read.
    float footprintWorld = 0.0f;
    /// The scene object the receiver lies on, or kNoObject. A receiver on a flat slab
    /// (isFlatSlab) cannot be shadowed by that slab, so a lookup over nothing else takes no
    /// samples.
    std::uint32_t object = kNoObject;
    static constexpr std::uint32_t kNoObject = 0xffffffffU;
};

/// Most maps one light has (shadowMapAreas).
constexpr int kMaxShadowMapsPerLight = 8;

/// Where one of a light's shadow maps lies, in light-plane coordinates (world units along the
/// map's axes) and depths along the light (world units, increasing away from it).
struct ShadowMapArea {
    glm::vec2 lowPlane{0.0f}, highPlane{0.0f};  ///< the rectangle its texels cover
    float depthLowWorld = 0.0f;  ///< no surface over the rectangle is nearer to the light
    float sideWorld = 0.0f;      ///< the side its resolution spans (at least the rectangle's)
    /// The rectangle of the receivers it serves: a receiver takes the map whose rectangle is
    /// nearest (LightShadowMaps).
    glm::vec2 receiversLowPlane{0.0f}, receiversHighPlane{0.0f};
    /// The width of a camera pixel at the nearest of those receivers, world units: the finest
    /// texels they can resolve (0: no view given).
    float pixelWorld = 0.0f;
    /// The narrowest footprint, as the light sees it, of the objects over those receivers other
    /// than flat slabs: the smallest blocker whose shadow the map must hold (0: none).
    float blockerWorld = 0.0f;
    /// Per scene object: whether it may lie over the rectangle (its footprint comes within
    /// sideWorld of it). The map's depth bounds skip the shells of the others.
    std::vector<bool> objectsNear;
};

/// The areas of the shadow maps of `light` over `scene` (validateScene passed): one per group of
/// receivers that no blocker of another group can shadow, at most kMaxShadowMapsPerLight, each
/// covering the whole scene as the light sees it unless that is more than 4 times as wide as its
/// group (a ground plane far wider than the objects standing on it, groups of objects far
/// apart): there its group, with texels 4 times its side over the resolution (shadow_map.cpp).
/// With `view`, only receivers its camera rays may meet count.
std::vector<ShadowMapArea> shadowMapAreas(const Scene& scene, const DirectionalLight& light,
                                          const PinholeProjection* view = nullptr);

class ShadowMap {
  public:
    /// The default resolution: the longer side of the map, in texels. 2048 over the demo scene
    /// (about 4.5 world units across as the light sees it) gives 2.2 mm texels, the footprint of
    /// a pixel of the 1280 x 1024 demo view on the floor (2.7 mm) and finer than a chain-mail
    /// tile texel there (3.9 mm), so the map resolves what the camera resolves.
    static constexpr int kDefaultResolution = 2048;

    /// Side of the square tiles the map is traced in, texels: small enough that a tile holds
    /// little a receiver does not ask for, large enough for whole batches of light rays.
    static constexpr int kTileTexels = 16;

    /// Levels of the map at the resolution asked for: the base level, then three of doubling
    /// texel size.
    static constexpr int kLevels = 4;
    /// Levels finer than the base, halving its texels each, a map may add where the camera's
    /// nearest receivers need them (ShadowMapArea::pixelWorld): while the base's texels are wider
    /// than kMaxTexelOverPixel pixels there (and, for the line test's wide lights, than
    /// 1 / kMinTexelsPerBlocker of the smallest blocker, ShadowMapArea::blockerWorld), and the
    /// finest level has at most kMaxFinerResolution texels a side (256 MiB of address space, 2.5
    /// GiB with the line test's layers, of which only the tiles traced are touched). Level k has
    /// texels 2^k times the finest level's.
    static constexpr int kMaxFinerLevels = 3;
    static constexpr float kMaxTexelOverPixel = 2.0f;
    static constexpr float kMinTexelsPerBlocker = 16.0f;
    static constexpr int kMaxFinerResolution = 8192;
    static constexpr int kMaxResolution = 16384;  ///< the most texels a side asked for
    /// Samples spread over a disk of radius r read a level whose texels are at most r divided by
    /// this (unless the receiver's footprint allows larger ones).
    static constexpr float kTexelsPerFilterRadius = 2.0f;

    /// The map of `light` over `area` (one of shadowMapAreas(tracer.scene(), light)),
    /// `resolutionTexels` texels along area.sideWorld at the base level, square texels, and the
    /// finer levels area.pixelWorld asks for (kMaxFinerLevels).
    /// Nothing is traced yet but the base level's tiles that may hold the nearest depth: a tile
    /// is traced by the thread whose lookup first reaches it (others wait for it), so every texel
    /// holds what a full build gives, whatever the thread count and order. Preconditions:
    /// validateScene passed for tracer.scene(); `tracer` outlives the map. Throws InputError unless
    /// resolutionTexels is in [16, kMaxResolution].
    ShadowMap(const SceneTracer& tracer, const DirectionalLight& light, int resolutionTexels,
              const ShadowMapArea& area);

    /// Fraction in [0, 1] of the light that reaches `receiver` past other surfaces, by
    /// percentage-closer filtering over a disk whose radius is tan(angle/2) times the receiver-
    /// blocker distance (the penumbra of a light of that angular diameter). Blockers are surfaces
    /// nearer to the light than the receiver's base-surface tangent plane, so its own detail never
    /// shadows it here. `seed` fixes the per-pixel rotation and jitter of the samples (the same
    /// seed gives the same answer). The level read follows receiver.footprintWorld and the disks'
    /// radii (kTexelsPerFilterRadius). Adds the samples taken to `samples`: none when the receiver
    /// faces away from the light (it returns 0), 1 for a light of angle 0 (hard shadow), 9 or 73
    /// for Adaptive, 73 for Full; for a light that takes the line test, the texels it read.
    /// Precondition: filter is not None.
    float visibility(const ShadowReceiver& receiver, ShadowFilter filter, std::uint32_t seed,
                     std::uint64_t& samples) const;

    /// The distance on the light's plane from `world` to the rectangle of the receivers this
    /// map serves (0 inside it), world units.
    float distanceToReceivers(const glm::vec3& world) const;

    /// The finest level's size, texels, and texel side, world units.
    int width() const { return levels_[0].width; }
    int height() const { return levels_[0].height; }
    float texelWorld() const { return levels_[0].texelWorld; }
    /// Stored depth of texel (x, y) of level `level` along the light direction, world units;
    /// +infinity where the light ray hit nothing. Traces the texel's tile if no lookup has.
    /// Preconditions: 0 <= level < levelCount(), (x, y) inside the level. Thread-safe.
    float depthAt(int x, int y, int level = 0) const {
        return depthAt(levels_[std::size_t(level)], x, y);
    }
    /// Levels: kLevels and the finer ones the map added below them.
    int levelCount() const { return int(levels_.size()); }
    /// The smallest depth of the base level (the blocker nearest the light), found on first use
    /// from only the tiles that may hold it: a map no lookup reaches traces nothing for it.
    float nearestDepth() const;
    /// Texels traced so far (whole tiles, clipped to their level), all levels.
    std::uint64_t tracedTexels() const { return tracedTexels_.load(std::memory_order_relaxed); }
    /// Texels of all levels, traced or not.
    std::uint64_t texelCount() const;

  private:
    /// The objects the line test keeps per light ray: a lower one may be a blocker hidden behind
    /// those above it (a receiver under a stack of tori).
    static constexpr int kLineLayers = 3;
    /// What the line test keeps of a light ray: the first kLineLayers objects it meets, nearest
    /// first, with the depths where it enters each (front[0] is Level::depths' depth, repeated so
    /// the layers read alike) and leaves it (the back face of a closed mesh). Depths along the
    /// light, world units; +infinity and ShadowReceiver::kNoObject past the last object. No
    /// initialisers, so the memory of tiles no lookup reaches is never touched (Level::depths).
    struct LineLayers {
        float front[kLineLayers];
        float back[kLineLayers];
        std::uint32_t object[kLineLayers];
    };
    /// One level: a grid of light rays over the map's bounds, traced a tile at a time.
    struct Level {
        float texelWorld = 1.0f;
        int width = 0;
        int height = 0;
        int tilesX = 0;
        int tilesY = 0;
        /// Tile by tile (row-major over the tiles), each tile's kTileTexels^2 texels row-major
        /// (edge tiles padded), so a lookup's disk reads a few contiguous tiles. Left
        /// uninitialised: a tile's texels are written once, by traceTile, so the memory of tiles
        /// no lookup reaches is never touched.
        std::unique_ptr<float[]> depths;
        /// The line test's (else null): per texel as `depths`, the objects its light ray meets.
        std::unique_ptr<LineLayers[]> layers;
        /// Where texel (x, y) is stored in depths.
        std::size_t index(int x, int y) const {
            const auto column = unsigned(x), row = unsigned(y);  // >= 0: unsigned / and % shift
            const std::size_t tile =
                column / kTileTexels + std::size_t(tilesX) * (row / kTileTexels);
            return tile * std::size_t(kTileTexels * kTileTexels) +
                   (row % kTileTexels) * kTileTexels + column % kTileTexels;
        }
        std::unique_ptr<std::once_flag[]> tileOnce;
        std::unique_ptr<std::atomic<bool>[]> tileDone;
    };
    /// depthAt in `level`.
    float depthAt(const Level& level, int x, int y) const {
        traceTileOnce(
            level, int(unsigned(x) / kTileTexels) + level.tilesX * int(unsigned(y) / kTileTexels));
        return level.depths[level.index(x, y)];
    }
    /// Depth stored at the texel of `level` containing light-plane point `planeWorld`;
    /// +infinity outside.
    float lookup(const Level& level, const glm::vec2& planeWorld) const;
    /// The coarsest level whose texels are at most `texelWorld` (the finest if none is).
    const Level& levelFor(float texelWorld) const;
    /// Traces tile `tile` (row-major over the level's tiles) unless it is done; returns once it
    /// is.
    void traceTileOnce(const Level& level, int tile) const {
        if (level.tileDone[std::size_t(tile)].load(std::memory_order_acquire)) return;
        std::call_once(level.tileOnce[std::size_t(tile)], [&] { traceTile(level, tile); });
    }
    void traceTile(const Level& level, int tile) const;
    /// The line test's layers (LineLayers) of light rays `rays` of `level`, which met `hits`
    /// where `found`, into texels `texels`. Overwrites all three spans (the further layers' rays).
    void traceLayers(const Level& level, std::span<Ray> rays, std::span<SurfaceHit> hits,
                     std::span<bool> found, std::span<const std::size_t> texels,
                     TraceCounters& counters) const;
    /// Fills casterBounds_.
    void boundDepths();
    /// The level whose tiles the caster bounds are kept on: the base (finer levels would only
    /// multiply the bounds' tiles and the work of reading them).
    const Level& boundLevel() const { return levels_[boundLevel_]; }
    /// The bound level's tiles (first x, first y, last x, last y) whose squares touch the
    /// light-plane box [low, high], grown by `marginTiles`, clipped to the level.
    glm::ivec4 boundTiles(const glm::vec2& low, const glm::vec2& high, int marginTiles) const;
    /// Whether no sample of a lookup can find a blocker: every texel it may read, those with
    /// centres within `reachWorld` of light-plane point `centre`, lies where the depth bounds of
    /// the shells other than the receiver's own flat slab are at least `depth`.
    bool nothingNearerThan(const glm::vec2& centre, float reachWorld, float depth,
                           std::uint32_t receiverObject) const;

    const SceneTracer& tracer_;
    glm::vec3 toLight_{0.0f, 0.0f, 1.0f};  ///< unit, from surfaces toward the light
    glm::vec3 axisX_{1.0f, 0.0f, 0.0f};    ///< unit, across the map
    glm::vec3 axisY_{0.0f, 1.0f, 0.0f};    ///< unit, across the map
    glm::vec2 originPlane_{0.0f};  ///< light-plane coordinates of the map's corner, world units
    glm::vec2 receiversLow_{0.0f}, receiversHigh_{0.0f};  ///< ShadowMapArea's
    std::vector<bool> objectsNear_;                       ///< ShadowMapArea's
    float tanHalfAngle_ = 0.0f;
    bool lineTest_ = false;  ///< a light at least kLineTestMinAngleDeg wide (file note)
    /// A receiver as the line test sees it (visibility's terms).
    struct LineReceiver {
        glm::vec2 centre;  ///< light-plane point
        float depth;       ///< along the light
        glm::vec2 slope;   ///< of its tangent plane: depth per unit of light-plane offset
        float slopeLength;
        float footprintWorld;
        std::uint32_t object;  ///< whose flat slab lies behind it, or ShadowReceiver::kNoObject
        float reachWorld;      ///< the farthest offset a blocker can be at
    };
    /// The line test's rays per line (angular stratum): radii of equal area.
    static constexpr int kLineRadii = 8;
    static constexpr unsigned kAllLineRays = (1U << kLineRadii) - 1;
    /// Per ray of a line: the depth it rises toward the light per unit of light-plane offset.
    using LineRises = std::array<float, kLineRadii>;
    /// visibility() by the line test (file note): the share of the 64 directions whose rays meet
    /// no blocker. Adaptive: every other angular stratum first, the rest only where those
    /// disagree.
    float lineVisibility(const LineReceiver& receiver, ShadowFilter filter, std::uint32_t seed,
                         std::uint64_t& samples) const;
    /// The rays of one line at one offset, a bit each, by where they pass the blockers there (as
    /// the light sees them): of the `count` layers in front of the receiver's plane, gaps[k] holds
    /// the rays behind the first k and in front of the rest (gaps[0]: in front of all, under
    /// none); with the layers' objects and the depths of their rims (rimDepth in shadow_map.cpp).
    /// Past `count` nothing is read.
    struct LineGaps {
        int count = 0;
        std::array<unsigned, kLineLayers + 1> gaps{};
        std::array<std::uint32_t, kLineLayers> objects{};
        std::array<float, kLineLayers> rims{};
    };
    /// The rays of one line (unit light-plane direction `along`) that meet a blocker, a bit each;
    /// every ray starts where `start` says (the receiver's texel: under an object over it or
    /// nowhere). Adds the texels read to `reads`.
    unsigned blockedOnLine(const LineReceiver& receiver, const glm::vec2& along,
                           const LineRises& rises, const LineGaps& start,
                           std::uint64_t& reads) const;
    /// The bound level's tile (row-major) holding light-plane point `planeWorld`; -1 outside.
    /// Inline: the line test asks at every step.
    int boundTileAt(const glm::vec2& planeWorld) const {
        const Level& level = boundLevel();
        const glm::ivec2 texel = texelOf(level, planeWorld);
        return texel.x < 0 ? -1 : texel.x / kTileTexels + level.tilesX * (texel.y / kTileTexels);
    }
    /// Whether no surface over the receiver's reach can lie in front of a ray of its disk (the
    /// caster bounds, coarse blocks first): then it is lit, with no texel read.
    bool nothingCanBlockLines(const LineReceiver& receiver) const;
    /// The texel of `level` holding light-plane point `planeWorld`; x = -1 outside the level.
    /// Inside it the texel is the integer part (no floor needed: x >= 0, and floor(x) < width
    /// exactly when x < width).
    glm::ivec2 texelOf(const Level& level, const glm::vec2& planeWorld) const {
        const float x = (planeWorld.x - originPlane_.x) / level.texelWorld;
        const float y = (planeWorld.y - originPlane_.y) / level.texelWorld;
        if (!(x >= 0.0f && y >= 0.0f && x < float(level.width) && y < float(level.height)))
            return {-1, -1};
        return {int(x), int(y)};
    }
    mutable std::once_flag nearestOnce_;
    mutable float nearestDepth_ = 0.0f;  ///< nearestDepth(), once found
    float startDepth_ = 0.0f;            ///< where the light rays start: in front of everything
    std::vector<Level> levels_;          ///< the finest first
    std::size_t boundLevel_ = 0;         ///< the base level's index: the finer levels' count
    /// Per tile of the bound level: lower bounds of the depth of any surface there, from the
    /// shells over the tile's square.
    struct CasterBounds {
        float others = std::numeric_limits<float>::infinity();  ///< shells of curved objects
        float flat = std::numeric_limits<float>::infinity();    ///< shells of flat slabs
        /// The flat slab whose shells are over the tile: ShadowReceiver::kNoObject for none,
        /// kSeveral for more than one.
        std::uint32_t flatObject = ShadowReceiver::kNoObject;
        static constexpr std::uint32_t kSeveral = ShadowReceiver::kNoObject - 1;
        /// flatObject of a tile under the shells of two tiles whose flatObject values are `a`
        /// and `b`: their one flat slab, none, or kSeveral.
        static std::uint32_t mergedFlatObject(std::uint32_t a, std::uint32_t b) {
            if (a == ShadowReceiver::kNoObject || a == b) return b;
            return b == ShadowReceiver::kNoObject ? a : kSeveral;
        }
    };
    /// The least depth of a surface over `bounds`' square that may shadow a receiver on
    /// `receiverObject` (its own flat slab left out).
    static float casterBound(const CasterBounds& bounds, std::uint32_t receiverObject) {
        return bounds.flatObject == receiverObject ? bounds.others
                                                   : std::min(bounds.others, bounds.flat);
    }
    std::vector<CasterBounds> casterBounds_;
    /// The caster bounds of blocks of kBoundBlock x kBoundBlock tiles, then of blocks of those,
    /// and so on (the line test's cull reads a disk of many tiles): each the least of its parts.
    struct BoundLevel {
        int width = 0, height = 0;  ///< in blocks
        int tiles = 1;              ///< a block's side, in the bound level's tiles
        std::vector<CasterBounds> bounds;
    };
    static constexpr int kBoundBlock = 4;
    std::vector<BoundLevel> boundLevels_;  ///< the bound level's tiles first
    void buildBoundLevels();
    /// Whether a surface in block (x, y) of bound level `level` may lie in front of a ray of the
    /// line test (nothingCanBlockLines).
    bool blockMayBlock(const LineReceiver& receiver, std::size_t level, int x, int y) const;
    mutable std::atomic<std::uint64_t> tracedTexels_{0};
};

/// The shadow maps of one light, one per area of shadowMapAreas: a receiver takes the map that
/// serves the receivers nearest to it.
class LightShadowMaps {
  public:
    /// The maps of shadowMapAreas(tracer.scene(), light, view): with `view`, for the receivers
    /// its camera rays may meet (others take the nearest map, which may not hold their
    /// blockers). Preconditions and throws: ShadowMap's; `view` is read only here.
    LightShadowMaps(const SceneTracer& tracer, const DirectionalLight& light,
                    int resolutionTexels = ShadowMap::kDefaultResolution,
                    const PinholeProjection* view = nullptr);

    /// ShadowMap::visibility of the map serving receiver.surfaceWorld.
    float visibility(const ShadowReceiver& receiver, ShadowFilter filter, std::uint32_t seed,
                     std::uint64_t& samples) const {
        return mapFor(receiver.surfaceWorld).visibility(receiver, filter, seed, samples);
    }
    /// The map whose receivers' rectangle is nearest to `world` on the light's plane (the first
    /// of equally near ones).
    const ShadowMap& mapFor(const glm::vec3& world) const;

    std::size_t size() const { return maps_.size(); }
    const ShadowMap& operator[](std::size_t index) const { return *maps_[index]; }
    /// Sums of ShadowMap's over the maps.
    std::uint64_t tracedTexels() const;
    std::uint64_t texelCount() const;

  private:
    std::vector<std::unique_ptr<ShadowMap>> maps_;
};

/// Whether `light` reaches any base surface the camera of `scene` sees the front of: a triangle
/// facing the eye with a vertex normal facing the light. When none does, no receiver will ask
/// for the light's shadow map and it need not be built.
bool lightReachesVisibleSurface(const Scene& scene, const DirectionalLight& light);

/// Whether `object`'s base mesh is planar with every vertex normal perpendicular to its plane: its
/// shell is a flat slab, whose detail lies behind the top plane as the light sees it, so it never
/// shadows a receiver on that plane.
bool isFlatSlab(const SceneObject& object);

/// False when no surface of the scene can shadow another one: a single object on a planar base
/// mesh with parallel vertex normals (its shell is a flat slab, whose detail shadows itself only
/// inside the slab, which the self-shadow rays trace). Shadow maps of such a scene hold nothing.
bool sceneCastsShadowsBetweenSurfaces(const Scene& scene);

}  // namespace distile
