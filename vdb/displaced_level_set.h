/// @file
/// A world-space ground truth for detail on curved base meshes: the tile's detail mapped through
/// a base mesh's shell as an OpenVDB level set, and camera rays traced against it with OpenVDB's
/// level-set ray intersector (issue 5: the planar approximation of ch. 8 then has a measured
/// error).
///
/// Construction: the detail is sampled once on one tile's texel-space lattice (multi-threaded),
/// and its zero isosurface is extracted once for a whole tile (OpenVDB volumeToMesh, the lattice
/// being periodic). That tile mesh is placed at every repeat of the tile over the uv footprint of
/// the mesh (the tile repeated uvScale times per unit of uv); only the repeats that meet a wall
/// or the chart's edge are extracted on their own. Every vertex is mapped through the shell and
/// the world-space mesh becomes a narrow-band level set (OpenVDB meshToLevelSet). The shell is
/// the renderer's (render/tracer.h shellCorners): texel (x, y, z) -> uv = (x / (uvScale.x W),
/// y / (uvScale.y H)) -> the base triangle holding that uv, barycentrics b -> world =
/// sum_i b_i (P_i - N_i depthWorld (1 - z / D)), with P_i the vertex positions and N_i the unit
/// vertex normals (linear interpolation, as the shell prism's corners). The detail is clipped to
/// 0 <= z <= D; a solid floor is a slab 1.5 texels thick below z = 0. Where the uv chart does not
/// wrap (a plane's edges, a sphere's poles) the detail is cut by a wall at the chart's edge, so
/// the surface is closed; a chart that wraps (the same position at u and u + 1, or v and v + 1,
/// as the built-in torus and sphere) continues across the seam (seamlessly when uvScale is a
/// whole number along it).
#pragma once

#include <functional>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <span>

#include "common/size3.h"

namespace distile {

/// The base mesh and material of one object, as plain arrays (world units).
/// Precondition of the uv chart: no two triangles overlap in uv (true for the built-in plane,
/// sphere and torus; not for meshes with mirrored UVs, whose detail would be mapped to one of the
/// overlapping triangles only).
struct DisplacementShell {
    std::span<const glm::vec3> positions;   ///< world units
    std::span<const glm::vec3> normals;     ///< unit outward vertex normals
    std::span<const glm::vec2> uvs;         ///< one per vertex
    std::span<const glm::uvec3> triangles;  ///< indices into the vertex arrays
    glm::dvec2 uvScale{1.0};                ///< tile repeats per unit of u and v
    double depthWorld = 0.05;               ///< shell thickness below the base surface
    bool solidFloor = true;                 ///< z = 0 is solid (else rays pass through holes)
};

struct DisplacedLevelSetOptions {
    /// Samples per texel of the texel-space lattice the isosurface is extracted from.
    int samplesPerTexel = 1;
    /// World voxels per world size of one texel (the median over the base triangles of
    /// sqrt(world area / texel area)): 2 gives voxels of half a texel.
    double voxelsPerTexel = 2.0;
    /// Half width of the world level set's narrow band, voxels.
    float halfBandVoxels = 3.0f;
};

/// Figures of a build, for reports.
struct DisplacedLevelSetStats {
    double voxelSizeWorld = 0.0;
    double texelSizeWorld = 0.0;  ///< the median world size of a texel used to choose the voxel
    std::size_t tileCopies = 0;   ///< tile repeats placed from the one shared tile mesh
    std::size_t edgeCopies = 0;   ///< repeats at walls or chart edges, extracted on their own
    std::size_t meshVertices = 0;
    std::size_t meshPolygons = 0;  ///< triangles and quads of the world-space detail mesh
    std::size_t activeVoxels = 0;
    std::size_t memoryBytes = 0;   ///< of the world level set (OpenVDB's memUsage)
    double surfaceSeconds = 0.0;   ///< sampling the tile and placing its copies (wall time)
    double levelSetSeconds = 0.0;  ///< OpenVDB meshToLevelSet (wall time)
    bool wrapsU = false;           ///< the uv chart wraps in u (no wall at its edges)
    bool wrapsV = false;
};

class DisplacedLevelSet {
  public:
    /// Exact (or at least non-overestimating) signed distance of the detail in texels at a
    /// texel-space position, periodic in x and y; called concurrently from several threads.
    using DistanceFunction = std::function<double(const glm::dvec3& texelPosition)>;

    /// Builds the world level set of `detail` (tile size `tile`) mapped through `shell`.
    /// @throws InputError an invalid tile size, an empty or inconsistent shell (array sizes,
    ///         indices), non-finite data, uvScale or depthWorld not > 0, options out of range
    ///         (samplesPerTexel in [1, 8], voxelsPerTexel in (0, 16], halfBandVoxels in [2, 16]),
    ///         a uv chart of zero area, a tile lattice of more than 2^31 samples, or a chart
    ///         holding more than 65536 tile repeats.
    static DisplacedLevelSet build(const DistanceFunction& detail, const Size3& tile,
                                   const DisplacementShell& shell,
                                   const DisplacedLevelSetOptions& options = {});

    DisplacedLevelSet(DisplacedLevelSet&&) noexcept;
    DisplacedLevelSet& operator=(DisplacedLevelSet&&) noexcept;
    ~DisplacedLevelSet();

    /// The first zero crossing along the ray origin + t direction, t in [0, maxDistanceWorld]:
    /// true with `distanceWorld` (t, world units along the unit direction) and `normalWorld` (unit,
    /// the level set's gradient) filled. Thread-safe.
    bool intersect(const glm::dvec3& origin, const glm::dvec3& unitDirection,
                   double maxDistanceWorld, double& distanceWorld, glm::dvec3& normalWorld) const;

    const DisplacedLevelSetStats& stats() const;

  private:
    struct Impl;
    explicit DisplacedLevelSet(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

}  // namespace distile
