/// @file
/// Height-field detail: material solid below a surface z = h(x, y) over the tile footprint,
/// periodic in x and y (ch. 8's stone and text examples), turned into an exact signed level set.
///
/// The surface is the triangulated height field through one node per texel column: node (i, j)
/// sits at texel (i + 0.5, j + 0.5, heightsTexels[i + j W]), indices wrap periodically, and each
/// cell between four nodes is split along its (i, j)-(i+1, j+1) diagonal into two planar
/// triangles. Distances are to that surface (exact point-to-triangle distances, texels); the sign
/// is negative below it (z < h(x, y)). Since voxel centres sit on node columns, every voxel's sign
/// is exact, and a flat field gives exactly z - h.
#pragma once

#include <glm/vec3.hpp>
#include <memory>
#include <string>
#include <vector>

#include "common/progress.h"
#include "common/size3.h"
#include "common/triangle_soup.h"
#include "vdb/level_set.h"

namespace distile {

struct HeightField {
    int width = 0;   ///< nodes along x: the tile width W
    int height = 0;  ///< nodes along y: the tile height H
    /// Height of node (i, j) in texels (0 = floor, D = top), x fastest: index i + j * width.
    std::vector<double> heightsTexels;

    /// Height of node (i, j), indices wrapped periodically (any integers).
    double node(int i, int j) const;
};

/// Throws InputError naming `what` unless the field is width x height = tile W x H nodes, has
/// that many heights, and every height is finite and in [0, D].
void validateHeightField(const HeightField& field, const Size3& tile, const std::string& what);

/// Height of the triangulated surface at texel position (x, y), any x and y (periodic), texels.
/// @pre field is valid (validateHeightField).
double heightFieldSurfaceTexels(const HeightField& field, double x, double y);

/// The triangulated surface over nodes [-marginNodes, W + marginNodes] x [-marginNodes,
/// H + marginNodes] (periodic copies beyond the footprint), texel space, facing +z. Every point
/// of the footprint within marginNodes - 1 texels of the surface is nearest to a triangle of this
/// soup. @pre field is valid, marginNodes >= 0.
TriangleSoup heightFieldTriangles(const HeightField& field, int marginNodes);

/// Exact signed distance to the field's triangulated surface, texels, negative below it
/// (z < heightFieldSurfaceTexels): double precision point-to-triangle distances over the cells
/// that can hold a nearer triangle than the vertical distance, culled by the height ranges of
/// cells and of 8 x 8 cell blocks. Thread-safe.
class HeightFieldDistance {
  public:
    /// Distances are found up to `limitTexels` (beyond it: +-limitTexels). @pre field is valid
    /// (validateHeightField), limitTexels > 0.
    HeightFieldDistance(HeightField field, double limitTexels);
    HeightFieldDistance(HeightFieldDistance&&) noexcept;
    ~HeightFieldDistance();

    const HeightField& field() const;

    /// @pre texel.x in [-1, W + 1], texel.y in [-1, H + 1] (the field repeats: wrap other points
    /// into the footprint first).
    double signedDistanceTexels(const glm::dvec3& texel) const;

  private:
    struct Search;
    std::unique_ptr<const Search> search_;
};

/// Signed level set of the height field: exact unsigned distances to the triangulated surface
/// (double precision point-to-triangle distances over the cells that can hold a nearer triangle
/// than the vertical distance, culled by the height ranges of cells and of 8 x 8 cell blocks),
/// sign from z against the surface height. Same grid layout, band rules, provenance metadata and
/// determinism as LevelSet::fromDistance.
/// @throws InputError the tile size is invalid, halfBandTexels is not in [1, 1024], or the field
///                    fails validateHeightField.
LevelSet levelSetFromHeightField(const HeightField& field, const Size3& tile, float halfBandTexels,
                                 const std::string& source, const std::string& params,
                                 const ProgressCallback& progress = {});

}  // namespace distile
