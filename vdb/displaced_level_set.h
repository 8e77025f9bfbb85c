/// @file
/// A world-space ground truth for detail on curved base meshes: the tile's detail mapped through
/// a base mesh's shell as a world-space polygon mesh (buildDisplacedMesh), which the world
/// reference traces with a BVH (render/world_reference.h), or as an OpenVDB level set of that
/// same mesh (DisplacedLevelSet), traced with OpenVDB's level-set ray intersector.
///
/// Construction: the detail is sampled once on one tile's texel-space lattice (multi-threaded)
/// and its zero isosurface is extracted once for a whole tile (OpenVDB volumeToMesh, the lattice
/// being periodic). The detail is clipped to 0 <= z <= D; a solid floor is a slab 1.5 texels
/// thick below z = 0. Then, for every base triangle, the repeats of that tile mesh that overlap
/// its uv triangle (the tile repeated uvScale times per unit of uv) are clipped to it and mapped
/// with its own barycentrics through the shell (the renderer's, render/tracer.h shellCorners):
/// texel (x, y, z) -> uv = (x / (uvScale.x W), y / (uvScale.y H)) -> barycentrics b in that
/// triangle -> world = sum_i b_i (P_i - N_i depthWorld (1 - z / D)), with P_i the vertex positions
/// and N_i the unit vertex normals. Mapping per triangle, not per uv, makes mirrored and
/// overlapping uv charts right: each triangle carries the detail of its own uv triangle. Points
/// cut on an edge shared by two triangles are mapped along that edge alone, so both sides meet.
/// An edge no other triangle shares (by welded world position, common/position_weld.h: a uv seam
/// is not a border) is an open border: the detail's cross-section there is closed by a wall, so
/// the surface is closed.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <memory>
#include <span>
#include <vector>

#include "common/size3.h"

namespace distile {

namespace detail {
struct BuiltDisplacedLevelSet;
}

/// The base mesh and material of one object, as plain arrays (world units). The uv chart may
/// overlap itself (mirrored UVs): detail is mapped per triangle.
struct DisplacementShell {
    std::span<const glm::vec3> positions;   ///< world units
    std::span<const glm::vec3> normals;     ///< unit outward vertex normals
    std::span<const glm::vec2> uvs;         ///< one per vertex
    std::span<const glm::uvec3> triangles;  ///< indices into the vertex arrays
    glm::dvec2 uvScale{1.0};                ///< tile repeats per unit of u and v
    double depthWorld = 0.05;               ///< shell thickness below the base surface
    bool solidFloor = true;                 ///< z = 0 is solid (else rays pass through holes)
};

struct DisplacedMeshOptions {
    /// Samples per texel of the texel-space lattice the isosurface is extracted from.
    int samplesPerTexel = 1;
    /// The most memory the mesh may take at its peak with a BVH over it, bytes, as estimated
    /// from the base triangles' texel area and the tile's polygons before the mesh is mapped.
    double memoryBudgetBytes = double(std::uint64_t(8) << 30);
    /// Only the estimate: the tile's lattice and isosurface are made and the memory estimated
    /// (stats.tilePolygons, stats.estimatedBytes) and checked, but nothing is mapped (the mesh
    /// is empty), so a caller with several meshes can refuse them all before building one.
    bool estimateOnly = false;
};

/// Figures of a mesh build, for reports (wall times in seconds).
struct DisplacedMeshStats {
    double texelSizeWorld = 0.0;   ///< median over the base triangles of sqrt(world / texel area)
    std::size_t tilePolygons = 0;  ///< of the one texel-space tile mesh
    std::size_t borderEdges = 0;   ///< base-mesh edges closed by a wall
    std::size_t meshVertices = 0;
    std::size_t meshPolygons = 0;  ///< triangles and quads of the world-space mesh
    double estimatedBytes = 0.0;   ///< the estimate checked against memoryBudgetBytes
    double latticeSeconds = 0.0;   ///< sampling the detail on the tile lattice
    double extractSeconds = 0.0;   ///< the tile's isosurface (OpenVDB volumeToMesh)
    double mapSeconds = 0.0;       ///< clipping to the base triangles, walls, mapping
};

/// The world-space detail surface of one object: triangles and quads over shared vertices,
/// each vertex with its world and texel position, each polygon with the base triangle whose
/// barycentrics mapped it.
struct DisplacedMesh {
    std::vector<glm::vec3> positions;  ///< world units
    /// Texel space: x, y as the chart's uv times texels per uv (not reduced to one tile), so the
    /// base-mesh uv of a point is (x / (uvScale.x W), y / (uvScale.y H)); z in [0, D] on the
    /// detail (below 0 on the solid floor's slab).
    std::vector<glm::vec3> texelPositions;
    std::vector<glm::uvec3> triangles;
    std::vector<glm::uvec4> quads;
    std::vector<std::uint32_t> triangleBase;  ///< per triangle: its base-mesh triangle
    std::vector<std::uint32_t> quadBase;      ///< per quad: its base-mesh triangle
    DisplacedMeshStats stats;
};

/// Exact (or at least non-overestimating) signed distance of the detail in texels at a
/// texel-space position, periodic in x and y; called concurrently from several threads.
using DetailDistanceFunction = std::function<double(const glm::dvec3& texelPosition)>;

/// The solid floor's slab below z = 0, texels: it closes the floor into a solid of the mesh.
inline constexpr double kFloorSlabTexels = 1.5;

/// The detail distance `detailTexels` at texel height `zTexels` with the shell's clipping applied,
/// the field whose zero set buildDisplacedMesh extracts: the top (z = D of a shell `depthTexels`
/// deep) caps it, and the floor is either solid (a slab kFloorSlabTexels thick below z = 0) or
/// open (nothing below z = 0).
inline double clippedDetailTexels(double detailTexels, double zTexels, double depthTexels,
                                  bool solidFloor) {
    const double field =
        solidFloor ? std::max(std::min(detailTexels, zTexels), -(zTexels + kFloorSlabTexels))
                   : std::max(detailTexels, -zTexels);
    return std::max(field, zTexels - depthTexels);
}

/// Builds the world-space surface of `detail` (tile size `tile`) mapped through `shell`, as the
/// file note describes. Deterministic for any thread count.
/// @throws InputError an invalid tile size, an empty or inconsistent shell (array sizes,
///         indices), non-finite data, uvScale or depthWorld not > 0, samplesPerTexel not in
///         [1, 8], a uv chart whose triangles all have zero uv or world area, a tile lattice of
///         more than 2^31 samples, a chart holding more than 65536 tile repeats, a mesh
///         estimated to need more than options.memoryBudgetBytes (refused before it is mapped),
///         or (unless options.estimateOnly) a detail with no surface inside the shell.
DisplacedMesh buildDisplacedMesh(const DetailDistanceFunction& detail, const Size3& tile,
                                 const DisplacementShell& shell,
                                 const DisplacedMeshOptions& options = {});

struct DisplacedLevelSetOptions {
    DisplacedMeshOptions mesh;
    /// World voxels per world size of one texel (DisplacedMeshStats::texelSizeWorld), in
    /// [0.25, 16]: 2 gives voxels of half a texel. Memory grows as its square. 0 (the default):
    /// kAutomaticVoxelsPerTexel, or where the detail's surface would need more than the 1 GiB
    /// build budget there, the finest that fits it (at least 0.25).
    double voxelsPerTexel = 0.0;
    static constexpr double kAutomaticVoxelsPerTexel = 2.0;
    /// Half width of the world level set's narrow band, voxels.
    float halfBandVoxels = 3.0f;
};

/// Figures of a level-set build, for reports.
struct DisplacedLevelSetStats {
    DisplacedMeshStats mesh;
    double voxelsPerTexel = 0.0;  ///< as built (the automatic choice made)
    double voxelSizeWorld = 0.0;
    std::size_t activeVoxels = 0;
    std::size_t memoryBytes = 0;   ///< of the world level set (OpenVDB's memUsage)
    double levelSetSeconds = 0.0;  ///< OpenVDB mesh to volume (wall time)
};

class DisplacedLevelSet {
  public:
    using DistanceFunction = DetailDistanceFunction;

    /// Builds the world level set of `detail` (tile size `tile`) mapped through `shell`: the
    /// narrow-band level set of buildDisplacedMesh's surface.
    /// @throws InputError as buildDisplacedMesh, and options out of range (voxelsPerTexel 0 or in
    ///         [0.25, 16], halfBandVoxels in [2, 16]) or a band estimated to need more than 1 GiB
    ///         while it builds (the surface's area over the voxel area, times the band's width;
    ///         with voxelsPerTexel 0, only when even 0.25 would).
    static DisplacedLevelSet build(const DistanceFunction& detail, const Size3& tile,
                                   const DisplacementShell& shell,
                                   const DisplacedLevelSetOptions& options = {});

    /// The level set of a mesh built already (buildDisplacedMesh).
    /// @throws InputError as voxelsPerTexel.
    static DisplacedLevelSet build(const DisplacedMesh& mesh,
                                   const DisplacedLevelSetOptions& options = {});

    /// The voxels per texel build(mesh, options) builds at (the automatic choice made), checked
    /// against the 1 GiB build budget without building: a caller with several meshes can refuse
    /// before any level set takes its minutes.
    /// @throws InputError options out of range (as above), an empty mesh, or a band estimated to
    ///         need more than 1 GiB (with voxelsPerTexel 0, only when even 0.25 would).
    static double voxelsPerTexel(const DisplacedMesh& mesh,
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
    explicit DisplacedLevelSet(detail::BuiltDisplacedLevelSet built);
    std::unique_ptr<detail::BuiltDisplacedLevelSet> built_;  ///< its grid (the OpenVDB module's)
};

}  // namespace distile
