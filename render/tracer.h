/// @file
/// Nearest-hit queries against a scene's displaced detail: the base-mesh visibility (where a ray
/// enters a detail shell) followed by the ch. 8 march in the tile's texel space. Used for camera
/// rays by the renderer and for light rays by shadow maps; shading lives in renderer.cpp.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "common/shell_map.h"
#include "render/bvh.h"
#include "render/march.h"
#include "render/scene.h"
#include "render/shell_march.h"
#include "sampler/filter_choice.h"
#include "sampler/occupancy.h"

namespace distile {

/// Work left out where a scene does not need it. Every switch is on by default and exists to
/// measure its skip (`distile bench --speed`): off does the work anyway.
struct RenderSkips {
    /// Empty-space skipping: a ray starts its march where it first reaches the top of the
    /// occupied layers of the tile columns it crosses (sampler/occupancy.h), not at the top face.
    bool emptySpace = true;
    /// Camera rays skip detail shells whose conservative depth is not nearer than their best hit
    /// (render/coverage.h); the image is the same either way, only the work differs.
    bool shellCulling = true;
    /// No shadow work (self-shadow march, shadow-map lookups) for a light the detail's shading
    /// normal faces away from: its direct light is zero anyway.
    bool unlitShadows = true;
    /// No shadow maps when no surface can shadow another (render/shadow_map.h
    /// sceneCastsShadowsBetweenSurfaces: one flat object); self-shadows are traced as ever.
    bool casterlessShadowMaps = true;
};

/// One switch of RenderSkips: its name (`distile render --no-skip NAME`, the speed report's
/// rows), the field, and the work it leaves out.
struct RenderSkipSwitch {
    const char* name;
    bool RenderSkips::*enabled;
    const char* skipped;
};

/// Every RenderSkips switch, once.
inline constexpr RenderSkipSwitch kRenderSkipSwitches[] = {
    {"empty-space", &RenderSkips::emptySpace,
     "the march through the empty layers above the tile columns' occupied top"},
    {"shell-culling", &RenderSkips::shellCulling,
     "shells whose conservative depth is behind the pixel's best hit"},
    {"unlit-shadows", &RenderSkips::unlitShadows,
     "shadow rays and shadow-map lookups toward lights the normal faces away from"},
    {"casterless-shadow-maps", &RenderSkips::casterlessShadowMaps,
     "shadow maps of a scene where no surface can shadow another (one flat object)"},
};
static_assert(sizeof(RenderSkips) == std::size(kRenderSkipSwitches) * sizeof(bool),
              "every RenderSkips field must be a bool listed in kRenderSkipSwitches");

/// How rays go through the shell of a curved base (one whose vertex normals differ over a
/// triangle; flat faces always take the planar march, which is exact there).
enum class ShellMapping {
    /// Follow the shell map (common/shell_map.h) prism by prism (render/shell_march.h): the
    /// default.
    Curved,
    /// Ch. 8's planar approximation: the ray mapped into texel space once, with the frame at its
    /// entry, and marched straight. Kept to measure what the curved march costs and buys.
    Planar,
};

inline constexpr ShellMapping kShellMappings[] = {ShellMapping::Curved, ShellMapping::Planar};

/// "curved", "planar": the names of the command line.
inline const char* shellMappingName(ShellMapping mapping) {
    return mapping == ShellMapping::Curved ? "curved" : "planar";
}

/// Curved shells: a ray's budget is this many times MarchSettings::maxIterations (SceneTracer: a
/// grazing ray bends along the shell for many texels). 64
/// samples at the default budget: 128 made the demo's whole process 9% slower (medians of 7
/// interleaved runs, 1.19 s against 1.09 s) for an interior error of 0.017 texel against 0.027 on
/// the torus on the sheet (its world reference), both far inside what the shell map needs.
inline constexpr int kCurvedBudgetScale = 2;

struct TraceOptions {
    MarchSettings march;  ///< method, budget per ray (ch. 8 uses 8 to 16) and hit threshold
    FilterKind filter = FilterKind::Trilinear;  ///< the march's distances (must not overestimate)
    /// The shading normal's gradient at the hit; the B-spline's is smooth (ch. 20).
    FilterKind normalFilter = FilterKind::TricubicBSpline;
    /// March and normals on each material's analyticDistance instead of its tile (reference
    /// renders, render/analytic_filter.h), or hits and normals from its exactHit when it has one.
    /// Precondition: every tiled material has an analyticDistance.
    bool reference = false;
    RenderSkips skips;
    ShellMapping shellMapping = ShellMapping::Curved;
};

/// The base surface where a ray enters an object's detail shell, with the linear map between
/// world directions and the tile's texel space there (the per-pixel tangent frame, ch. 8). For a
/// ray through a curved shell (ShellMapping::Curved) it is taken where the ray ends instead: the
/// base point above the hit (position, normal, uv) and the shell map's Jacobian there.
struct ShellEntry {
    glm::vec3 position;   ///< on the base surface, world units
    glm::vec3 normal;     ///< N, unit, outward
    glm::vec3 tangent;    ///< T, unit, along +u
    glm::vec3 bitangent;  ///< B, unit, along +v
    glm::vec2 uv;
    glm::vec3 texelsPerWorld;  ///< scale of the T, B, N components into texels
    bool frontFacing = true;
    /// Curved shells: texel = texelFromWorld * world (d texel / d world of the shell map), used by
    /// toTexel and gradientToWorld instead of the frame.
    bool curved = false;
    glm::mat3 texelFromWorld{1.0f};

    glm::vec3 toTexel(const glm::vec3& world) const;
    /// A texel-space gradient as a world-space normal direction (not normalised).
    glm::vec3 gradientToWorld(const glm::vec3& gradient) const;
};

/// The nearest surface along a ray.
struct SurfaceHit {
    std::uint32_t object = 0;
    float distanceWorld = 0.0f;  ///< from the ray origin to the hit
    glm::vec3 position{0.0f};    ///< world units
    glm::vec3 normal{0.0f};      ///< shading normal, unit, world space
    ShellEntry entry;            ///< where the ray entered the shell
    bool onDetail = false;       ///< false: the bare base surface (no tile) or a back face
    MarchResult march;           ///< valid when onDetail
    /// Texels per world unit along the ray in the shell's texel space (from the entry's frame);
    /// 0 when the ray did not enter a tile (bare base surface, back face).
    float texelsPerWorldAlongRay = 0.0f;
    /// A hit in a curved shell (entry.curved): the prism it lies in and its point there
    /// (march.texelPosition is in that prism's texel space).
    std::uint32_t shellPrism = 0;
    PrismPoint shellPoint;
    /// A ray into a flat shell of a mesh with an open border: the shell it entered (through its
    /// top or a side), and a lower bound of the distance from that entry to the border (world
    /// units); +infinity for every other ray (SceneTracer::selfShadowTopTexels).
    std::uint32_t entryShell = 0;
    float entryBorderClearanceWorld = std::numeric_limits<float>::infinity();
};

/// A ray that entered a detail shell, between SceneTracer::enterShell and finishShell: its entry
/// and its march in the tile's texel space, both taken by marchShells (several at once).
struct ShellMarch {
    std::uint32_t object = 0;
    TriangleHit baseHit;       ///< where the ray met the shell's top
    const Ray* ray = nullptr;  ///< the ray, and the hit its entry goes into (enterShell's)
    SurfaceHit* hit = nullptr;
    glm::vec3 startTexels{0.0f};  ///< where the march starts (after the skipped empty path)
    glm::vec3 directionTexels{0.0f, 0.0f, -1.0f};  ///< unit in texel space
    float skippedTexels = 0.0f;                    ///< empty path from the top face to startTexels
    /// How far below the top the ray entered (world units): 0 through the top, more through a
    /// side of the prism on an open border of the mesh (SceneTracer::entryFaceCount).
    float entryDepthWorld = 0.0f;
    /// Travel from startTexels at which the ray leaves the shell through an open border of the
    /// base mesh (+infinity: not before the floor); the march ends there without a hit.
    float leaveTravelTexels = std::numeric_limits<float>::infinity();
    MarchSettings settings;        ///< the tracer's, with this ray's budget
    detail::SphereTraceRay trace;  ///< the sphere-tracing methods' state
    bool marched = false;          ///< result is final (exact reference hits are known at entry)
    MarchResult result;
    /// The texel-space gradient finishShell turns into the normal, when known before it: the
    /// unit normal of an exact reference hit, or the normal filter's gradient taken for several
    /// rays at once (marchShells).
    glm::vec3 gradientTexels{0.0f};
    bool gradientKnown = false;
    /// A march through a curved shell (render/shell_march.h): its result's position is in the
    /// texel space of the prism it ended in, and the distances below replace the entry's.
    bool curved = false;
    /// The curved march, until it ends: working memory of the thread that takes the entry,
    /// valid within one marchShells (or traceNearestBatch) call.
    CurvedMarchRay* curvedTrace = nullptr;
    float endDistanceWorld = 0.0f;  ///< the hit, or where the ray left the shell
    /// Left the shell: the ray crossed its boundary (through the top: the back face of a base
    /// triangle) between these two distances along it.
    float lastInsideWorld = 0.0f, firstOutsideWorld = 0.0f;
};

/// Calls function(key, items) once per distinct key of `keys`, in order of first appearance, with
/// the items (in order) whose key it is: items[i] has keys[i]. Precondition: items and keys of the
/// same size, at most 64.
template <class Item, class Key, class Function>
void forEachGroup(std::span<Item* const> items, std::span<const Key> keys, Function&& function) {
    constexpr std::size_t kMaxItems = 64;
    bool handedOver[kMaxItems] = {};
    Item* sameKey[kMaxItems];
    for (std::size_t first = 0; first < items.size(); ++first) {
        if (handedOver[first]) continue;  // with an earlier item's key
        std::size_t count = 0;
        for (std::size_t index = first; index < items.size(); ++index) {
            if (handedOver[index] || !(keys[index] == keys[first])) continue;
            sameKey[count++] = items[index];
            handedOver[index] = true;
        }
        function(keys[first], std::span<Item* const>(sameKey, count));
    }
}

/// forEachGroup by tile: function(tile, items). Precondition: no null tile.
template <class Item, class Function>
void forEachTile(std::span<Item* const> items, std::span<const TileColumns* const> tiles,
                 Function&& function) {
    forEachGroup(items, tiles, [&](const TileColumns* tile, std::span<Item* const> sameTile) {
        function(*tile, sameTile);
    });
}

/// marchInterleaved over rays that may sample different tiles: rays[i] samples tiles[i] through
/// the filter of `kind`; the rays of one tile are marched together. Each ray ends as it would
/// marched alone. Preconditions: rays and tiles of the same size, no null tile.
template <class Marcher>
void marchInterleavedByTile(FilterKind kind, std::span<Marcher* const> rays,
                            std::span<const TileColumns* const> tiles) {
    constexpr std::size_t kChunk = 64;
    for (std::size_t begin = 0; begin < rays.size(); begin += kChunk) {
        const std::size_t count = std::min(kChunk, rays.size() - begin);
        forEachTile(rays.subspan(begin, count), tiles.subspan(begin, count),
                    [&](const TileColumns& tile, std::span<Marcher* const> sameTile) {
                        withFilter(kind, tile,
                                   [&](const auto& filter) { marchInterleaved(filter, sameTile); });
                    });
    }
}

struct TraceCounters {
    std::uint64_t shellEntries = 0;     ///< rays that entered a detail shell and were marched
    std::uint64_t marchIterations = 0;  ///< sphere-tracing steps
};

namespace detail {

/// Lower bounds of the distance to the open border of an object whose flat shells lie in one
/// plane, per cell of a grid over that plane (render/tracer.cpp): the second cull of the
/// border walks, for the rays the bounds per triangle do not settle.
struct BorderGrid {
    glm::dvec3 origin{0.0}, axisU{0.0}, axisV{0.0};  ///< the plane
    glm::dvec2 low{0.0};                             ///< the grid's corner in the plane
    double cellWorld = 0.0, marginWorld = 0.0;
    int columns = 0, rows = 0;
    std::vector<std::uint16_t> steps;  ///< chessboard cells to the nearest border cell
    /// At most the distance from `point`'s projection onto the plane to the open border; 0
    /// without a grid, or outside it.
    float distanceWorld(const glm::vec3& point) const;
};

}  // namespace detail

class SceneTracer {
  public:
    /// Preconditions: validateScene(scene) passed; `scene` outlives the tracer.
    SceneTracer(const Scene& scene, const TraceOptions& options);

    /// The nearest hit beyond `minDistance`, or false for a miss. Thread-safe.
    bool traceNearest(const Ray& ray, float minDistance, SurfaceHit& hit,
                      TraceCounters& counters) const;

    /// At most this many rays per traceNearestBatch call.
    static constexpr std::size_t kMaxBatchRays = 64;
    /// traceNearest for each of `rays` (at most kMaxBatchRays), their marches taken together
    /// (marchShells interleaves them): `found[i]` and `hits[i]` are what traceNearest gives for
    /// rays[i] alone, bit for bit; the marches are counted in `counters`. With `withNormals`
    /// false the detail's normal is not computed (hits[i].normal stays the base surface's): for
    /// rays that need only where they stop, such as shadow maps'. Thread-safe.
    void traceNearestBatch(std::span<const Ray> rays, float minDistance, std::span<SurfaceHit> hits,
                           std::span<bool> found, TraceCounters& counters,
                           bool withNormals = true) const;

    /// Where `ray`, inside `object` from `fromDistance`, leaves its base mesh: the nearest back
    /// face of `object` beyond `fromDistance` (past at most 16 other triangles), or +infinity
    /// when there is none (an open mesh). Thread-safe.
    float exitDistance(const Ray& ray, float fromDistance, std::uint32_t object) const;

    /// Whether `ray`, from `minDistance`, meets `object`'s base surface first on a front face
    /// nearer than `distanceWorld`. A ray stopped by a back face of `object` at `distanceWorld`
    /// then looks through an opening of its detail (an open floor, between the exits of a curved
    /// shell) at the inside of the far side; otherwise the back face is where the ray comes to
    /// the object first: the sign of a closed mesh wound inside out. Thread-safe.
    bool entersFrontFirst(const Ray& ray, float minDistance, std::uint32_t object,
                          float distanceWorld) const;

    /// The height (texels) at which the self-shadow ray of flat-shell hit `hit` toward
    /// `toLightWorld` (unit) must end: `topTexels`, the shell's top, unless the ray leaves the
    /// shell through an open border of the mesh below it; there is no detail beyond that border.
    /// `startTexels` and `toLightTexels` (unit, rising): the ray in the hit's texel space.
    float selfShadowTopTexels(const SurfaceHit& hit, const glm::vec3& toLightWorld,
                              const glm::vec3& startTexels, const glm::vec3& toLightTexels,
                              float topTexels) const;

    /// Base triangles of all objects, in scene order: shell `s` is the detail shell of one of them.
    std::uint32_t shellCount() const { return std::uint32_t(triangles_.size()); }
    /// Where camera rays enter the detail: face f < shellCount() is shell f's top; the faces
    /// after them are the sides of the shells with detail (flat, or followed by the shell map)
    /// on an open border of their mesh (the edge of a floor plane, a hole, a vase's rim), two
    /// triangles each from the top's edge down to the floor's, through which rays from outside
    /// enter below the top.
    std::uint32_t entryFaceCount() const {
        return shellCount() + std::uint32_t(borderFaces_.size());
    }
    /// The corners of entry face `face`: a shell's top and bottom (shellCorners), or a side's
    /// triangle as both. Precondition: face < entryFaceCount().
    void entryFaceCorners(std::uint32_t face, glm::vec3 top[3], glm::vec3 bottom[3]) const;
    /// True for a side face (not a top) that no ray from `eye` enters: it faces away from it.
    bool entryFaceFacesAway(std::uint32_t face, const glm::vec3& eye) const {
        if (face < shellCount()) return false;
        const BorderFace& border = borderFaces_[face - shellCount()];
        return !(glm::dot(eye - border.corners[0], border.outward) > 0.0f);
    }
    /// World corners of shell `shell`: its top (the base triangle) and its bottom, the top moved
    /// by -N * depthWorld along the vertex normals (equal to the top without a tile).
    /// Precondition: shell < shellCount().
    void shellCorners(std::uint32_t shell, glm::vec3 top[3], glm::vec3 bottom[3]) const;
    /// The scene object whose base triangle shell `shell` is. Precondition: shell < shellCount().
    std::uint32_t shellObject(std::uint32_t shell) const { return triangles_[shell].object; }

    /// A ray against one entry face only (entryFaceCount), in three parts so that several rays'
    /// marches can be taken together (render/coverage.h): enterShell, marchShells, finishShell do
    /// for that face what traceNearest does for the shell it enters.
    /// enterShell: the face (intersectTriangle, as the BVH tests it): true when it is hit in
    /// (minDistance, maxDistance) and the ray enters the tile, with `march` holding where (`ray`
    /// and `hit` must outlive marchShells, which fills `hit` with the entry); false with
    /// `stopped` set when the ray stops on the bare base surface (a top's back face, no tile;
    /// `hit` filled) or cleared for a miss (a side seen from inside is one). Thread-safe.
    bool enterShell(std::uint32_t face, const Ray& ray, float minDistance, float maxDistance,
                    SurfaceHit& hit, ShellMarch& march, bool& stopped) const;
    /// Takes the entries and the marches of `marches` (from enterShell; at most kMaxBatchRays):
    /// the entries of rays into the same flat shell eight at a time where AVX2 allows
    /// (render/detail/entry_wide.h), the marches of several rays interleaved where the march method
    /// allows; the results are those of one ray at a time. Then the normal gradients of the
    /// marches that end on detail, sixteen at a time where the normal filter allows
    /// (BasicTricubicBSplineFilter::gradients): the same values.
    void marchShells(std::span<ShellMarch* const> marches) const;
    /// After marchShells: the march's end into `hit`; true when the ray stops in this shell, false
    /// when it leaves through an open floor. Counts the march in `counters`. Without
    /// `withNormal` the hit keeps the base surface's normal (traceNearestBatch).
    bool finishShell(const Ray& ray, const ShellMarch& march, SurfaceHit& hit,
                     TraceCounters& counters, bool withNormal = true) const;

    /// For rays whose only candidate is `shell` (render/coverage.h: the one shell over their
    /// pixels): enterShell, marchShells and finishShell for each, taken together, the same
    /// results bit for bit. True with `hits`, `found` and `counters` filled when `shell` is a flat
    /// shell with detail whose front every ray meets, marched by sphere tracing on the tiles with
    /// the B-spline's normals; false, with nothing written, otherwise. At most kMaxBatchRays rays.
    bool traceFlatShell(std::uint32_t shell, std::span<const Ray* const> rays,
                        std::span<SurfaceHit> hits, std::span<bool> found,
                        std::span<TraceCounters> counters) const;

    /// Object `object`'s tile in the layout the renderer samples (sampler/tile_columns.h); null
    /// for an object without a tile. Objects sharing a tile share its columns.
    const TileColumns* columns(std::uint32_t object) const { return columns_[object].get(); }

    const Scene& scene() const { return scene_; }
    const TraceOptions& options() const { return options_; }

    /// What the user should know about the scene as traced, one line each, naming the object: a
    /// curved shell deeper than its base's radius of curvature folds (its largest safe depth).
    const std::vector<std::string>& warnings() const { return warnings_; }
    /// The shell map of every shell (empty without a curved one): the prisms that the hits of
    /// curved shells (SurfaceHit::shellPrism) lie in.
    const ShellPrisms& shellPrisms() const { return shellPrisms_; }

  private:
    struct ShellTriangle {
        std::uint32_t object;
        std::uint32_t localTriangle;
        glm::vec2 texelsPerWorldUv;  ///< texels per world unit along T and B (0: degenerate UVs)
        glm::vec3 geometricNormal;   ///< (p1 - p0) x (p2 - p0), not normalised
        DoubleTriangle top;          ///< the base triangle, for intersectTriangle
        /// A tile over non-degenerate UVs (texelsPerWorldUv is 0 without a tile): a front-facing
        /// ray enters the detail here.
        bool hasDetail() const { return texelsPerWorldUv.x != 0.0f; }
        /// A ray along `direction` meets the front of the base triangle.
        bool frontFacing(const glm::vec3& direction) const {
            return glm::dot(geometricNormal, direction) < 0.0f;
        }
        /// The corners share one normal and tangent (a flat face of a flat mesh): the frame is
        /// the same at every point, computed once (frameNormal, frameTangent, frameBitangent).
        bool flatFrame = false;
        glm::vec3 frameNormal{0.0f}, frameTangent{0.0f}, frameBitangent{0.0f};
        /// Rays entering here follow the shell map (ShellMapping::Curved on a shell that is not
        /// flat).
        bool curved = false;
        /// A flat shell a ray enters the detail of: one the border walk crosses.
        bool flatWithDetail() const { return flatFrame && hasDetail(); }
    };
    /// What the border walk (borderExitWorld) and its cull keep of a flat shell: the object's
    /// triangles across its sides (ShellPrisms::kNoNeighbour: an open border), side i opposite
    /// corner i. The sides' planes (through the base edges along the normal) are found from the
    /// mesh as the walk crosses them (flatSidePlane). Kept for every triangle of such an object,
    /// set for those whose shell is flat with detail (a march walking into another stops
    /// looking).
    struct FlatSides {
        std::uint32_t neighbour[3];
        /// The triangle's heights over its sides (from the opposite corners), world units: a
        /// point with barycentrics b lies b[i] x height[i] from side i.
        float height[3];
        /// At most the distance from any point of the triangle to the object's open border,
        /// world units (0: not known; buildBorders): a path shorter than this cannot leave.
        float borderDistanceWorld = 0.0f;
    };
    /// A side of a shell's prism on an open border, one of its two triangles: the top's edge
    /// (corners 0, 1 of the first, 0 of the second) and the floor's below it (a curved shell's
    /// bilinear side, approximately).
    struct BorderFace {
        DoubleTriangle triangle;
        glm::vec3 corners[3];
        glm::vec3 outward;    ///< unit, away from the prism
        std::uint32_t shell;  ///< the flat shell whose side it is
        std::uint8_t side;    ///< opposite corner `side` of the shell's triangle
    };
    /// Appends the two triangles of side `side` (opposite that corner) of shell `shell` to
    /// borderFaces_ (those with area).
    void addBorderFaces(std::uint32_t shell, int side);
    /// The ray's entry through border face `face` (an index into borderFaces_) at `distanceWorld`
    /// along it: false (a miss) when it comes from inside, or does not descend into a flat shell.
    bool enterSide(const Ray& ray, std::uint32_t face, float distanceWorld, SurfaceHit& hit,
                   ShellMarch& march) const;
    /// The nearest entry of `ray` through a border face in (minDistance, maxDistance), its march
    /// set up as enterSide's; false when there is none.
    bool enterNearestSide(const Ray& ray, float minDistance, float maxDistance, SurfaceHit& hit,
                          ShellMarch& march) const;
    /// Fills `entry` (in place: the hit's own, no temporary) for the ray's hit on a shell's top.
    void shellEntry(const TriangleHit& hit, const Ray& ray, ShellEntry& entry) const;
    /// marchShells' three parts: the entries, the marches, then the normal gradients.
    void takeEntries(std::span<ShellMarch* const> marches) const;
    void takeMarches(std::span<ShellMarch* const> marches) const;
    /// takeMarches' interleaved sphere traces for marches on one tile (those not marched yet).
    void takeMarchesOnTile(const TileColumns& tile, std::span<ShellMarch* const> marches) const;
    void takeGradients(std::span<ShellMarch* const> marches) const;
    /// takeGradients for marches on one tile: those that end on detail without a gradient yet,
    /// sixteen at a time.
    static void takeGradientsOnTile(const TileColumns& tile, std::span<ShellMarch* const> marches);
    /// The shell the ray enters at `baseHit`: false when the ray stops on the base surface (`hit`
    /// filled), true with `march` holding the ray, its hit and `baseHit` for takeEntries.
    bool enterAt(const Ray& ray, const TriangleHit& baseHit, SurfaceHit& hit,
                 ShellMarch& march) const;
    /// enterAt's set-up of `march` for a ray entering the shell of `baseHit`, without its checks.
    void startMarch(const Ray& ray, const TriangleHit& baseHit, SurfaceHit& hit,
                    ShellMarch& march) const;
    /// `hit` as the ray's stop on the base surface at `baseHit` (no march).
    void baseSurfaceHit(const Ray& ray, const TriangleHit& baseHit, SurfaceHit& hit) const;
    /// baseSurfaceHit for a hit whose entry is already set: the rest from it, its `position` and
    /// `normal` passed in (read back from the entry just written, they would wait for its stores).
    void atEntry(const TriangleHit& baseHit, const glm::vec3& position, const glm::vec3& normal,
                 SurfaceHit& hit) const;
    /// The entry of one ray (takeEntries): its hit's entry and its march set up.
    void takeEntry(ShellMarch& march) const;
    /// The entries of rays (at least one) into the same flat shell, eight at a time
    /// (enterFlatShell8).
    void takeFlatEntries(std::span<ShellMarch* const> sameShell) const;
    /// Sets up `march` from its start with the march settings: a refused march's result, or the
    /// sphere trace's start. `sides`: flatSidesOf its shell.
    void beginMarch(ShellMarch& march, const FlatSides* sides) const;
    /// Whether takeFlatEntries takes the entries of rays into shell `shell`.
    bool entersFlatShell(std::uint32_t shell) const;
    /// The entry of a ray into a curved shell: its march started (render/shell_march.h) in
    /// `trace`, working memory that must outlive the march.
    void takeCurvedEntry(ShellMarch& march, CurvedMarchRay& trace) const;
    /// The curved marches among `marches` (takeMarches), interleaved by tile.
    void takeCurvedMarches(std::span<ShellMarch* const> marches) const;
    /// A curved march's end into its ShellMarch and its hit's frame.
    void finishCurvedMarch(ShellMarch& march) const;
    /// The prisms of every shell and their neighbours, warnings about folds.
    void buildShellMap();
    /// The open borders: flatSides_, flatSidesFirst_ and borderGrids_ for the objects whose flat
    /// shells have one, borderFaces_ and borderBvh_ for every shell with detail on one. After
    /// buildShellMap, whose neighbours it takes for objects that have curved shells.
    void buildBorders();
    static constexpr std::uint32_t kNoShell = 0xffffffffU;
    /// Where a straight path leaves the flat shells through an open border, or the shell it ends
    /// over (borderExitWorld).
    struct BorderWalk {
        double exitWorld = std::numeric_limits<double>::infinity();  ///< +infinity: not left
        std::uint32_t endShell = kNoShell;  ///< when not left: the shell at its end, if known
    };
    /// The path from `origin` along `direction` (unit) through flat shell `shell`, where it
    /// leaves through an open border of the mesh before `endWorld` along it (world distance),
    /// walking on across the sides into neighbouring flat shells; or, when it does not, the
    /// shell it is over at `endWorld`. Neither when the walk reaches a shell that is not flat or
    /// goes on past kMaxBorderWalk of them.
    BorderWalk borderExitWorld(const glm::dvec3& origin, const glm::dvec3& direction,
                               std::uint32_t shell, double endWorld) const;
    /// A guard against walking on forever (a ray along a side, rounding): far more shells than a
    /// ray crosses on its way to the floor of any mesh that renders in reasonable time.
    static constexpr int kMaxBorderWalk = 1 << 14;
    /// Where the march of `march` (a flat or planar shell's) leaves its shell through an open
    /// border, in texels of travel from its start (ShellMarch::leaveTravelTexels). `sides`:
    /// flatSidesOf its shell, taken once for the rays of a shell.
    /// Precondition: setBorderExit's clearance in the march's hit.
    float leaveTravelTexels(const ShellMarch& march, const FlatSides* sides) const;
    /// The march's leaveTravelTexels, and its hit's entryShell and entryBorderClearanceWorld (a
    /// lower bound of the entry's distance to the open border; +infinity without `sides`, as
    /// atEntry, which must have filled the hit, left it).
    void setBorderExit(ShellMarch& march, const FlatSides* sides) const;
    /// The FlatSides of shell `shell` when it is a flat shell of an object with an open border;
    /// null when no ray through it can leave by a border.
    const FlatSides* flatSidesOf(std::uint32_t shell) const;

    const Scene& scene_;
    TraceOptions options_;
    std::vector<ShellTriangle> triangles_;
    /// Per object: its tile's empty space for the march's filter and threshold; null when not
    /// skipped (no tile, skip off, a reference render, or a Catmull-Rom march filter).
    std::vector<std::shared_ptr<const TileOccupancy>> occupancies_;
    std::vector<std::shared_ptr<const TileColumns>> columns_;  ///< per object; null: no tile
    TriangleBvh bvh_;
    /// Per shell: its prism (the shell map) and the shells across its side faces (those of curved
    /// shells only; empty without any).
    std::vector<ShellPrism> prisms_;
    std::vector<std::array<std::uint32_t, 3>> neighbours_;
    std::vector<std::array<std::uint8_t, 3>> neighbourCorners_;
    ShellPrisms shellPrisms_;  ///< views of the three above
    /// Per object: where its triangles' FlatSides start in flatSides_ (by local triangle), or
    /// kNoFlatBorder when none of its flat shells has an open border.
    std::vector<std::uint32_t> flatSidesFirst_;
    static constexpr std::uint32_t kNoFlatBorder = 0xffffffffU;
    std::vector<FlatSides> flatSides_;
    std::vector<detail::BorderGrid> borderGrids_;  ///< per object (empty for most)
    std::vector<BorderFace> borderFaces_;          ///< of every flat shell, in shell and side order
    TriangleBvh borderBvh_;  ///< over borderFaces_, for the rays of the BVH path
    std::vector<std::string> warnings_;
};

// enterShell and enterAt inline: they run for every camera ray's shell, most of them a plain hit.

inline bool SceneTracer::enterShell(std::uint32_t face, const Ray& ray, float minDistance,
                                    float maxDistance, SurfaceHit& hit, ShellMarch& march,
                                    bool& stopped) const {
    stopped = false;
    double distance = 0.0, b1 = 0.0, b2 = 0.0;
    if (face >= shellCount()) {
        const std::uint32_t side = face - shellCount();
        return intersectTriangle(ray, borderFaces_[side].triangle, minDistance, maxDistance,
                                 distance, b1, b2) &&
               enterSide(ray, side, float(distance), hit, march);
    }
    if (!intersectTriangle(ray, triangles_[face].top, minDistance, maxDistance, distance, b1, b2))
        return false;
    if (enterAt(ray, {face, float(distance), b1, b2}, hit, march)) return true;
    stopped = true;
    return false;
}

inline bool SceneTracer::enterAt(const Ray& ray, const TriangleHit& baseHit, SurfaceHit& hit,
                                 ShellMarch& march) const {
    const ShellTriangle& shell = triangles_[baseHit.triangle];
    // A back face, or a base surface without detail, stops the ray.
    if (!shell.frontFacing(ray.direction) || !shell.hasDetail()) {
        baseSurfaceHit(ray, baseHit, hit);
        hit.march = MarchResult{};  // not marched (the hit may be working memory of a batch)
        return false;
    }
    startMarch(ray, baseHit, hit, march);
    return true;
}

inline void SceneTracer::startMarch(const Ray& ray, const TriangleHit& baseHit, SurfaceHit& hit,
                                    ShellMarch& march) const {
    march.object = triangles_[baseHit.triangle].object;
    // Field by field: `baseHit` is often a temporary whose fields were just stored one by one, and
    // a copy of the whole would load them as one, waiting for those stores.
    march.baseHit.triangle = baseHit.triangle;
    march.baseHit.distanceWorld = baseHit.distanceWorld;
    march.baseHit.b1 = baseHit.b1;
    march.baseHit.b2 = baseHit.b2;
    march.ray = &ray;
    march.hit = &hit;
    march.marched = false;
    march.gradientKnown = false;
    march.curved = false;
    march.entryDepthWorld = 0.0f;
}

}  // namespace distile
