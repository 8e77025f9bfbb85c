/// @file
/// Baking: detail source -> exact narrow-band level set -> dense tile.
///
/// Errors about one option are InputError::inField naming its member path, as the options
/// structs spell it: "size", "halfBandTexels", "placement.scale", "placement.offsetTexels",
/// "heightTexels"; a program shows them under its own names (InputError::renamed).
#pragma once

#include <glm/vec3.hpp>

#include "bake/conservative.h"
#include "bake/height_image.h"
#include "common/progress.h"
#include "common/triangle_soup.h"
#include "sampler/tile.h"
#include "vdb/chainmail.h"
#include "vdb/level_set.h"
#include "vdb/mesh_level_set.h"
#include "vdb/procedural.h"

namespace distile {

struct BakeOptions {
    Size3 size{256, 256, 16};
    /// Half width of the level set's narrow band, texels: 0 or in [1, maxHalfBandTexels(size)].
    /// 0 means the tile depth (at most 1024), so the band covers every texel of the tile (of any
    /// tile up to 1024 texels deep).
    float halfBandTexels = 0.0f;
    /// Resampling into the tile lowers texels so trilinear interpolation does not overestimate
    /// (bake/conservative.h); on by default.
    ConservativeOptions conservative;
    /// Whether a mesh bake fills the level set's band margin above and below the tile (what a
    /// .vdb file needs for its band to close around detail near the top and the floor). The tile
    /// never reads it; without it a mesh bake measures a third of the voxels and the margin's
    /// voxels stay inactive at the background. The other bakes always fill it (they are cheap).
    bool fillLevelSetMargins = true;
};

/// Checks `options` (InputError naming "size" or "halfBandTexels") and returns the level set's
/// half band, texels: halfBandTexels, or when it is 0 the tile depth (at most 1024).
float validatedHalfBandTexels(const BakeOptions& options);

struct BakeResult {
    LevelSet levelSet;
    Tile tile;
};

/// Throws InputError::inField naming "size" or "halfBandTexels" when the tile size is invalid
/// (validateTileSize) or the half band is neither 0 nor in [1, maxHalfBandTexels(size)].
void validateBakeOptions(const BakeOptions& options);

/// Chain mail (vdb/chainmail.h) baked into a level set and its tile. Throws InputError for bad
/// sizes or chain-mail options.
BakeResult bakeChainmail(const ChainmailOptions& chainmail, const BakeOptions& options,
                         const ProgressCallback& progress = {});

/// Any procedural pattern (vdb/procedural.h) baked into a level set and its tile; the tile's
/// provenance is the pattern's source name and paramsJson. Throws InputError for bad sizes or
/// pattern options.
BakeResult bakeProcedural(const ProceduralOptions& procedural, const BakeOptions& options,
                          const ProgressCallback& progress = {});

/// Where a detail mesh goes in the tile (texel space: x, y in [0,W) x [0,H), z = 0 the floor,
/// z = D the top).
/// - Fit (default): scaled uniformly so its x/y bounding box fits the tile footprint exactly
///   (the axis with the larger extent relative to W or H spans it), centred in x and y, its
///   bottom resting on the floor z = 0. A mesh meant to repeat should have its period as its
///   x/y bounding box. The scaled mesh must not be taller than the tile depth D.
/// - Explicit: texel position = scale * file position + offsetTexels.
struct MeshPlacement {
    bool fit = true;
    double scale = 1.0;            ///< Explicit only: texels per file unit, > 0
    glm::dvec3 offsetTexels{0.0};  ///< Explicit only: where the file's origin goes, texels
};

/// The fit placement of a box (file units): the uniform scale (texels per unit) and offset
/// (texels) that make its x/y extent span the tile footprint (the axis with the larger extent
/// relative to W or H spans it exactly), centred in x and y, its bottom on the floor z = 0.
/// @pre the box has an x or y extent > 0. @throws InputError::inField "size", "<what>: fitted
///   ... tall", when the fitted box is taller than the tile depth.
struct FootprintFit {
    double scale = 1.0;
    glm::dvec3 offsetTexels{0.0};
};
FootprintFit fitToFootprint(const Bounds3& box, const Size3& tile, const std::string& what);

/// Largest texel coordinate a placed mesh may have: beyond 2^20 a float (OpenVDB's mesh
/// positions) resolves less than 1/8 texel.
inline constexpr double kMaxPlacedTexelCoordinate = 1 << 20;

/// Widest placed mesh a bake accepts, in tile footprints along x and y (and footprint widths
/// along z): the bake's time grows with the periods the mesh covers (a ring 2.5 footprints wide
/// takes ~20 s on a 64x64x8 tile); a repeating mesh covers one.
inline constexpr double kMaxPlacedFootprints = 2.0;

/// Throws InputError unless a mesh placed in `tile` with bounds `placedTexels` (texels) overlaps
/// the tile (x in [0, W], y in [0, H], z in [0, D]; else in field "placement.offsetTexels"), is
/// at least one texel across, and at most kMaxPlacedFootprints tile footprints wide (else in
/// field "placement.scale").
void requireMeshInTile(const Bounds3& placedTexels, const Size3& tile);

/// The explicit placement `placement` amounts to for this mesh and tile: itself when explicit,
/// the fitted scale and offset (texels) otherwise. Throws InputError as placeMesh.
MeshPlacement explicitPlacement(const TriangleSoup& meshFileUnits, const MeshPlacement& placement,
                                const Size3& tile);

/// The mesh (file units) placed in the tile by `placement`, positions in texels.
/// @throws InputError the mesh fails validateTriangleSoup, has no x/y extent (Fit), is taller
///   than the tile depth after fitting, the scale is not finite and > 0, the offset is not
///   finite, a placed coordinate exceeds kMaxPlacedTexelCoordinate (in field "placement.scale",
///   or "placement.offsetTexels" for an offset of half that), or the placed mesh fails
///   requireMeshInTile.
TriangleSoup placeMesh(const TriangleSoup& meshFileUnits, const MeshPlacement& placement,
                       const Size3& tile);

/// The benchmark peer of the mesh bake (bake/solid_mesh.h bakeSolidMesh is the one programs use):
/// a closed detail mesh (file units) placed by `placement` and baked with OpenVDB's
/// mesh-to-level-set into a periodic level set (vdb/mesh_level_set.h) and its tile; the tile's
/// params record the placement (JSON: "placement": "fit" or "explicit", "scale", "offset_texels"
/// [x, y, z] as used, also when fitted, and "triangles"). The sign is
/// only meaningful for a closed, manifold mesh: callers check that (truth/mesh_truth.h) and
/// verify the sign. `insideTest`, when given, is the exact inside test of the *placed* mesh
/// (placeMesh's result, texels), which fixes the sign of the voxels within 1 texel of the surface
/// (vdb/mesh_level_set.h). `exactDistances`, when given, are the exact signed distances of the
/// placed mesh (periodic, texels, e.g. truth/mesh_truth.h MeshDistance::signedDistance): the
/// conservative correction then measures the trilinear overestimate against it instead of
/// estimating it (bake/conservative.h). Throws InputError as placeMesh and bakeChainmail do.
BakeResult bakeMesh(const TriangleSoup& meshFileUnits, const MeshPlacement& placement,
                    const BakeOptions& options, const ProgressCallback& progress = {},
                    const InsideTest& insideTest = {},
                    const ExactDistancesOnLine& exactDistances = {});

/// A height map: the image (bake/height_image.h) scaled to heights 0..heightTexels, sampled
/// periodically and bilinearly at the tile's texel columns, material solid below the
/// triangulated surface through those heights (vdb/height_field.h), baked into an exact signed
/// level set and its tile (provenance: source "heightmap", the image size and heightTexels).
struct HeightMapOptions {
    /// Height of image value 1, texels; 0 means the tile depth minus one (D - 1).
    double heightTexels = 0.0;
};

/// Throws InputError for bad sizes or heightTexels (heightFieldFromImage).
BakeResult bakeHeightMap(const HeightImage& image, const HeightMapOptions& heightMap,
                         const BakeOptions& options, const ProgressCallback& progress = {});

}  // namespace distile
