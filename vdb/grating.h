/// @file
/// Procedural grating: two layers of straight bars with rounded edges, as an exact analytic
/// signed distance in texel space (negative inside the bars).
///
/// The upper layer holds `barsPerTile` bars along x (centred at y = (j + 1/2) H / barsPerTile),
/// the lower layer `barsPerTile` bars along y (centred at x = (i + 1/2) W / barsPerTile). Every bar
/// is a box of cross-section `barWidthTexels` x `barHeightTexels` whose long edges are rounded
/// with radius `edgeRadiusTexels` (the exact distance of a rounded box: the box shrunk by the
/// radius, then offset by it). The layers are `layerGapTexels` apart and the pair is centred at
/// mid-depth z = D/2. The bars of a layer are disjoint and the layers do not touch, so the minimum
/// over bars is the exact signed distance everywhere, inside and outside. Periodic in x and y.
#pragma once

#include <glm/vec3.hpp>
#include <string>

#include "common/size3.h"

namespace distile {

struct GratingOptions {
    int barsPerTile = 8;           ///< bars per layer across the tile (both layers)
    double barWidthTexels = 8.0;   ///< bar width across its length, texels
    double barHeightTexels = 6.0;  ///< bar thickness in z, texels
    /// Rounding of the bars' long edges, texels (0: sharp). The default, half the bar height, gives
    /// a stadium cross-section: no sharp edge outside and no corner cone inside, which trilinear
    /// reconstruction would overestimate (bake/conservative.h).
    double edgeRadiusTexels = 3.0;
    double layerGapTexels = 1.0;  ///< gap between the layers in z, texels (> 0)
};

class Grating {
  public:
    /// Throws InputError when an option is out of range (barsPerTile < 1 or more than W/4 or H/4,
    /// width not below the bar spacing, sizes <= 0 or not finite, edge radius above half the
    /// width or height, gap <= 0) or when the two layers do not fit the tile depth with half a
    /// texel of margin at the top and the bottom.
    Grating(const GratingOptions& options, const Size3& tile);

    /// Exact signed distance in texels at a texel-space point (any x, y: periodic with W, H).
    double signedDistanceTexels(const glm::dvec3& texelPosition) const;

    /// Height of both layers and the gap, texels (centred at z = D/2).
    double heightTexels() const;

    /// The options as one-line JSON, for tile provenance.
    std::string paramsJson() const;

    const GratingOptions& options() const { return options_; }
    const Size3& tileSize() const { return tile_; }

  private:
    GratingOptions options_;
    Size3 tile_;
};

}  // namespace distile
