/// @file
/// World-space reference renders: every tiled object's detail mapped through its base mesh's
/// curved shell into a world-space mesh (vdb/displaced_level_set.h buildDisplacedMesh) and
/// traced there. Unlike RenderOptions::reference, which marches the analytic detail with the
/// per-pixel planar tangent frame of ch. 8, this follows the curved shell, so comparing an
/// ordinary render with it (render/compare.h) measures the planar approximation's error too.
///
/// Two ways to trace the same mesh: a BVH (Embree 3, triangles and quads in float; the
/// default), or an OpenVDB level set of it traced with OpenVDB's level-set ray intersector
/// (slower, the ground truth the BVH is validated against). Either hit, a fraction of a texel
/// off the detail (the mesh is extracted at one sample per texel), is then refined in double
/// precision along the ray onto the exact detail surface: the first zero of the detail's
/// distance (analytic, else the tile's trilinear one, clipped to the shell as the mesh is) at the
/// ray's point mapped into the shell (common/shell_map.h), within 1.5 texels of the hit, to 1e-4
/// texel; its normal is that distance's gradient carried to world space by the map's Jacobian.
/// As in the renderer's tracer (SceneTracer), a tiled object's base triangle met from behind
/// stops a camera ray (the inside of an open mesh), unless the ray is leaving the shell through
/// its top after entering it through a front face; detail met from below its shell (the
/// underside of a solid floor) is passed through. Both shade as the renderer does
/// (render/shading.h): sky colour for misses, ambient with the renderer's openness term from the
/// hit's texel height, Lambert + Blinn-Phong, albedo at the hit's base-mesh uv, dim back faces,
/// and soft shadows from rays toward each light through the BVH of every object.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/progress.h"
#include "render/renderer.h"
#include "vdb/displaced_level_set.h"

namespace distile {

enum class WorldReferenceMethod {
    Bvh,       ///< the world-space mesh in an Embree BVH
    LevelSet,  ///< hits and normals from an OpenVDB level set of the same mesh
};

struct WorldReferenceOptions {
    int width = 1280;
    int height = 1024;
    bool outputAovs = false;  ///< depth, normal and texel scale (the layers distile compare reads)
    WorldReferenceMethod method = WorldReferenceMethod::Bvh;
    /// The mesh (both methods) and, for WorldReferenceMethod::LevelSet, the level set.
    DisplacedLevelSetOptions levelSet;
    /// Shadow rays per light and pixel, spread over the light's disk (angle_deg), in [1, 256].
    int shadowSamples = 16;
};

/// The tile renderer's settings a world reference does not read, by the `distile render` flag
/// that sets each, without its dashes (the Python module's keyword: the same with '_' for '-'):
/// the command and the module refuse them beside a world reference, as kWorldReferenceReads says.
inline constexpr const char* kSettingsAWorldReferenceIgnores[] = {
    "spp",           "iterations", "epsilon", "march",      "relaxation", "filter",
    "normal-filter", "shell",      "shadows", "no-shadows", "no-skip"};
/// What a world reference does instead, for the message that refuses one of them.
inline constexpr const char* kWorldReferenceReads =
    "traces the detail as a world-space mesh (exact hits, one ray per pixel, 16 shadow rays per "
    "light)";

/// The AOVs (render/render_files.h kAovFiles) a world reference fills: what `distile compare`
/// reads. Its other AOVs are black.
inline constexpr const char* kWorldReferenceAovs[] = {"depth", "normal", "texel_scale"};

struct WorldReferenceResult {
    /// The image, shaded as the file note says. AOVs, when requested: depth and normal as
    /// RenderAovs holds them (a back face's normal is its base normal, unflipped, as the
    /// renderer's); texelScale is 0 everywhere (compareRenders then takes the other
    /// render's); the other AOVs are black. Stats: rays and baseHits (rays that hit anything),
    /// converged = baseHits.
    RenderResult render;
    std::vector<DisplacedMeshStats> meshes;         ///< one per tiled object, in scene order
    std::vector<DisplacedLevelSetStats> levelSets;  ///< the same, WorldReferenceMethod::LevelSet
    double meshSeconds = 0.0;                       ///< building the world-space meshes (wall time)
    double levelSetSeconds = 0.0;  ///< building the level sets (WorldReferenceMethod::LevelSet)
    double bvhSeconds = 0.0;       ///< building the BVH
    double traceSeconds = 0.0;     ///< tracing and shading the pixels
    std::size_t bvhBytes = 0;      ///< memory Embree allocated for the BVH and its buffers
    /// Camera rays whose detail hit was moved onto the exact detail surface, and those whose hit
    /// stayed on the traced mesh or level set (the refinement left its bracket, did not
    /// converge, or had no base triangle to start from).
    std::uint64_t refinedHits = 0;
    std::uint64_t unrefinedHits = 0;
    std::uint64_t backFaceStops = 0;  ///< camera rays stopped by a tiled base triangle's back face
};

/// Renders `scene` against world-space meshes of its tiled objects: one camera ray per pixel
/// through its centre (as the first sample of a 1-spp render). The detail is each material's
/// analyticDistance when it has one, else its tile (trilinear). Objects without a tile are
/// traced as their bare base meshes. Deterministic for any thread count. `progress` is called
/// on the calling thread after each mesh, after the BVH and after each band of rows (the build
/// counts as the first 60%).
/// @throws InputError an invalid scene (validateScene), size (width/height in [1, 16384]),
///         shadowSamples not in [1, 256], or mesh or level-set options (buildDisplacedMesh,
///         DisplacedLevelSet::build), naming the object.
/// @throws std::runtime_error Embree failed (out of memory, among others).
WorldReferenceResult renderWorldReference(const Scene& scene, const WorldReferenceOptions& options,
                                          const ProgressCallback& progress = {});

}  // namespace distile
