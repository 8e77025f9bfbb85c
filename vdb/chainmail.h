/// @file
/// Procedural chain mail as an exact analytic signed distance, in two weaves.
///
/// European 4-in-1 (the default, ChainmailWeave::European4in1):
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
///
/// Japanese 4-in-1 (ChainmailWeave::Japanese4in1): large flat rings (axis z, centreline radius R,
/// wire r) on a square lattice of `ringsPerRow` x `rowsPerTile` at mid-depth, each joined to its
/// four neighbours by small vertical rings (radius `smallRingRadiusSpacings`, wire
/// `smallWireRadiusSpacings`) centred on the lattice edges' midpoints: the small ring between two
/// neighbours along x lies in the x-z plane, the one between neighbours along y in the y-z plane,
/// and each threads through both large rings it joins. `tiltDeg` is unused. The defaults of
/// japanese4in1Defaults() on 256 x 256 x 16 (8 x 8 large rings R = 13.75, r = 1.5; small rings
/// 6.0 and 1.25) keep 1 texel between linked wires, 1.5 texels between neighbouring large rings and
/// 0.75 texels of margin at the top and bottom; with non-intersecting rings the distance is exact.
#pragma once

#include <algorithm>
#include <glm/vec3.hpp>
#include <string>

#include "common/size3.h"
#include "common/triangle_soup.h"

namespace distile {

/// How the rings interlock.
enum class ChainmailWeave { European4in1, Japanese4in1 };

struct ChainmailOptions {
    ChainmailWeave weave = ChainmailWeave::European4in1;
    int ringsPerRow = 8;   ///< rings along x per tile; ring spacing s = W / ringsPerRow
    int rowsPerTile = 10;  ///< rows along y per tile; even (tilts alternate)
    double ringRadiusSpacings = 0.703125;  ///< torus centreline radius, in ring spacings s
    double wireRadiusSpacings = 0.065625;  ///< wire (tube) radius, in ring spacings s
    double tiltDeg = 12.0;                 ///< tilt of each ring's plane about the y axis, degrees
    double smallRingRadiusSpacings = 0.1875;     ///< Japanese 4-in-1: small ring radius, spacings
    double smallWireRadiusSpacings = 0.0390625;  ///< Japanese 4-in-1: small ring wire, spacings
};

/// The options of the Japanese 4-in-1 weave that fit a 16-texel-deep tile 256 texels wide (see
/// the file note); the lattice is square when W = H.
ChainmailOptions japanese4in1Defaults();

/// "european4in1" / "japanese4in1", the names used in paramsJson() and on the command line.
const char* weaveName(ChainmailWeave weave);

class Chainmail {
  public:
    /// Throws InputError when the options are out of range (counts < 1, odd rowsPerTile, radii
    /// <= 0, wire thicker than the ring, tilt outside [0, 60] degrees; Japanese 4-in-1: small
    /// ring radius or wire out of (0, 1] spacings, large rings that touch each other) or when the
    /// rings would touch the tile's top or bottom (they need at least half a texel of margin).
    Chainmail(const ChainmailOptions& options, const Size3& tile);

    /// Exact signed distance in texels (negative inside the wire) at a point in texel space.
    /// Any x, y: the pattern is periodic with period W, H. Finite for finite input. Farther than
    /// farSlabTexels() above or below the rings' slab, the distance to the slab: a lower bound.
    double signedDistanceTexels(const glm::dvec3& texelPosition) const;

    /// Height of the rings' bounding slab, texels (centred at z = D/2).
    double heightTexels() const;

    /// How far above or below the rings' slab signedDistanceTexels is exact, texels: eight ring
    /// or row spacings, and at least the tile's depth (every point of the tile is within it).
    double farSlabTexels() const {
        return std::max(8.0 * std::max(ringSpacingTexels_, rowSpacingTexels_), double(tile_.depth));
    }

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
    double smallRingRadiusTexels_ = 0.0;
    double smallWireRadiusTexels_ = 0.0;

    double japaneseDistanceTexels(double x, double y, double z) const;
};

/// The European 4-in-1 rings of `chainmail` whose centres lie in the tile footprint
/// ([0, W) x [0, H)) as a triangle mesh in texel space: each ring is the torus sampled at
/// `segmentsAround` angles around the ring's axis times `segmentsTube` angles around the wire, two
/// triangles per quad, counter-clockwise seen from outside. Rings that cross the footprint's edges
/// are whole; their periodic copies (shifts by W, H) are the caller's business. Every vertex lies
/// on the analytic surface (signedDistanceTexels = 0 up to rounding) and every point of every face
/// within chainmailTessellationErrorTexels() of it.
/// @throws InputError for the Japanese 4-in-1 weave (not supported) or a segment count outside
///   [3, 4096].
TriangleSoup tessellateChainmail(const Chainmail& chainmail, int segmentsAround, int segmentsTube);

/// Bound (texels) on the distance from a face of tessellateChainmail(chainmail, segmentsAround,
/// segmentsTube) to the ring it approximates: the chord sagitta of the outermost circle around the
/// axis plus that of the wire's circle, (R + r)(1 - cos(pi / segmentsAround)) +
/// r (1 - cos(pi / segmentsTube)) (each quad is a planar isosceles trapezoid whose points are
/// chords between mirror-image points of two wire polygons). Same preconditions as
/// tessellateChainmail().
double chainmailTessellationErrorTexels(const Chainmail& chainmail, int segmentsAround,
                                        int segmentsTube);

}  // namespace distile
