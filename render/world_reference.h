/// @file
/// World-space reference renders (issue 5): every tiled object's detail mapped through its base
/// mesh's shell as an OpenVDB level set (vdb/displaced_level_set.h) and traced with OpenVDB's
/// level-set ray intersector. Unlike RenderOptions::reference, which marches the analytic detail
/// with the per-pixel planar tangent frame of ch. 8, this follows the curved shell, so comparing
/// an ordinary render with it (render/compare.h) measures the planar approximation's error too.
#pragma once

#include <vector>

#include "common/progress.h"
#include "render/renderer.h"
#include "vdb/displaced_level_set.h"

namespace distile {

struct WorldReferenceOptions {
    int width = 1280;
    int height = 1024;
    bool outputAovs = false;  ///< depth, normal and texel scale (the layers distile compare reads)
    DisplacedLevelSetOptions levelSet;
};

struct WorldReferenceResult {
    /// The image is a Lambert shading of the hit normals under the scene's lights (no shadows).
    /// AOVs, when requested: depth and normal as RenderAovs holds them; texelScale is 0 everywhere
    /// (compareRenders then takes the other render's); the other AOVs are black.
    /// Stats: rays and baseHits (rays that hit anything), converged = baseHits.
    RenderResult render;
    std::vector<DisplacedLevelSetStats> levelSets;  ///< one per tiled object, in scene order
    double buildSeconds = 0.0;                      ///< building the level sets (wall time)
};

/// Renders `scene` against world-space level sets of its tiled objects: one camera ray per pixel
/// through its centre (as the first sample of a 1-spp render). The detail is each material's
/// analyticDistance when it has one, else its tile (trilinear). Objects without a tile are traced
/// as their bare base meshes. Deterministic for any thread count.
/// @throws InputError an invalid scene (validateScene), size (width/height in [1, 16384]) or
///         level-set options (DisplacedLevelSet::build).
WorldReferenceResult renderWorldReference(const Scene& scene, const WorldReferenceOptions& options,
                                          const ProgressCallback& progress = {});

}  // namespace distile
