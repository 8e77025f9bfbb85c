/// @file
/// Float level sets (and fog volumes) made by other programs (Houdini, Blender, vdb_tool,
/// OpenVDB's Python module), read from any .vdb file with any voxel size and index-to-world
/// transform, and resampled into texel space.
///
/// The source keeps its own world space and units. A placement maps it to the tile's texel space
/// with a uniform scale: texel = scale * world + offsetTexels (TexelPlacement). Index space of the
/// source may be rotated, sheared or scaled non-uniformly: sampling happens in the source's index
/// space (trilinear, OpenVDB's BoxSampler) at the world point of each texel, and the values there
/// are world-unit distances (OpenVDB's level-set convention, whatever the voxel shape), so the
/// uniform scale alone turns them into texels.
///
/// The source's narrow band is often thinner than the tile needs (3 voxels is OpenVDB's default;
/// the tile wants the tile depth). Beyond the band the source holds only its background constant,
/// which is not a distance: there the tile's distances are rebuilt from the surface
/// (surfaceWorld(), bake/vdb_bake.h VdbDistance).
#pragma once

#include <filesystem>
#include <glm/vec3.hpp>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/size3.h"
#include "common/triangle_soup.h"

namespace distile {

namespace detail {
struct ReadVolume;
class VolumeSampler;
}  // namespace detail

/// One grid of a .vdb file, as the file's metadata describes it.
struct VdbGridInfo {
    std::string name;
    std::string valueType;  ///< "float", "vec3s", ...
    std::string gridClass;  ///< "level set", "fog volume", "unknown", ...
};

/// Where the source's world space goes in the tile: texel = scale * world + offsetTexels.
struct TexelPlacement {
    double scale = 1.0;            ///< texels per world unit, finite and > 0
    glm::dvec3 offsetTexels{0.0};  ///< where the world origin goes, texels
};

/// One scalar float grid of a .vdb file and the surface it describes.
class VdbVolume {
  public:
    /// Reads grid `gridName` of `file` (empty: the only float level set of the file).
    /// A level set's surface is its zero crossing, or the crossing of `iso` when given (values
    /// below it inside). Any other float grid (a fog volume) needs `iso`: its surface is where the
    /// value crosses it, inside above it.
    /// @throws InputError the file is missing or not a regular file; `gridName` is not in the file
    /// (the message lists
    ///   the grids); the grid is not a float grid; no grid was named and the file has no float
    ///   level set or several (listed); the grid is not a level set and `iso` is not given; `iso`
    ///   is not finite.
    /// @throws FormatError the file is not a readable .vdb file (truncated, corrupt: its header's
    ///   lengths, counts and offsets are checked against its size before OpenVDB reads it,
    ///   detail::checkVdbHeader); the grid needs more than kInputMemoryBudgetBytes; the grid's
    ///   transform is not finite or not invertible; the grid is empty or has no surface at the
    ///   iso value.
    static VdbVolume read(const std::filesystem::path& file, const std::string& gridName = {},
                          std::optional<double> iso = {});

    VdbVolume(VdbVolume&&) noexcept;
    VdbVolume& operator=(VdbVolume&&) noexcept;
    ~VdbVolume();

    const std::string& gridName() const;
    bool isLevelSet() const;
    double iso() const;  ///< 0 for a level set read without an iso value
    /// World-unit voxel size along the index axes (not equal for a non-uniform transform).
    glm::dvec3 voxelSizeWorld() const;
    /// World-space box of the active voxels' centres (the band of a level set): the region where
    /// trilinear interpolation has voxel values on both sides.
    Bounds3 activeBoundsWorld() const;
    /// World-space box of the surface (the polygonised iso crossing).
    Bounds3 surfaceBoundsWorld() const;
    /// The iso crossing polygonised on the source's voxel lattice (OpenVDB's volumeToMesh, one
    /// vertex per crossed voxel, quads split into triangles), world units; closed wherever the
    /// band is.
    const TriangleSoup& surfaceWorld() const;
    /// The triangles of surfaceWorld() whose box meets `regionWorld`, each cut into equal parts
    /// until no edge is longer than `maxEdgeWorld` (at most 16 x 16 parts), every vertex moved
    /// onto the iso crossing of the source's smooth reconstruction (triquadratic where its 27
    /// voxels are active, else trilinear) by Newton steps along its gradient. Where the surface is
    /// curved this keeps the polygons within a small fraction of a voxel of it; volumeToMesh's
    /// vertices alone cut inside convex parts by up to about diagonal^2 / (8 radius).
    TriangleSoup refinedSurfaceWorld(double maxEdgeWorld, const Bounds3& regionWorld) const;

  private:
    friend class VdbSourceSampler;
    explicit VdbVolume(detail::ReadVolume volume);
    std::unique_ptr<detail::ReadVolume> volume_;  ///< with its grid (the OpenVDB module's)
};

/// The grids of a .vdb file (metadata only). Throws as VdbVolume::read for a missing or
/// unreadable file.
std::vector<VdbGridInfo> listVdbGrids(const std::filesystem::path& file);

/// The source's own values at texel-space positions of a placement: the file's world point of the
/// texel (world = (texel - offsetTexels) / scale), mapped to the source's index space, where
/// trilinear interpolation (OpenVDB's BoxSampler) runs on the voxel lattice whatever its rotation
/// or aspect. Thread-safe (`sample` only reads).
class VdbSourceSampler {
  public:
    /// @throws InputError placement.scale is not finite and > 0, or the offset is not finite.
    VdbSourceSampler(const VdbVolume& volume, const TexelPlacement& placement);
    VdbSourceSampler(VdbSourceSampler&&) noexcept;
    ~VdbSourceSampler();

    struct Sample {
        /// A level set's distance (value minus iso, times the scale), texels; for any other grid
        /// (iso minus value) times the scale, which is not a distance.
        double valueTexels = 0.0;
        /// Inside the surface: below the iso value for a level set, above it otherwise.
        bool inside = false;
        /// All eight voxels of the trilinear stencil are active: for a level set, `valueTexels`
        /// interpolates the file's distances (not its background).
        bool inBand = false;
    };
    Sample sample(const glm::dvec3& texelPosition) const;

    /// A level set's half band less the iso offset, in texels: how far from the surface its values
    /// are distances, the smaller of its background and its largest stored value, less |iso|,
    /// times the scale; 0 for other grids.
    double bandTexels() const;
    bool isLevelSet() const;

  private:
    std::unique_ptr<detail::VolumeSampler> sampler_;  ///< the OpenVDB module's
    bool levelSet_ = true;
};

/// Test and example volumes: a sphere of `radiusWorld` around `centreWorld`, as a level set
/// (OpenVDB's createLevelSetSphere, half band `halfWidthVoxels`) or, with `fog`, as a fog volume
/// (1 inside, 0 outside, a linear ramp across the band; surface at 0.5), in a grid named
/// `gridName` with voxel size `voxelSizeWorld` and its index axes rotated by `rotationDegrees`
/// about x, then by as much about y (world positions are unchanged: only the voxel lattice turns).
/// Written to `file` (overwritten), one grid per sphere, in order.
struct SphereVolumeOptions {
    double radiusWorld = 1.0;
    glm::dvec3 centreWorld{0.0};
    double voxelSizeWorld = 0.1;
    double rotationDegrees = 0.0;
    float halfWidthVoxels = 3.0f;
    /// A level set's background (what reads back beyond its band), world units; 0: the band's
    /// half width, as OpenVDB's tools make it.
    double backgroundWorld = 0.0;
    bool fog = false;
    std::string gridName = "surface";
};
void writeSphereVolumes(const std::filesystem::path& file,
                        const std::vector<SphereVolumeOptions>& spheres);
inline void writeSphereVolume(const std::filesystem::path& file,
                              const SphereVolumeOptions& sphere) {
    writeSphereVolumes(file, {sphere});
}

}  // namespace distile
