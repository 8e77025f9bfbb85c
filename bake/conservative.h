/// @file
/// Conservative tiles: lowering texels so that trilinear interpolation (sampler/filters.h) does
/// not overestimate the true distance by more than a tolerance.
///
/// A tile stores the exact distance at texel centres, but the trilinear interpolant between them
/// overestimates wherever the field is convex along an axis: outside curved surfaces and sharp
/// edges (a cube's edge: up to ~0.15 texel) and, much more, across the kink of a distance field
/// on a medial axis (a wire's centreline: up to half a texel). Overestimates let the sphere
/// tracer step through surface.
///
/// Two ways to find the overestimate, one correction (lower each texel by it, minus an
/// allowance). Which runs:
/// - **Measured**, whenever the exact distance is given: `distile bake mesh` (CGAL's exact
///   distance to the placed mesh). Every point of the half-texel grid is checked: trilinear minus
///   exact distance, beyond the tolerance, is removed by lowering the point's 1-8 interpolation
///   corners by that much (their trilinear weights sum to 1); each texel takes the largest
///   lowering asked of it. Points on the faces z = 0 and z = D, where the filter extends the edge
///   cell linearly (1.5 x the edge slice - 0.5 x its inner neighbour), are corrected by lowering
///   the edge slice (see below). Sharp edges and corners (a cube) get lowered by what they
///   overestimate, not more. Points are checked near the surface (measuredBandTexels) and,
///   farther, wherever a corner texel's estimated lowering (below) is > 0: a kink or a curvature
///   the samples show, such as the medial axis of a vase's cavity 10 texels from its wall (there
///   the estimate alone left overestimates of 0.36 texel in 0.1% of a vase tile's samples; the
///   measured points bring them to 0.14 texel in 0.02%, for 6% more bake time). Beyond the band
///   outside the detail a texel keeps the estimate's lowering if that is larger. More than the
///   band inside, a point need only read at most -band and the texel takes the measured lowering
///   alone: no tracer samples there, and lowering an inner kink (a slab's mid-plane, midway
///   between texel centres: 0.5 texel across the whole tile) cost a slab RMS 0.11 texel.
/// - **Estimated**, otherwise: height maps (bakeHeightMap) and library callers that only have a
///   level set, and under the measured correction, procedural detail. The overestimate around a
///   texel is
///   estimated from the positive parts of its second differences D_a along each axis a
///   (periodic in x and y; the first and last slice use the centred difference of their inner
///   neighbour): sum_a g(D_a), g(D) = smoothFactor * D for D <= kinkThresholdTexels (smooth
///   curvature), kinkFactor * D above it (a kink between samples); lowering = max(0, estimate -
///   allowanceShare * toleranceTexels). Tuned on the default chain mail; it over-lowers at sharp
///   edges (a cube: 0.70 texel near-surface error, measured path 0.50). The measured path was
///   tried on the procedural tiles too: it lowers more across the wires' centreline kinks
///   (Japanese 4-in-1 RMS 0.106 > 0.1 texel), so they keep the estimate. But the estimate alone
///   misses kinks that fall between two texels (the edge of a bar with a sharp corner midway
///   between texel centres: 0.22 texel outside the surface on a 64 x 64 x 16 grating), so
///   procedural bakes take both (measuredOnTopOfEstimate): the estimate, lowered further
///   wherever a point measured against the analytic distance still overestimates its distance
///   to the outside.
/// Faces: the filter extends the edge cells linearly to z = 0 and z = D, so the face value is
/// 1.5 x the edge slice - 0.5 x its inner neighbour. Both paths ask a removal R at each face
/// point: measured there, or estimated (at least the edge slice's own lowering; 3/8 of a concave
/// second difference in z; and where the field is concave in z nearby, where a kink the samples
/// miss may lie right at the face, the face held at the edge slice's value, as the former clamp
/// did). The edge slice is then lowered by at least (R + 0.5 L_inner) / 1.5, L_inner the lowering
/// of the inner neighbour: the face drops by at least R and never rises. So a lowered corner
/// lowers the interpolant in its cells, the outer half texels included, and the tile never
/// rises. Neither path bounds what happens between its samples (a feature smaller than half a
/// texel is invisible to them); both are checked per baked kind against the truth
/// (tests/sampler_test.cpp, tests/cli_test.cpp, `distile check`).
#pragma once

#include <functional>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <span>

#include "sampler/tile.h"

namespace distile {

/// Exact signed distances of the detail at the texel-space points (x, y, z[k]) of one vertical
/// line, texels (negative inside), periodic in x and y like the tile: the measured path asks for
/// its points a line at a time, so the detail's distance can share work between them. Called
/// concurrently from several threads.
using ExactDistancesOnLine = std::function<void(const glm::dvec2& xy, std::span<const double> z,
                                                std::span<double> distances)>;

struct ConservativeOptions {
    bool enabled = true;            ///< false: keep the exact texel-centre distances
    float toleranceTexels = 0.05f;  ///< overestimate the correction aims to stay below, texels
    /// Measured path: points are checked where one of their interpolation corners is within this
    /// of the surface (|value| <= it, texels), and (mesh bakes) where the estimate lowers one;
    /// exact mesh distances are costly, so smooth far fields are not measured.
    float measuredBandTexels = 3.0f;
    /// Measured path: false (mesh bakes) replaces the estimate within the band and deeper
    /// inside by the measured lowering and takes the larger of the two beyond it outside (the
    /// faces' removals there stay estimated); true (procedural bakes) keeps the estimate and
    /// lowers further wherever a point still overestimates its distance to the outside,
    /// max(exact, 0): where a tracer samples. A point inside the detail must only read negative:
    /// the estimate's rougher lowering of the wires' centreline kinks stays (see the file note).
    bool measuredOnTopOfEstimate = false;
    /// Estimated path: part of the tolerance a texel's estimated overestimate may keep (the
    /// measured path removes everything beyond the tolerance at its points).
    float allowanceShare = 0.9f;
    /// Estimated path only: lowering per unit of second difference (1/8 = exact for constant
    /// curvature), the threshold above which a second difference is a kink, and the lowering per
    /// unit of second difference at a kink (at most 1/2).
    float smoothFactor = 0.15f;
    float kinkThresholdTexels = 0.8f;
    float kinkFactor = 0.3f;
};

/// Lowers the texels of `tile` (which must hold the exact distances at texel centres, clamped to
/// the level set's band) as the file note says: measured against `exactDistances` when it is
/// given, estimated otherwise; nothing when !options.enabled. Multi-threaded; the result does not
/// depend on the thread count. Throws InputError when a factor or share is negative or not
/// finite, or the tolerance is negative.
void makeConservative(Tile& tile, const ConservativeOptions& options,
                      const ExactDistancesOnLine& exactDistances = {});

}  // namespace distile
