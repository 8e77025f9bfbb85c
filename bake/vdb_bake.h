/// @file
/// Baking a level set made elsewhere (a .vdb file read as vdb/vdb_volume.h VdbVolume) into a
/// tile: placed in texel space, resampled at every voxel of the tile's level set, then resampled
/// into the tile as every bake is (bake/resample.h).
///
/// Nothing is wrapped: the tile holds the volume where its texels land. For a repeating tile give
/// one period of a larger volume as the window; the bake measures how well the window's opposite
/// faces agree (the seam mismatch) and leaves the verdict to the caller.
#pragma once

#include <glm/vec2.hpp>
#include <memory>
#include <optional>
#include <string>

#include "bake/bake.h"
#include "bake/soup_distance.h"
#include "vdb/vdb_volume.h"

namespace distile {

/// Where the volume goes in the tile (texel = scale * world + offsetTexels).
/// - Fit (default): the world box of the surface fitted as bake/bake.h fitToFootprint does.
/// - Explicit: `scale` and `offsetTexels` as given.
/// - Window: `windowWorld` is one period of the volume: its x/y extent maps exactly onto the
///   footprint (so its x/y aspect must be the tile's), its bottom onto the floor z = 0; its
///   height must fit in the tile depth.
struct VdbPlacement {
    enum class Mode { Fit, Explicit, Window };
    Mode mode = Mode::Fit;
    double scale = 1.0;            ///< Explicit: texels per world unit, > 0
    glm::dvec3 offsetTexels{0.0};  ///< Explicit: where the world origin goes, texels
    Bounds3 windowWorld;           ///< Window: world box, min < max on every axis
};

/// Signed distances of a placed VdbVolume at texel-space positions, texels, clamped to
/// +-halfBandTexels: what the tile of bakeVdb holds at its texel centres.
/// - A level set whose band covers halfBandTexels: its own values (VdbSourceSampler, trilinear).
/// - Otherwise the band is rebuilt, not extrapolated: the exact distance (double precision,
///   bake/soup_distance.h) to the source's surface, polygonised, cut into triangles no longer than
///   kVdbSurfaceEdgeTexels and moved onto the iso crossing of the source's triquadratic
///   reconstruction (VdbVolume::refinedSurfaceWorld), placed in texel space; signed by the source
///   (inside below the iso value for a level set, above it otherwise). It is used at every texel,
///   also within the source's band: against an exact torus it errs less than the file's trilinear
///   values do (docs/pipeline.md gives the figures).
/// Positions farther than halfBandTexels + 1 from the tile's box [0,W] x [0,H] x [0,D] hold the
/// clamped value with the source's sign. Thread-safe.
/// The rebuilt surface's longest edge, texels: the chord of a 2-texel edge lies within
/// 2^2 / (8 R) texel of a surface of radius R texels (0.05 for R = 10).
inline constexpr double kVdbSurfaceEdgeTexels = 2.0;

class VdbDistance {
  public:
    /// @throws InputError placement.scale is not finite and > 0, the offset is not finite, or
    ///   halfBandTexels is not in [1, 1024].
    VdbDistance(const VdbVolume& volume, const TexelPlacement& placement, const Size3& tile,
                float halfBandTexels);

    double distanceTexels(const glm::dvec3& texelPosition) const;
    /// distanceTexels starting the rebuilt distance's search from `hint` (the same result, found
    /// sooner for a point near the last one).
    double distanceTexels(const glm::dvec3& texelPosition, SoupDistance::NearestHint& hint) const;
    /// True when the band was rebuilt (the source band is thinner than halfBandTexels or the
    /// source is not a level set).
    bool rebuilt() const { return rebuilt_; }

  private:
    VdbSourceSampler source_;
    Size3 tile_;
    double halfBandTexels_;
    bool rebuilt_ = false;
    /// The placed surface near the tile; null when not rebuilt or nothing is near.
    std::shared_ptr<const SoupDistance> surface_;
};

struct VdbBakeResult {
    BakeResult bake;
    TexelPlacement placement;  ///< the placement used (fit and window resolved)
    /// Window only: the largest |d(x = 0) - d(x = W)| over the texel rows of the faces x = 0 and
    /// x = W of the tile (y likewise), texels.
    std::optional<glm::dvec2> seamMismatchTexels;
    bool rebuilt = false;  ///< the surface was rebuilt beyond the source band (vdb/vdb_volume.h)
};

/// Bakes `volume` placed by `placement`; the tile's provenance is source "vdb" with params
/// {"file": fileName, "grid", "placement", "scale", "offset" [, "window"] [, "iso"]}.
/// @throws InputError bad sizes or band (as bakeProcedural); "placement.scale" or
///   "placement.offsetTexels" not finite or scale <= 0; "placement.windowWorld" empty, not
///   finite, not the tile's x/y aspect, taller than the tile depth, or outside the grid's active
///   box in x or y or missing the surface; a fitted surface taller than the tile depth;
///   "placement.scale" for a placed surface under a texel across; "placement.offsetTexels" for a
///   placed surface whose box misses the tile.
VdbBakeResult bakeVdb(const VdbVolume& volume, const VdbPlacement& placement,
                      const BakeOptions& options, const std::string& fileName,
                      const ProgressCallback& progress = {});

}  // namespace distile
