/// @file
/// Exact distances and generalized winding numbers of a triangle soup placed in a periodic tile,
/// for baking detail meshes of any kind: closed solids, open sheets, soups of overlapping parts,
/// duplicated or flipped faces.
///
/// - **Distance**: the exact Euclidean distance (double precision) from a point to the nearest
///   triangle of the periodic union of the soup's copies shifted by (m W, n H, 0)
///   (common/triangle_soup.h periodicShifts), found with a bounding-volume hierarchy
///   (median splits, leaves of at most 2 triangles) queried once per copy that can be nearer.
///   The query walks a four-wide version of the hierarchy whose boxes are stored in float,
///   rounded outward, and compared with a margin that covers the float rounding of the point
///   and of the box arithmetic: a box is skipped only when it is provably no nearer than the
///   best triangle so far, and every triangle distance is computed in double, so the result is
///   the exact double-precision minimum. Up to 16 points on one vertical line share a walk
///   (each box is tested against all of them at once; a grid's column of voxels visits about a
///   quarter of the nodes its voxels would one by one), each point keeping its own best.
/// - **Sign**: the generalized winding number w (Jacobson et al. 2013): the sum of the signed
///   solid angles of the triangles over 4 pi. It is 1 inside and 0 outside a closed,
///   outward-oriented mesh, adds up over overlapping closed parts, and degrades gracefully
///   for holes and soups; a point is inside where w > 1/2. Far clusters of triangles are
///   replaced by their dipole (the sum of their vector areas at their area-weighted centroid;
///   Barill et al. 2018, "Fast winding numbers for soups and clouds", first order): a node of
///   the hierarchy is taken whole when the point is farther than kWindingFarFieldRatio times the
///   node's radius; nearer ones are opened down to clusters of at most 4 triangles, whose exact
///   per-triangle solid angles are summed. Where the result is ambiguous (|w - 1/2| <
///   kWindingRecheckMargin) it is evaluated again with kWindingRecheckRatio, which is exact enough
///   to decide the sign for any mesh whose exact w stays clear of 1/2. Only the copies whose
///   bounding box contains the point in x and y count (the other copies of a closed part contribute
///   0 there).
///
/// All queries are const and thread-safe; results do not depend on the thread that asks.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <vector>

#include "common/size3.h"
#include "common/triangle_soup.h"
#include "common/uninitialized.h"

namespace distile {

/// A hierarchy node is taken as one dipole beyond this many node radii from the point.
inline constexpr double kWindingFarFieldRatio = 2.0;
/// Winding numbers within this of 1/2 are evaluated again with kWindingRecheckRatio.
inline constexpr double kWindingRecheckMargin = 0.25;
inline constexpr double kWindingRecheckRatio = 8.0;

/// An edge of a triangle soup, its corners matched by exact position, used more often in one
/// direction than in the other: where open parts end, sheets, flipped faces.
struct UnbalancedEdge {
    glm::dvec3 a, b;
};

/// Every unbalanced edge of `soup`, once, in an order that depends only on the soup (its
/// position ids). Empty for closed, consistently oriented parts, however they overlap or repeat.
std::vector<UnbalancedEdge> unbalancedEdges(const TriangleSoup& soup);

class SoupDistance {
  public:
    /// `soupTexels`: positions in texel space of `tile` (placeMesh's result). Builds the
    /// hierarchy (O(n log n), single-threaded).
    /// @pre the soup passes validateTriangleSoup; tile extents >= 1.
    SoupDistance(const TriangleSoup& soupTexels, const Size3& tile);

    /// Distance to the nearest triangle of the periodic union, texels; `cutoffTexels` when
    /// nothing is nearer than it (the search stops there). @pre cutoffTexels > 0.
    double unsignedDistance(const glm::dvec3& texelPosition, double cutoffTexels) const;

    /// The triangle (and copy) an unsignedDistance query found nearest; a start for the next
    /// query at a nearby point, whose result it only speeds up (never changes).
    struct NearestHint {
        std::uint32_t triangle = UINT32_MAX;  ///< UINT32_MAX: none
        std::int32_t copyX = 0, copyY = 0;    ///< of the copy, shifted by (copyX W, copyY H, 0)
        bool operator==(const NearestHint&) const = default;
    };
    /// A NearestHint::triangle in a tie: two or more other triangles are as near.
    static constexpr std::uint32_t kSeveralTriangles = UINT32_MAX - 1;
    /// Triangles whose squared distance is within this fraction of the nearest's are tied with it
    /// (far below the hierarchy's skipping margin, 2^-20, and far above rounding).
    static constexpr double kTieRelative = 1e-9;
    /// unsignedDistance starting from `hint`'s triangle, which it then updates.
    double unsignedDistance(const glm::dvec3& texelPosition, double cutoffTexels,
                            NearestHint& hint) const;

    /// unsignedDistance at the points (x, y, z[k]) of one vertical line, each from and updating
    /// hints[k]: the same distances, for less work (the points share one walk of the hierarchy
    /// per copy, kLineLanes at a time). When `ties` is given (one per point), ties[k] is the one
    /// other triangle (and copy) within kTieRelative of the nearest, triangle kSeveralTriangles
    /// when there are more, UINT32_MAX when there is none (or nothing within the cutoff).
    void unsignedDistancesOnLine(const glm::dvec2& xy, std::span<const double> z,
                                 double cutoffTexels, std::span<NearestHint> hints,
                                 std::span<double> distances,
                                 std::span<NearestHint> ties = {}) const;

    /// Generalized winding number of the periodic union at the point (see the file note).
    double windingNumber(const glm::dvec3& texelPosition) const;

    /// For meshes whose winding number changes only across the surface: the winding number at
    /// the point counted from the crossings of a vertical ray from it out of the mesh's bounds
    /// (+1 for each triangle it leaves through the front, -1 through the back), exact where every
    /// triangle near the ray is provably crossed through its interior or missed (the margins of
    /// segmentTouchesNoTriangle); nullopt where one is unclear (the ray grazes an edge, a corner
    /// or a plane). Much cheaper than windingNumber near a fine mesh: the ray meets a few
    /// triangles where the far field opens hundreds of nodes.
    /// @pre windingChangesOnlyAcrossTheSurface().
    std::optional<int> windingNumberByCrossings(const glm::dvec3& texelPosition) const;

    /// For meshes whose winding number changes only across the surface: whether the winding
    /// number is 0 just in front of the centroid of the triangle abc (texels, one of the soup's),
    /// and so, crossing it backwards, 1 just behind: it bounds the inside there. True for a
    /// triangle without area (it has no sides).
    bool facesOutsideAtCentroid(const glm::dvec3& a, const glm::dvec3& b,
                                const glm::dvec3& c) const;
    /// facesOutsideAtCentroid of triangle `triangle` as NearestHint numbers them (a sliver as
    /// the segment it is measured as: no sides).
    bool facesOutsideAtCentroid(std::uint32_t triangle) const;

    /// The winding number counted from crossings (windingNumberByCrossings) where the winding
    /// number changes only across the surface and they are clear, else windingNumber: an exact
    /// integer for closed parts, and far cheaper near a fine mesh than the far field.
    double countedWindingNumber(const glm::dvec3& texelPosition) const;

    /// The side of the surface `texelPosition` lies on at its nearest point, on triangle
    /// `nearest` (found by unsignedDistancesOnLine, with its `tie`): +1 in front (where the
    /// triangle's counter-clockwise normal points), -1 behind, 0 where it cannot be told. Told at
    /// a face's interior (no tie) from its normal, at an edge whose one neighbour is the tie
    /// (using the edge the other way round) from the sum of their normals (Baerentzen and Aanaes
    /// 2005), within 60 degrees of them; not at corners (their fan is not known here). Where the
    /// winding number changes only across the surface, the winding number behind is 1 more than
    /// in front, and the point's winding number holds up to its nearest point (the ball between
    /// is empty of surface).
    int sideOfNearestPoint(const glm::dvec3& texelPosition, const NearestHint& nearest,
                           const NearestHint& tie) const;

    /// False when the segment from `from` to `to` (texels) may touch a triangle of the periodic
    /// union; true only when it provably touches none (near misses, within rounding, count as
    /// touching). With windingChangesOnlyAcrossTheSurface, true means both ends have the same
    /// winding number.
    bool segmentTouchesNoTriangle(const glm::dvec3& from, const glm::dvec3& to) const;

    /// unsignedDistance, negative where windingNumber > 1/2; +-cutoffTexels beyond it.
    double signedDistance(const glm::dvec3& texelPosition, double cutoffTexels) const;

    std::size_t triangleCount() const { return triangles_.size(); }
    const Size3& tile() const { return tile_; }

    /// True when every edge (corners matched by exact position) is used as often in one
    /// direction as in the other: closed, consistently oriented parts, however they overlap or
    /// repeat. Then the winding number changes only across the surface (it jumps by an integer
    /// there and is constant elsewhere), so a point nearer to a point of known winding number
    /// than that point's distance to the surface shares it. Otherwise (holes, flipped faces,
    /// sheets) it also varies continuously off the surface.
    bool windingChangesOnlyAcrossTheSurface() const { return windingPiecewiseConstant_; }

  private:
    /// The binary hierarchy, which the winding number walks. (Trivial types, like Dipole: their
    /// arrays are not zeroed before the build writes every element.)
    struct Node {
        std::uint32_t first;  ///< leaf: first triangle; inner: index of the second child
        std::uint32_t count;  ///< leaf: number of triangles; inner: 0 (first child follows)
        /// All the triangles below the node (consecutive in leaf order).
        std::uint32_t firstTriangle, triangleCount;
    };
    /// Four children of the binary hierarchy's collapsed form, which the distance and segment
    /// queries walk: their boxes side by side (float, rounded outward) for one four-wide test.
    /// An empty slot has an empty box (min +inf, max -inf).
    struct alignas(64) WideNode {
        float minX[4], minY[4], minZ[4], maxX[4], maxY[4], maxZ[4];
        std::uint32_t child[4];  ///< inner: index of a wide node; leaf: first triangle
        std::uint32_t count[4];  ///< leaf: number of triangles; inner or empty: 0
    };
    /// A box in float, rounded outward from the double corners it holds.
    struct FloatBox {
        glm::vec3 min, max;
    };
    struct Dipole {
        glm::dvec3 centre;      ///< area-weighted centroid of the node's triangles
        glm::dvec3 vectorArea;  ///< sum of (b - a) x (c - a) / 2 over the node's triangles
        /// At least the distance from centre to the node's farthest triangle corner (exactly that
        /// at leaves; an inner node's sphere holds its children's).
        double radius;
    };
    struct Triangle {
        glm::dvec3 a, b, c;
    };
    /// A triangle whose corners are collinear to within rounding as the segment it is: its
    /// longest edge, the far corner repeated. The closest-point test's region tests cannot
    /// classify points against such a sliver (they pick a wrong region, off by up to its length),
    /// while on (a, b, b) they reduce exactly to the segment ab.
    static Triangle asSegmentIfSliver(const Triangle& triangle);

    /// A triangle as the build sorts it: the sum of its corners (three times its centroid).
    struct BuildItem {
        glm::vec3 cornerSum;
        std::uint32_t triangle;  ///< index in the input
    };
    /// Splits node `index` over items [begin, end) (reordered: leaves hold consecutive items)
    /// at the median of the longest axis of their centroids' box, and its subtree.
    void split(std::uint32_t index, std::uint32_t begin, std::uint32_t end,
               UninitializedVector<BuildItem>& items);
    struct Bound {
        Dipole dipole;
        double area = 0.0;  ///< of the node's triangles
    };
    /// Node `index`'s box, and its subtree's, bottom-up from triangles_ (leaf order).
    void boxOf(std::uint32_t index);
    /// Node `index`'s dipole, and its subtree's, into dipoles_.
    Bound dipoleOf(std::uint32_t index) const;
    /// Node `index`'s dipole; the first call builds them all (thread-safe).
    const Dipole& dipole(std::uint32_t index) const;
    std::uint32_t collapse(std::uint32_t binaryIndex);
    static constexpr int kLineLanes = 16;
    /// One point's nearest triangles so far: the nearest, the next (another triangle, or
    /// another copy of it) and the squared distance of the one after.
    struct LineLaneNearest {
        double bestSquared = HUGE_VAL, secondSquared = HUGE_VAL, thirdSquared = HUGE_VAL;
        NearestHint best, second;
    };
    /// The nearest triangles of copy (copyX, copyY) to up to kLineLanes points (x, y, z[k]) of
    /// its frame, in one walk of the hierarchy, merged into lanesNearest[k]. A box is skipped only
    /// when it is provably no nearer than a lane's best (see the file note), so the best is the
    /// exact minimum and every triangle within kTieRelative of it is compared.
    void closestSquaredOnLine(const glm::dvec2& xy, std::span<const double> z, int copyX, int copyY,
                              std::span<LineLaneNearest> lanesNearest) const;
    /// Calls visit(triangle) for every triangle whose box (float, rounded outward, with the
    /// point's rounding) overlaps the segment's, until it returns false; false if it did.
    template <class Visit>
    bool everyTriangleNearSegment(const glm::dvec3& from, const glm::dvec3& to,
                                  Visit&& visit) const;
    bool segmentTouchesNoTriangleOfCopy(const glm::dvec3& from, const glm::dvec3& to) const;
    double windingNumberOfCopy(const glm::dvec3& point, double farFieldRatio) const;

    bool windingPiecewiseConstant_ = false;
    Size3 tile_;
    Bounds3 bounds_;
    // Filled in parallel right after they are sized: not zeroed first.
    UninitializedVector<Triangle> triangles_;  ///< in leaf order
    UninitializedVector<Node> nodes_;          ///< depth-first, root first
    std::vector<WideNode> wideNodes_;          ///< root first
    UninitializedVector<FloatBox> boxes_;      ///< one per node
    /// One per node, built on the first winding number asked for (dipole()).
    mutable UninitializedVector<Dipole> dipoles_;
    std::unique_ptr<std::once_flag> dipolesBuilt_ = std::make_unique<std::once_flag>();
};

}  // namespace distile
