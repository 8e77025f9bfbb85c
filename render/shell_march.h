/// @file
/// The march through a curved shell (common/shell_map.h): the ray is followed in world space, and
/// each distance sample is taken where the ray really is in texel space, through the shell map of
/// the prism it is in. The ray goes on from prism to prism across shared side faces, leaves the
/// shell through the top or an open border, or ends on the detail or the floor.
///
/// Each sample inverts the map at the ray's point by Newton's method (one step from the previous
/// point's prediction, in double precision) and steps the sampled distance in texels along the
/// ray's texel-space direction there: dt = distance / |J r|, with J = d texel / d world, the map's
/// local stretch along the ray. That is ch. 8's normalisation factor taken at every sample instead
/// of once at the entry. The step is exact to first order; where the stretch grows along the step
/// (the map is not affine) a budgeted step that lands inside the detail is refined by regula
/// falsi, as in the planar march.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <glm/vec3.hpp>
#include <limits>
#include <span>
#include <vector>

#include "common/shell_map.h"
#include "common/size3.h"
#include "mesh/base_mesh.h"
#include "render/bvh.h"
#include "render/march.h"

namespace distile {

/// A shell: the prisms of one object's triangles, in the tracer's shell order, and for each the
/// prism across the side face opposite each corner (kNoNeighbour at an open border).
struct ShellPrisms {
    static constexpr std::uint32_t kNoNeighbour = 0xffffffffU;
    std::span<const ShellPrism> prisms;
    std::span<const std::array<std::uint32_t, 3>> neighbours;
    /// For each side face that has a neighbour: the neighbour's corner opposite that face.
    std::span<const std::array<std::uint8_t, 3>> neighbourCorners;
};

/// The shell map of one base mesh carrying a tile: a prism per triangle (common/shell_map.h) and,
/// across each side face, the neighbouring triangle: the one triangle with the same edge
/// reversed, vertices welded by position (so uv seams and mirrored charts connect); none at an
/// open border, a non-manifold edge, one whose triangles disagree in orientation or a side whose
/// two ends weld into one vertex.
struct ShellMesh {
    std::vector<ShellPrism> prisms;                        ///< by triangle
    std::vector<std::array<std::uint32_t, 3>> neighbours;  ///< across the face opposite a corner
    std::vector<std::array<std::uint8_t, 3>> neighbourCorners;  ///< ShellPrisms::neighbourCorners
    ShellPrisms view() const { return {prisms, neighbours, neighbourCorners}; }
};

/// The shell map of `mesh` (unit vertex normals) under a tile of `tileSize` texels repeated
/// `uvScale` times per unit of uv, `depthWorld` deep. Preconditions: valid indices, finite data.
ShellMesh buildShellMesh(const BaseMesh& mesh, const glm::vec2& uvScale, const Size3& tileSize,
                         double depthWorld);

/// buildShellMesh written into arrays of one element per triangle of `mesh`, its neighbours
/// numbered from `firstIndex`: one object's shell in the arrays of a scene's shells.
void buildShellMeshInto(const BaseMesh& mesh, const glm::vec2& uvScale, const Size3& tileSize,
                        double depthWorld, std::uint32_t firstIndex, std::span<ShellPrism> prisms,
                        std::span<std::array<std::uint32_t, 3>> neighbours,
                        std::span<std::array<std::uint8_t, 3>> neighbourCorners);

/// The neighbours of buildShellMeshInto alone (no prisms): across each side of each triangle of
/// `mesh`, numbered from `firstIndex` (ShellPrisms::kNoNeighbour at an open border).
void buildNeighboursInto(const BaseMesh& mesh, std::uint32_t firstIndex,
                         std::span<std::array<std::uint32_t, 3>> neighbours,
                         std::span<std::array<std::uint8_t, 3>> neighbourCorners);

/// How a curved march ended.
struct CurvedMarchEnd {
    MarchResult march;           ///< texel position in the end prism's texel space, iterations, ...
    bool leftShell = false;      ///< through the top, an open border or an open floor: no hit here
    double distanceWorld = 0.0;  ///< along the ray: the hit, or where it left the shell
    /// Left the shell: it crossed its boundary between these two distances along the ray (the
    /// last point sampled inside, the first known outside).
    double lastInsideWorld = 0.0, firstOutsideWorld = 0.0;
    std::uint32_t prism = 0;  ///< where it ended
    PrismPoint point;         ///< the end point in that prism
    /// |J r| at the end: texels per world unit along the ray (0 when it left the shell).
    float texelsPerWorldAlongRay = 0.0f;
};

namespace detail {

/// Where a curved march is: its prism, its point there and the ray's offset from the prism's
/// corner 0 (re-based when the prism changes).
struct CurvedCursor {
    std::uint32_t prism = 0;
    PrismPoint point;
    glm::dvec3 originOffset{0.0};   ///< ray origin - P_0 of `prism`
    ShellPrism::Jacobian jacobian;  ///< the map's, at (or a hair from) `point`
};

/// The outcome of locating the ray's point at some distance.
enum class Located { Inside, AboveTop, OpenSide, Lost };

/// Where a prism point found in cursor.prism lies against the prism's side faces: inside them,
/// beyond an open border, or beyond a side with a neighbour, where `cursor` has walked: the
/// neighbour, the ray origin's offset from its corner 0 and a guess of the point in it (exact
/// where the two triangles form a parallelogram).
enum class SideWalk { Inside, OpenSide, Walked };
SideWalk walkAcrossSide(const ShellPrisms& shell, const glm::dvec3& origin, CurvedCursor& cursor);

/// Moves `cursor` to the prism holding the ray's point at `distanceWorld` (walking to neighbours
/// across side faces, at most 64 of them) and inverts the map there from cursor.point as the
/// guess. AboveTop: the point is above the top (depth < 0) of the prism it is in; OpenSide: it is
/// beyond a border without a neighbour; Lost: no prism found (a fold, a walk that does not end).
Located locate(const ShellPrisms& shell, const glm::dvec3& origin, const glm::dvec3& direction,
               double distanceWorld, CurvedCursor& cursor);

/// Moves `point` `world` units along a ray whose prism-space velocity is `velocity`
/// (d(b1, b2, h) / dt): the linear prediction of where the ray is in the prism.
inline void moveAlong(PrismPoint& point, const glm::dvec3& velocity, double world) {
    point.b1 += velocity.x * world;
    point.b2 += velocity.y * world;
    point.depthWorld += velocity.z * world;
}

/// A march takes its samples by chordStep() while its path since the last Newton step is at
/// most this long, texels (the velocity and stretch it keeps change little over it).
inline constexpr double kChordPathTexels = 4.0;

/// How chordStep() went.
enum class Chord { Taken, Walked, Declined };

/// One chord step to the ray's point at `distanceWorld`, from cursor.point (the guess) with
/// cursor.jacobian kept, the Jacobian of an earlier Newton step in the same prism: the map's
/// residual there solved with it. Taken: cursor.point is the corrected point (it moved as
/// little as a converged Newton step, and lies in the prism between its top and floor). Walked:
/// the corrected point lies beyond a side with a neighbour, and `cursor` has walked into it
/// (walkAcrossSide) for locate() to go on from there. Declined: `cursor` is unchanged.
Chord chordStep(const ShellPrisms& shell, const glm::dvec3& origin, const glm::dvec3& direction,
                double distanceWorld, CurvedCursor& cursor);

/// The texel-space velocity d texel / dt of a ray along unit `direction` where the map's
/// Jacobian is `jacobian`; `prismVelocity` receives d(b1, b2, h) / dt.
inline glm::dvec3 texelVelocity(const ShellPrism& prism, const ShellPrism::Jacobian& jacobian,
                                const glm::dvec3& direction, glm::dvec3& prismVelocity) {
    prismVelocity = jacobian.solve(direction);
    return prism.texelDelta(prismVelocity);
}

}  // namespace detail

/// One ray's march through a curved shell (file note), taken a distance sample at a time like
/// detail::SphereTraceRay, so that marchInterleaved() can overlap several rays' samples: the
/// operations per ray are the same whatever the interleaving. Budgeted settings take the planar
/// march's minimum step (the path left in the shell along the local texel direction over the
/// samples left: to the floor while the ray descends, to the top once it rises) and refine an
/// overshoot by regula falsi; the other sphere-tracing methods step the sampled distance. One
/// iteration per sample.
class CurvedMarchRay {
  public:
    /// Starts the march of `ray` from its entry on the top of prism `entryPrism` (barycentrics
    /// b1, b2 of the entry, `entryDistanceWorld` along the ray). `shell` must outlive the march.
    /// Preconditions: entryPrism < shell.prisms.size(); settings.maxIterations >= 1.
    void start(const ShellPrisms& shell, const Ray& ray, std::uint32_t entryPrism, double b1,
               double b2, double entryDistanceWorld, Floor floor, const MarchSettings& settings);

    /// False once the march has ended (then end() is final).
    bool needsSample() const { return needsSample_; }
    /// Where the next sample is, in the texel space of the prism the ray is in.
    glm::vec3 samplePosition() const { return samplePosition_; }
    /// Takes the distance sampled at samplePosition(); false when no more samples are needed.
    bool advance(float distance);

    const CurvedMarchEnd& end() const { return end_; }

  private:
    /// Locates the ray's point at distanceWorld_, `stepTexels` from the last sample, and sets up
    /// its sample (the step shortened where the texel-space path grew longer than it), or ends
    /// the march there when it is outside the shell.
    bool prepareSample(double stepTexels);
    /// prepareSample's short cut: the point moved `stepTexels` along the velocity, corrected by
    /// one chord step (the map's residual there solved with the Jacobian of the last Newton step,
    /// whose velocity and stretch the march keeps), while the path since that Newton step is at
    /// most detail::kChordPathTexels, the step moves the point as little as a converged Newton
    /// step and the point stays in its prism. False otherwise; a point beyond a side with a
    /// neighbour has then walked into it (locate() goes on from there).
    bool takeChordStep(double stepTexels);
    /// Ends at the current point: a hit (converged, or at the end of the budget).
    bool stop(bool converged);
    /// Ends without a hit: the ray left the shell at `atWorld`, between the last point sampled
    /// inside and distanceWorld_ (outside).
    bool leave(double atWorld);
    /// A sample closer to the floor than `distance` texels: ends on the floor when the ray
    /// reaches it (true), else false and the march goes on.
    bool reachFloor(double toFloorTexels);
    /// Regula falsi: a sample inside or outside narrows the bracket, then toEstimate.
    bool refineStep(float distance);
    /// Moves to the bracket's false position and sets up its sample (ends there without one when
    /// the budget is spent).
    bool toEstimate();

    const ShellPrisms* shell_ = nullptr;
    glm::dvec3 origin_{0.0}, direction_{0.0};
    detail::CurvedCursor cursor_;
    Floor floor_ = Floor::Solid;
    float epsilonTexels_ = 0.0f;
    int budget_ = 0;
    bool budgeted_ = false;
    double entryDistanceWorld_ = 0.0;
    double distanceWorld_ = 0.0;  ///< of the current point
    /// The last point sampled outside the detail, before the current one.
    double outsideWorld_ = 0.0, outsideDepthWorld_ = 0.0;
    float outsideTexels_ = 0.0f;
    bool refining_ = false;
    double insideWorld_ = 0.0;  ///< refining: the bracket's inside end (outside: outsideWorld_)
    float insideTexels_ = 0.0f;
    glm::dvec3 prismVelocity_{0.0};       ///< d(b1, b2, h) / dt at the current point
    glm::dvec3 directionTexels_{0.0};     ///< unit texel-space direction of the ray there
    double speed_ = 0.0;                  ///< |d texel / dt| there: texels per world unit
    double pathSinceNewtonTexels_ = 0.0;  ///< texel path since the Jacobian was taken
    glm::vec3 samplePosition_{0.0f};
    bool needsSample_ = false;
    CurvedMarchEnd end_;
};

/// A point moving along a world ray through a shell by lengths of its texel-space path (the
/// stretch |J r| taken where it is): the path of a self-shadow ray toward a light. The map is
/// inverted (Newton) at every kStepsPerSettle-th step and wherever the point may have left its
/// prism; in between the point moves along the path's tangent there (a soft visibility estimate
/// needs no more: over a few texels the tangent strays by a small fraction of a texel).
class ShellRayPath {
  public:
    /// Starts at world point `originWorld` (in prism `prism`, near prism point `guess`) along
    /// unit `direction`. False when that point is not inside the shell. `shell` must outlive
    /// the path.
    bool start(const ShellPrisms& shell, const glm::dvec3& originWorld, const glm::dvec3& direction,
               std::uint32_t prism, const PrismPoint& guess);
    /// Moves `texels` of texel-space path on; false once the point has left the shell (through
    /// the top or an open border).
    bool advance(double texels);
    /// Where the point is, in the texel space of its prism.
    glm::vec3 texelPosition() const { return texelPosition_; }
    /// The unit texel-space direction of the path there.
    const glm::dvec3& directionTexels() const { return directionTexels_; }

    static constexpr int kStepsPerSettle = 4;

  private:
    /// Locates the point at distanceWorld_ and takes its texel position and direction.
    bool settle();

    const ShellPrisms* shell_ = nullptr;
    glm::dvec3 origin_{0.0}, direction_{0.0};
    detail::CurvedCursor cursor_;
    double distanceWorld_ = 0.0;
    double speed_ = 0.0;  ///< texels per world unit along the path
    glm::dvec3 prismVelocity_{0.0}, directionTexels_{0.0, 0.0, 1.0};
    glm::vec3 texelPosition_{0.0f};
    int stepsSinceSettle_ = 0;
    double pathSinceNewtonTexels_ = 0.0;  ///< texel path since the Jacobian was taken
};

/// A whole curved march of one ray over `filter` (CurvedMarchRay, sample by sample).
template <class Filter>
CurvedMarchEnd marchCurved(const Filter& filter, const ShellPrisms& shell, const Ray& ray,
                           std::uint32_t entryPrism, double b1, double b2,
                           double entryDistanceWorld, Floor floor, const MarchSettings& settings) {
    CurvedMarchRay march;
    march.start(shell, ray, entryPrism, b1, b2, entryDistanceWorld, floor, settings);
    while (march.needsSample() && march.advance(filter.distanceTexels(march.samplePosition()))) {
    }
    return march.end();
}

}  // namespace distile
