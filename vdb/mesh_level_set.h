/// @file
/// Signed narrow-band level sets of closed triangle meshes placed in texel space, computed with
/// OpenVDB's mesh-to-level-set (exact point-to-triangle distances in the band; voxel size 1
/// texel, voxel (i, j, k) centred at (i + 0.5, j + 0.5, k + 0.5); the same grid class, name and
/// metadata as LevelSet::fromDistance).
///
/// Periodicity: the tile is periodic in x and y; the detail is the union of the mesh's copies
/// shifted by (m W, n H, 0) (common/triangle_soup.h, periodicShifts). The closed mesh is converted
/// once, unshifted, and every tile voxel takes the minimum over the copies that reach it (voxel
/// lookups at integer shifts, no interpolation), so distances are measured across the wrap and a
/// mesh that crosses a tile edge continues on the other side. (Shifting only the triangles near
/// the edges before the conversion would hand OpenVDB open fragments, whose inside/outside flood
/// fill leaks.) The minimum is exact outside the detail and wherever the copies do not overlap;
/// inside overlapping copies it underestimates the depth. Only the voxels of the tile footprint
/// [0,W) x [0,H) are kept, with ceil(halfBand) voxels of margin below z = 0 and above z = D (as
/// LevelSet::fromDistance does).
#pragma once

#include <functional>
#include <glm/vec3.hpp>
#include <string>

#include "common/progress.h"
#include "common/size3.h"
#include "common/triangle_soup.h"
#include "vdb/level_set.h"

namespace distile {

/// An exact inside test of the detail at a texel-space position (for instance truth/mesh_truth.h
/// MeshDistance::isInside of the placed mesh, periodic). Called concurrently from several threads.
using InsideTest = std::function<bool(const glm::dvec3& texelPosition)>;

/// Level set of `meshTexels` (positions in texel space). The sign is OpenVDB's inside/outside
/// classification, meaningful only for a closed, manifold, consistently oriented mesh; check
/// open meshes first (truth/mesh_truth.h inspectMesh). Distances in texels, clamped to
/// +-halfBandTexels outside the band. `source` and `params` are stored as provenance metadata.
/// Deterministic for any thread count. `progress` is called on this thread (coarsely: OpenVDB's
/// conversion is one call).
/// OpenVDB's inside/outside test is approximate in the voxels the triangles cut: a few voxel
/// centres within a fraction of a texel of the surface get the wrong sign. When `insideTest` is
/// given, every voxel with |distance| < 1 texel takes its sign from it instead (the magnitude
/// stays OpenVDB's exact distance), so the signs are exact everywhere.
/// @throws InputError the tile size is invalid (validateTileSize), halfBandTexels is not in
///                    [1, 1024], or the mesh fails validateTriangleSoup.
LevelSet levelSetFromMesh(const TriangleSoup& meshTexels, const Size3& tile, float halfBandTexels,
                          const std::string& source, const std::string& params,
                          const ProgressCallback& progress = {}, const InsideTest& insideTest = {});

}  // namespace distile
