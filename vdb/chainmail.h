/// @file
/// Procedural European 4-in-1 chain mail as an exact analytic signed distance.
///
/// Rings are tori on a lattice in texel space: row j (along y) holds `ringsPerRow` rings along x,
/// spaced s = W / ringsPerRow; rows are H / rowsPerTile apart and odd rows are shifted by s/2.
/// Every ring is tilted about the y axis, even rows by +tilt and odd rows by -tilt, so each ring
/// threads through its four diagonal neighbours. Ring centres sit at mid-depth, z = D/2. The
/// lattice repeats exactly every W in x and H in y, so the tile is periodic.
///
/// The defaults (on 256 x 256 x 16: 8 x 10 rings, centreline radius 22.5 texels, wire radius
/// 2.1 texels, tilt 12 degrees, 13.8 texels tall) are the thickest wire for which linked rings
/// keep a gap (1.5 texels) in a 16-texel-deep tile. With such non-intersecting rings the distance
/// is exact everywhere; options that make rings intersect still give the exact distance outside
/// the material and a conservative bound inside it.
#pragma once

#include <string>

#include <glm/vec3.hpp>

#include "common/size3.h"

namespace distile {

struct ChainmailOptions {
    int ringsPerRow = 8;               ///< rings along x per tile; ring spacing s = W / ringsPerRow
    int rowsPerTile = 10;                  ///< rows along y per tile; even (tilts alternate)
    double ringRadiusSpacings = 0.703125;  ///< torus centreline radius, in ring spacings s
    double wireRadiusSpacings = 0.065625;  ///< wire (tube) radius, in ring spacings s
    double tiltDeg = 12.0;                 ///< tilt of each ring's plane about the y axis, degrees
};

class Chainmail {
public:
    /// Throws InputError when the options are out of range (counts < 1, odd rowsPerTile, radii
    /// <= 0, wire thicker than the ring, tilt outside [0, 60] degrees) or when the rings would
    /// touch the tile's top or bottom (they need at least half a texel of margin).
    Chainmail(const ChainmailOptions& options, const Size3& tile);

    /// Exact signed distance in texels (negative inside the wire) at a point in texel space.
    /// Any x, y: the pattern is periodic with period W, H. Finite for finite input.
    double signedDistanceTexels(const glm::dvec3& texelPosition) const;

    /// Height of the rings' bounding slab, texels (centred at z = D/2).
    double heightTexels() const;

    /// The options as one-line JSON, for tile provenance.
    std::string paramsJson() const;

    const ChainmailOptions& options() const { return options_; }
    const Size3& tileSize() const { return tile_; }

private:
    ChainmailOptions options_;
    Size3 tile_;
    double ringSpacingTexels_;
    double rowSpacingTexels_;
    double ringRadiusTexels_;
    double wireRadiusTexels_;
    double cosTilt_;
    double sinTilt_;
};

}  // namespace distile
