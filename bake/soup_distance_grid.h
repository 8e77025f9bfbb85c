/// @file
/// The exact distances of a SoupDistance at every voxel centre of a block of slices of the tile's
/// texel grid: what a mesh bake fills its level set with (bake/solid_mesh.h).
///
/// Unsigned distances come from one query per vertical line of voxels (all the slices at once),
/// each voxel started from the nearest triangle of its neighbour in the row. Signed by the winding
/// number: for meshes whose winding number changes only across the surface
/// (SoupDistance::windingChangesOnlyAcrossTheSurface) the voxels are joined into regions that no
/// surface separates -- two neighbours join when d1 + d2 exceeds their spacing (the two empty balls
/// cover the segment between them) -- and the winding number is evaluated once per region, at its
/// voxel farthest from the surface (as an integer: counted from crossings where they are clear).
/// Otherwise at every voxel.
///
/// Signed by regions, the grid also tells whether each voxel's distance is to the surface a
/// signed bake measures (bake/mesh_surface.h), the boundary of the inside: the voxel's nearest
/// point bounds it when the winding number is 0 on its front and 1 behind. The side of the
/// surface a voxel lies on there is told from the nearest triangle and the one it is tied with
/// (SoupDistance::sideOfNearestPoint), and its winding number from its region; where the side
/// cannot be told (corners, more ties), its nearest triangle is checked as MeshSurface checks
/// every triangle (winding number 0 in front of its centroid). For a closed mesh whose parts
/// neither overlap nor touch, this spares checking every triangle.
#pragma once

#include <glm/vec3.hpp>
#include <vector>

#include "bake/soup_distance.h"
#include "common/progress.h"

namespace distile {

/// Voxel (i, j, k) of the block is centred at (i + 0.5, j + 0.5, k + 0.5), texels,
/// 0 <= i < W, 0 <= j < H, zBegin <= k < zEnd.
struct SoupDistanceGrid {
    int width = 0, height = 0, zBegin = 0, zEnd = 0;
    /// x fastest, then y, then z; texels, clamped to +-cutoffTexels; negative inside when signed.
    std::vector<double> distancesTexels;
    /// The nearest triangle of each voxel (same order), to start queries near it from.
    std::vector<SoupDistance::NearestHint> nearest;
    /// Signed grids of meshes whose winding number changes only across the surface: true when
    /// every voxel's nearest point provably bounds the inside (see soupDistanceGrid), so the
    /// distances are those to the surface a signed bake measures (bake/mesh_surface.h) and no
    /// triangle needs trimming for them. False otherwise.
    bool nearestPointsBound = false;

    /// A start for a query at `texelPosition`: the nearest triangle of the voxel nearest to it
    /// (of the copy of the tile it lies in, the slice clamped into the block).
    SoupDistance::NearestHint hintNear(const glm::dvec3& texelPosition) const;

    const double* row(int j, int k) const {
        return distancesTexels.data() +
               (std::size_t(k - zBegin) * std::size_t(height) + std::size_t(j)) *
                   std::size_t(width);
    }
};

/// The distances of `soup` at the voxels of slices [zBegin, zEnd) of its tile, at most
/// `cutoffTexels` (> 0) in magnitude: unsigned when `signedByWindingNumber` is false, else
/// negative where the winding number exceeds 1/2 (see the file note). Multi-threaded; the
/// result does not depend on the thread count. `progress` gets the fraction of slices done.
SoupDistanceGrid soupDistanceGrid(const SoupDistance& soup, int zBegin, int zEnd,
                                  double cutoffTexels, bool signedByWindingNumber,
                                  const ProgressCallback& progress = {});

/// SoupDistance::signedDistance at any point whose nearest voxel centre lies in `grid` (a signed
/// grid of `soup`), from its unsigned `distance` there: the sign is taken from that voxel when no
/// surface can lie between them (as the file note says; for meshes whose winding number changes
/// only across the surface), else from the winding number at the point. Thread-safe.
double signedDistanceBesideGrid(const SoupDistance& soup, const SoupDistanceGrid& grid,
                                const glm::dvec3& texelPosition, double distance);

}  // namespace distile
