// The mesh bake (bake/solid_mesh.h) and its exact distance and winding-number sign
// (bake/soup_distance.h), against closed-form distances.
#include "bake/bake.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <glm/geometric.hpp>
#include <optional>
#include <random>
#include <span>

#include "bake/bake_cache.h"
#include "bake/height_image.h"
#include "bake/mesh_surface.h"
#include "bake/provenance.h"
#include "bake/solid_mesh.h"
#include "bake/soup_distance.h"
#include "bake/soup_distance_grid.h"
#include "common/error.h"
#include "detail_meshes.h"
#include "render/renderer.h"
#include "sampler/filters.h"
#include "sampler/tile_error.h"
#include "sampler/tile_io.h"
#include "scene/scene_file.h"
#include "tests/on_threads.h"
#include "tests/temp_folder.h"
#include "truth/mesh_truth.h"
#include "vdb/height_field.h"

namespace distile {
namespace {

namespace fs = std::filesystem;

using test::inscribedTessellationError;
using test::makeBoxSoup;
using test::makeIcosphereSoup;
using test::makeTorusSoup;

/// Appends `part`'s triangles to `soup` (no corners shared: a soup of parts).
void append(TriangleSoup& soup, const TriangleSoup& part) {
    const unsigned base = unsigned(soup.positions.size());
    soup.positions.insert(soup.positions.end(), part.positions.begin(), part.positions.end());
    for (const glm::uvec3& t : part.triangles) soup.triangles.push_back(t + glm::uvec3(base));
}

/// Random points in the box [lo, hi].
std::vector<glm::dvec3> randomPoints(const glm::dvec3& lo, const glm::dvec3& hi, int count,
                                     unsigned seed) {
    std::mt19937 random(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<glm::dvec3> points;
    for (int n = 0; n < count; ++n)
        points.push_back(lo + (hi - lo) * glm::dvec3(unit(random), unit(random), unit(random)));
    return points;
}

// A tile big enough that the periodic copies stay farther than the cutoff.
const Size3 kLargeTile{256, 256, 96};
constexpr double kCutoff = 30.0;

TEST(SoupDistance, IcosphereMatchesTheAnalyticSphereWithinItsTessellation) {
    // r = 40 texels, 5120 triangles: the mesh lies between the inscribed and the analytic
    // sphere, so its distance differs from the sphere's by at most their gap (0.03 texel).
    const glm::dvec3 centre(128.3, 127.6, 48.2);
    const double radius = 40.0;
    const TriangleSoup sphere = makeIcosphereSoup(centre, radius, 4);
    const double tolerance = inscribedTessellationError(sphere, centre, radius) + 1e-9;
    ASSERT_LT(tolerance, 0.05);
    const SoupDistance distance(sphere, kLargeTile);
    double maxError = 0.0;
    for (const glm::dvec3& p : randomPoints(centre - 55.0, centre + 55.0, 20000, 1)) {
        const double analytic = glm::length(p - centre) - radius;
        if (std::abs(analytic) >= kCutoff - 1.0) continue;
        const double baked = distance.signedDistance(p, kCutoff);
        maxError = std::max(maxError, std::abs(baked - analytic));
        if (std::abs(analytic) > tolerance) {
            ASSERT_EQ(baked < 0.0, analytic < 0.0) << p.x << " " << p.y << " " << p.z;
        }
    }
    EXPECT_LE(maxError, tolerance);
    // Beyond the cutoff: the cutoff, signed.
    EXPECT_EQ(distance.signedDistance(centre, 10.0), -10.0);
    EXPECT_EQ(distance.signedDistance(centre + glm::dvec3(0, 0, 45.0), 1.0), 1.0);
}

TEST(SoupDistance, WindingNumberOfAClosedMeshIsOneInsideAndZeroOutside) {
    // Away from the surface the first-order far field (dipoles at 2 node radii) stays within 0.1
    // of the exact 0 / 1 (0.05 measured): far from 1/2, so the sign is never in doubt.
    const TriangleSoup torus = makeTorusSoup(glm::dvec3(128.0, 128.0, 48.0), 30.0, 10.0, 96, 48);
    const SoupDistance distance(torus, kLargeTile);
    for (const glm::dvec3& p :
         randomPoints(glm::dvec3(80, 80, 30), glm::dvec3(176, 176, 66), 5000, 2)) {
        const double radial = std::hypot(p.x - 128.0, p.y - 128.0);
        const double tube = std::hypot(radial - 30.0, p.z - 48.0) - 10.0;
        if (std::abs(tube) < 0.5) continue;
        EXPECT_NEAR(distance.windingNumber(p), tube < 0.0 ? 1.0 : 0.0, 0.1);
    }
}

TEST(SoupDistance, OverlappingSpheresInOneSoupAreInsideWhereEitherIs) {
    const glm::dvec3 a(110.0, 128.0, 48.0), b(135.0, 130.0, 50.0);
    TriangleSoup soup = makeIcosphereSoup(a, 20.0, 3);
    append(soup, makeIcosphereSoup(b, 18.0, 3));
    const double tolerance = inscribedTessellationError(makeIcosphereSoup(a, 20.0, 3), a, 20.0);
    const SoupDistance distance(soup, kLargeTile);
    int inside = 0;
    for (const glm::dvec3& p :
         randomPoints(glm::dvec3(80, 100, 20), glm::dvec3(165, 160, 80), 20000, 3)) {
        const double analytic =
            std::min(glm::length(p - a) - 20.0, glm::length(p - b) - 18.0);  // the union
        if (std::abs(analytic) <= tolerance) continue;
        const double baked = distance.signedDistance(p, kCutoff);
        ASSERT_EQ(baked < 0.0, analytic < 0.0) << p.x << " " << p.y << " " << p.z;
        inside += baked < 0.0;
        // Outside, the distance is the union's; inside, the distance to the nearest surface
        // (the inner sphere's wall counts too): never farther than the union's depth.
        if (analytic > 0.0) {
            EXPECT_NEAR(baked, std::min(analytic, kCutoff), tolerance);
        }
    }
    EXPECT_GT(inside, 1000);  // the test measures something
}

TEST(SoupDistance, DuplicatedAndFlippedFacesKeepTheSign) {
    const glm::dvec3 centre(128.0, 128.0, 48.0);
    const TriangleSoup sphere = makeIcosphereSoup(centre, 30.0, 4);
    const double tolerance = inscribedTessellationError(sphere, centre, 30.0);
    // Every face twice (w = 2 inside), and a tenth of the faces flipped (w = 1 - 2 x their solid
    // angle share: wrong only right next to a flipped face).
    TriangleSoup duplicated = sphere;
    append(duplicated, sphere);
    TriangleSoup flipped = sphere;
    std::vector<glm::dvec3> flippedCentres;
    for (std::size_t t = 0; t < flipped.triangles.size(); t += 10) {
        glm::uvec3& f = flipped.triangles[t];
        std::swap(f.y, f.z);
        flippedCentres.push_back(
            (flipped.positions[f.x] + flipped.positions[f.y] + flipped.positions[f.z]) / 3.0);
    }
    const SoupDistance duplicatedDistance(duplicated, kLargeTile);
    const SoupDistance flippedDistance(flipped, kLargeTile);
    for (const glm::dvec3& p : randomPoints(centre - 40.0, centre + 40.0, 10000, 4)) {
        const double analytic = glm::length(p - centre) - 30.0;
        if (std::abs(analytic) <= tolerance) continue;
        ASSERT_EQ(duplicatedDistance.signedDistance(p, kCutoff) < 0.0, analytic < 0.0);
        EXPECT_NEAR(std::abs(duplicatedDistance.signedDistance(p, kCutoff)),
                    std::min(std::abs(analytic), kCutoff), tolerance);
        // Farther than a face's size (1.6 texels) from a flipped face, its solid angle is small.
        double nearestFlipped = HUGE_VAL;
        for (const glm::dvec3& c : flippedCentres)
            nearestFlipped = std::min(nearestFlipped, glm::length(p - c));
        if (nearestFlipped < 2.0) continue;
        ASSERT_EQ(flippedDistance.signedDistance(p, kCutoff) < 0.0, analytic < 0.0)
            << p.x << " " << p.y << " " << p.z;
    }
}

TEST(SoupDistance, OpenCupUnsignedDistanceIsTheWallsAndBottom) {
    // A cylinder wall (radius 20, height 30, 128 segments) and its bottom disk, no top.
    const glm::dvec3 base(128.0, 128.0, 30.0);
    const double radius = 20.0, height = 30.0;
    const int segments = 128;
    TriangleSoup cup;
    cup.positions.push_back(base);
    for (int s = 0; s < segments; ++s) {
        const double angle = 2.0 * std::numbers::pi * s / segments;
        const glm::dvec3 rim(radius * std::cos(angle), radius * std::sin(angle), 0.0);
        cup.positions.push_back(base + rim);
        cup.positions.push_back(base + rim + glm::dvec3(0, 0, height));
    }
    for (unsigned s = 0; s < unsigned(segments); ++s) {
        const unsigned next = (s + 1) % segments;
        const unsigned bottom = 1 + 2 * s, top = bottom + 1, nextBottom = 1 + 2 * next,
                       nextTop = nextBottom + 1;
        cup.triangles.emplace_back(0u, nextBottom, bottom);
        cup.triangles.emplace_back(bottom, nextBottom, nextTop);
        cup.triangles.emplace_back(bottom, nextTop, top);
    }
    const double sagitta = radius * (1.0 - std::cos(std::numbers::pi / segments));
    const SoupDistance distance(cup, kLargeTile);
    for (const glm::dvec3& p :
         randomPoints(base - glm::dvec3(30, 30, 10), base + glm::dvec3(30, 30, 40), 10000, 5)) {
        const glm::dvec3 q = p - base;
        const double rho = std::hypot(q.x, q.y);
        // The wall: a segment in the (rho, z) half plane from (radius, 0) to (radius, height).
        const double wall = std::hypot(rho - radius, std::max({0.0, -q.z, q.z - height}));
        // The bottom disk.
        const double bottom = std::hypot(std::max(0.0, rho - radius), q.z);
        const double analytic = std::min(wall, bottom);
        if (analytic >= kCutoff) continue;
        EXPECT_NEAR(distance.unsignedDistance(p, kCutoff), analytic, sagitta + 1e-9);
    }
}

TEST(SoupDistance, PeriodicDistanceMatchesTheExactMeshDistanceAcrossTheWrap) {
    const Size3 tile{64, 64, 16};
    const TriangleSoup torus = makeTorusSoup(glm::dvec3(3.3, 60.2, 8.1), 14.0, 5.0, 96, 48);
    const SoupDistance distance(torus, tile);
    const MeshDistance truth(torus, MeshDistance::Periodic{tile});
    for (const glm::dvec3& p : randomPoints(glm::dvec3(0.0), glm::dvec3(64, 64, 16), 5000, 6)) {
        const double exact = truth.signedDistance(p);
        EXPECT_NEAR(distance.signedDistance(p, 100.0), exact, 1e-9);
    }
}

TEST(SoupDistance, SliverTriangleIsTheSegmentItSpans) {
    // Three collinear corners (the middle one listed last) and one whose corners are off a line
    // only by rounding: the distance is to the segment between the outer corners, from any side.
    // The closest-point region tests misclassified about 1% of points against such slivers, by up
    // to 0.7 of their length.
    const Size3 tile{256, 256, 64};
    const glm::dvec3 from(100.25, 100.5, 20.0), to(110.75, 104.5, 26.0);
    const glm::dvec3 direction = to - from;
    for (const glm::dvec3 middle :
         {from + 0.37 * direction, from + 0.61 * direction + glm::dvec3(1e-14, -1e-14, 0.0)}) {
        TriangleSoup sliver;
        sliver.positions = {from, to, middle};
        sliver.triangles = {{0, 1, 2}};
        const SoupDistance distance(sliver, tile);
        for (const glm::dvec3& p :
             randomPoints(from - glm::dvec3(8.0), to + glm::dvec3(8.0), 20000, 11)) {
            const double t = std::clamp(
                glm::dot(p - from, direction) / glm::dot(direction, direction), 0.0, 1.0);
            ASSERT_NEAR(distance.unsignedDistance(p, 100.0), glm::length(p - from - t * direction),
                        1e-9)
                << p.x << " " << p.y << " " << p.z;
        }
    }
}

TEST(SoupDistance, SegmentTouchesNoTriangleOnlyWhenItMissesEveryCopy) {
    // A closed box overhanging the +x edge of a 64-wide tile: its copy shifted by -64 spans
    // x in [-4, 6].
    const Size3 tile{64, 64, 32};
    const SoupDistance box(makeBoxSoup(glm::dvec3(60, 20, 10), glm::dvec3(70, 30, 20)), tile);
    ASSERT_TRUE(box.windingChangesOnlyAcrossTheSurface());
    // Clear of it: below the floor, inside it, beside the copy.
    EXPECT_TRUE(box.segmentTouchesNoTriangle({62.5, 25.5, 8.5}, {62.5, 25.5, 9.5}));
    EXPECT_TRUE(box.segmentTouchesNoTriangle({62.5, 25.5, 14.5}, {63.5, 25.5, 14.5}));
    EXPECT_TRUE(box.segmentTouchesNoTriangle({7.5, 25.5, 14.5}, {8.5, 25.5, 14.5}));
    // Across a face, across the copy's face at x = 6, ending on a face, through an edge.
    EXPECT_FALSE(box.segmentTouchesNoTriangle({62.5, 25.5, 9.5}, {62.5, 25.5, 10.5}));
    EXPECT_FALSE(box.segmentTouchesNoTriangle({5.5, 25.5, 14.5}, {6.5, 25.5, 14.5}));
    EXPECT_FALSE(box.segmentTouchesNoTriangle({62.5, 25.5, 9.0}, {62.5, 25.5, 10.0}));
    EXPECT_FALSE(box.segmentTouchesNoTriangle({61.5, 20.5, 9.5}, {61.5, 19.5, 10.5}));
}

TEST(SoupDistance, WindingNumberByCrossingsCountsOverlapsAndCopies) {
    // A torus and a sphere that overlap (w = 2 where both are), a box listed twice (w = 2) and a
    // box overhanging the +x edge of the tile (its copy shifted by -64 spans x in [-4, 6]).
    const Size3 tile{64, 64, 32};
    const glm::dvec3 torusCentre(20.0, 30.0, 8.0), sphereCentre(30.0, 32.0, 9.0);
    TriangleSoup soup = makeTorusSoup(torusCentre, 12.0, 4.0, 48, 16);
    const TriangleSoup sphere = makeIcosphereSoup(sphereCentre, 6.0, 2);
    append(soup, sphere);
    const glm::dvec3 twiceLo(40.0, 4.0, 2.0), twiceHi(50.2, 14.7, 13.1);
    append(soup, makeBoxSoup(twiceLo, twiceHi));
    append(soup, makeBoxSoup(twiceLo, twiceHi));
    const glm::dvec3 edgeLo(60.0, 40.0, 10.0), edgeHi(70.0, 50.0, 20.0);
    append(soup, makeBoxSoup(edgeLo, edgeHi));
    const SoupDistance distance(soup, tile);
    ASSERT_TRUE(distance.windingChangesOnlyAcrossTheSurface());
    // The faces lie within this of the analytic torus and sphere (inscribed tessellations).
    const double tessellation = inscribedTessellationError(sphere, sphereCentre, 6.0);
    const auto insideBox = [](glm::dvec3 p, const glm::dvec3& lo, const glm::dvec3& hi) {
        return p.x > lo.x && p.x < hi.x && p.y > lo.y && p.y < hi.y && p.z > lo.z && p.z < hi.z;
    };
    int counted = 0, unclear = 0;
    const std::vector<glm::dvec3> points =
        randomPoints(glm::dvec3(0.0), glm::dvec3(64.0, 64.0, 24.0), 20000, 11);
    for (const glm::dvec3& p : points) {
        const double tube = std::hypot(std::hypot(p.x - torusCentre.x, p.y - torusCentre.y) - 12.0,
                                       p.z - torusCentre.z) -
                            4.0;
        const double ball = glm::length(p - sphereCentre) - 6.0;
        if (std::abs(tube) <= tessellation || std::abs(ball) <= tessellation) continue;
        const int expected = (tube < 0.0) + (ball < 0.0) + 2 * insideBox(p, twiceLo, twiceHi) +
                             insideBox(p, edgeLo, edgeHi) +
                             insideBox(p + glm::dvec3(64.0, 0.0, 0.0), edgeLo, edgeHi);
        const std::optional<int> crossings = distance.windingNumberByCrossings(p);
        if (!crossings) {
            ++unclear;
            continue;
        }
        ASSERT_EQ(*crossings, expected) << p.x << " " << p.y << " " << p.z;
        counted += expected;
    }
    EXPECT_GT(counted, 1000);  // the test measures the insides
    EXPECT_LT(unclear, 20);    // a random ray grazes an edge almost never
}

/// A closed soup whose winding number reaches 2 (a box listed twice) and 1 where a torus and a
/// sphere overlap, and the open cup's wall (no inside of its own).
TriangleSoup overlappingClosedParts() {
    TriangleSoup soup = makeTorusSoup(glm::dvec3(20.0, 30.0, 8.0), 12.0, 4.0, 48, 16);
    append(soup, makeIcosphereSoup(glm::dvec3(30.0, 32.0, 9.0), 6.0, 2));
    const TriangleSoup box = makeBoxSoup(glm::dvec3(50.0, 4.0, 2.0), glm::dvec3(60.2, 14.7, 13.1));
    append(soup, box);
    append(soup, box);
    return soup;
}

TEST(SoupDistanceGrid, EveryVoxelIsTheExactDistanceSignedByItsWindingNumber) {
    const Size3 tile{64, 64, 16};
    const TriangleSoup soup = overlappingClosedParts();
    const SoupDistance distance(soup, tile);
    ASSERT_TRUE(distance.windingChangesOnlyAcrossTheSurface());
    const MeshDistance truth(soup, MeshDistance::Periodic{tile});
    const double cutoff = 6.0;
    const auto bakeGrid = [&] { return soupDistanceGrid(distance, -3, 19, cutoff, true); };
    const SoupDistanceGrid grid = onThreads(2, bakeGrid);
    EXPECT_EQ(onThreads(1, bakeGrid).distancesTexels, grid.distancesTexels);
    int inside = 0, checkedSigns = 0;
    for (int k = -3; k < 19; ++k) {
        for (int j = 0; j < tile.height; ++j) {
            for (int i = 0; i < tile.width; ++i) {
                const glm::dvec3 p(i + 0.5, j + 0.5, k + 0.5);
                const double baked = grid.row(j, k)[i];
                // The same double as a query of its own (the row hint never changes a result),
                // and CGAL's exact distance.
                ASSERT_EQ(std::abs(baked), distance.unsignedDistance(p, cutoff));
                ASSERT_NEAR(std::abs(baked), std::min(truth.unsignedDistance(p), cutoff), 1e-9);
                // Where the far-field winding number is unambiguous it decides alone.
                const double winding = distance.windingNumber(p);
                if (std::abs(winding - 0.5) < 0.25) continue;
                ++checkedSigns;
                ASSERT_EQ(baked<0.0, winding> 0.5) << p.x << " " << p.y << " " << p.z;
                inside += baked < 0.0;
            }
        }
    }
    EXPECT_GT(checkedSigns, 64 * 64 * 20);
    EXPECT_GT(inside, 1500);  // the box alone holds ~1100 voxels, the torus ~1800
    // Points between the voxels (as the conservative pass asks), a vertical line of them started
    // from the grid's nearest triangles (beyond the tile's edges too), take the same signed
    // distance as a query of their own.
    for (const glm::dvec3& q : randomPoints(glm::dvec3(-8.0), glm::dvec3(72, 72, 16), 300, 8)) {
        const std::vector<double> z{0.0, 0.5, 1.7, q.z, 9.25, 15.5, 16.0};
        std::vector<SoupDistance::NearestHint> hints;
        for (double zn : z) hints.push_back(grid.hintNear({q.x, q.y, zn}));
        std::vector<double> line(z.size());
        distance.unsignedDistancesOnLine({q.x, q.y}, z, cutoff, hints, line);
        for (std::size_t n = 0; n < z.size(); ++n) {
            const glm::dvec3 p(q.x, q.y, z[n]);
            ASSERT_EQ(line[n], distance.unsignedDistance(p, cutoff));
            const double winding = distance.windingNumber(p);
            if (std::abs(winding - 0.5) < 0.25) continue;
            EXPECT_EQ(signedDistanceBesideGrid(distance, grid, p, line[n]),
                      distance.signedDistance(p, cutoff));
        }
    }
}

TEST(SoupDistanceGrid, OpenMeshesTakeTheWindingNumberAtEveryVoxel) {
    // Half of an icosphere: open, so the winding number varies off the surface too.
    TriangleSoup half = makeIcosphereSoup(glm::dvec3(32.0, 32.0, 8.0), 7.0, 2);
    std::erase_if(half.triangles, [&](const glm::uvec3& t) {
        return half.positions[t.x].z + half.positions[t.y].z + half.positions[t.z].z < 24.0;
    });
    const Size3 tile{64, 64, 16};
    const SoupDistance distance(half, tile);
    ASSERT_FALSE(distance.windingChangesOnlyAcrossTheSurface());
    const SoupDistanceGrid grid = soupDistanceGrid(distance, 0, 16, 8.0, true);
    int inside = 0;
    for (int k = 0; k < 16; ++k) {
        for (int j = 0; j < tile.height; ++j) {
            for (int i = 0; i < tile.width; ++i) {
                const glm::dvec3 p(i + 0.5, j + 0.5, k + 0.5);
                ASSERT_EQ(grid.row(j, k)[i], distance.signedDistance(p, 8.0));
                inside += grid.row(j, k)[i] < 0.0;
            }
        }
    }
    EXPECT_GT(inside, 100);
}

/// Signed distance to the axis-aligned box [lo, hi] (negative inside).
double boxDistance(const glm::dvec3& p, const glm::dvec3& lo, const glm::dvec3& hi) {
    const glm::dvec3 outside = glm::max(glm::max(lo - p, p - hi), glm::dvec3(0.0));
    const double inside =
        std::min({p.x - lo.x, hi.x - p.x, p.y - lo.y, hi.y - p.y, p.z - lo.z, hi.z - p.z});
    return glm::length(outside) > 0.0 ? glm::length(outside) : -inside;
}

TEST(SoupDistanceGrid, NearestPointsBoundOnlyWhereEveryNearestTriangleIsSurface) {
    // A box's voxels find their nearest points on faces and on edges (whose neighbour tells the
    // side): all bound the inside. Two overlapping spheres: the voxels inside both find inner
    // walls (winding 1 in front). Two boxes touching face to face: the voxels by the shared face
    // find it tied with its twin of the other box (winding 1 on both sides).
    const Size3 tile{32, 32, 16};
    const auto bound = [&tile](const TriangleSoup& soup) {
        const SoupDistance distance(soup, tile);
        EXPECT_TRUE(distance.windingChangesOnlyAcrossTheSurface());
        return soupDistanceGrid(distance, 0, 16, 8.0, true).nearestPointsBound;
    };
    EXPECT_TRUE(bound(makeBoxSoup(glm::dvec3(4.2, 5.3, 3.1), glm::dvec3(13.7, 12.4, 11.6))));
    EXPECT_TRUE(bound(makeIcosphereSoup(glm::dvec3(16.0, 16.0, 8.0), 6.0, 3)));
    TriangleSoup spheres = makeIcosphereSoup(glm::dvec3(12.0, 16.0, 8.0), 6.0, 3);
    append(spheres, makeIcosphereSoup(glm::dvec3(19.0, 16.5, 8.0), 5.0, 3));
    EXPECT_FALSE(bound(spheres));
    TriangleSoup boxes = makeBoxSoup(glm::dvec3(4.0, 4.0, 4.0), glm::dvec3(12.0, 12.0, 12.0));
    append(boxes, makeBoxSoup(glm::dvec3(12.0, 4.0, 4.0), glm::dvec3(20.0, 12.0, 12.0)));
    EXPECT_FALSE(bound(boxes));
}

TEST(UnbalancedEdges, MatchCornersByPositionWeldedOrNot) {
    // A closed box is balanced whether its triangles share corners or each has its own; without
    // one triangle, the hole's three edges are unbalanced; a flipped triangle's three edges are
    // used twice one way.
    const TriangleSoup box = makeBoxSoup(glm::dvec3(1.0), glm::dvec3(2.0, 3.0, 4.0));
    const auto unwelded = [](const TriangleSoup& soup) {
        TriangleSoup corners;
        for (const glm::uvec3& t : soup.triangles) {
            const unsigned first = unsigned(corners.positions.size());
            for (int c = 0; c < 3; ++c) corners.positions.push_back(soup.positions[t[c]]);
            corners.triangles.emplace_back(first, first + 1, first + 2);
        }
        return corners;
    };
    EXPECT_TRUE(unbalancedEdges(box).empty());
    EXPECT_TRUE(unbalancedEdges(unwelded(box)).empty());
    TriangleSoup open = box;
    const glm::uvec3 removed = open.triangles.back();
    open.triangles.pop_back();
    for (const TriangleSoup& soup : {open, unwelded(open)}) {
        const std::vector<UnbalancedEdge> edges = unbalancedEdges(soup);
        ASSERT_EQ(edges.size(), 3u);
        for (const UnbalancedEdge& edge : edges) {
            int corners = 0;
            for (int c = 0; c < 3; ++c)
                corners +=
                    (edge.a == box.positions[removed[c]]) + (edge.b == box.positions[removed[c]]);
            EXPECT_EQ(corners, 2);
        }
    }
    TriangleSoup flipped = box;
    std::swap(flipped.triangles[0].y, flipped.triangles[0].z);
    EXPECT_EQ(unbalancedEdges(flipped).size(), 3u);
    EXPECT_EQ(unbalancedEdges(unwelded(flipped)).size(), 3u);
}

TEST(SoupDistance, SideOfNearestPointTellsTiesAndSides) {
    // A point inside a box 0.3 from the middle of its +x face is behind it. With a second box on
    // the other side of that face, the face's twin is tied with it: no side can be told.
    const Size3 tile{32, 32, 16};
    const auto query = [&tile](const TriangleSoup& soup, const glm::dvec3& p, double expected) {
        const SoupDistance distance(soup, tile);
        std::array<SoupDistance::NearestHint, 1> hint, tie;
        std::array<double, 1> d;
        distance.unsignedDistancesOnLine({p.x, p.y}, std::span(&p.z, 1), 8.0, hint, d, tie);
        EXPECT_NEAR(d[0], expected, 1e-12);
        EXPECT_NE(tie[0].triangle, SoupDistance::kSeveralTriangles);
        return std::pair(tie[0], distance.sideOfNearestPoint(p, hint[0], tie[0]));
    };
    const glm::dvec3 p(11.7, 9.1, 7.6);  // clear of the faces' diagonals
    const TriangleSoup box = makeBoxSoup(glm::dvec3(4.0), glm::dvec3(12.0));
    const auto [none, behind] = query(box, p, 0.3);
    EXPECT_EQ(none.triangle, UINT32_MAX);
    EXPECT_EQ(behind, -1);
    EXPECT_EQ(query(box, glm::dvec3(12.3, 9.1, 7.6), 0.3).second, 1);
    TriangleSoup boxes = box;
    append(boxes, makeBoxSoup(glm::dvec3(12.0, 4.0, 4.0), glm::dvec3(20.0, 12.0, 12.0)));
    const auto [twin, unknown] = query(boxes, p, 0.3);
    EXPECT_NE(twin.triangle, UINT32_MAX);
    EXPECT_EQ(unknown, 0);
    // Nearest to the edge x = 12, y = 12 of the box: its neighbour face is the tie, and the
    // point, outside both faces, is in front.
    const auto [neighbour, outsideEdge] = query(box, glm::dvec3(12.4, 12.3, 7.6), 0.5);
    EXPECT_NE(neighbour.triangle, UINT32_MAX);
    EXPECT_EQ(outsideEdge, 1);
}

TEST(MeshBake, BoxesTouchingFaceToFaceBakeAsTheirUnion) {
    // The shared face is no surface (winding 1 on both sides): every texel is the distance to
    // the union box (periodic), exactly (float rounding).
    BakeOptions options;
    options.size = {32, 32, 16};
    options.conservative.enabled = false;
    TriangleSoup boxes = makeBoxSoup(glm::dvec3(4.0, 4.0, 4.0), glm::dvec3(12.0, 12.0, 12.0));
    append(boxes, makeBoxSoup(glm::dvec3(12.0, 4.0, 4.0), glm::dvec3(20.0, 12.0, 12.0)));
    MeshPlacement placement;
    placement.fit = false;
    const SolidMeshBake bake = bakeSolidMesh(boxes, placement, options, "boxes");
    const Tile& tile = bake.result.tile;
    double maxError = 0.0;
    for (int k = 0; k < 16; ++k) {
        for (int j = 0; j < 32; ++j) {
            for (int i = 0; i < 32; ++i) {
                const glm::dvec3 p(i + 0.5, j + 0.5, k + 0.5);
                // The union box and its periodic copies (disjoint: the least of theirs).
                double exact = 16.0;
                for (int m = -1; m <= 1; ++m) {
                    for (int n = -1; n <= 1; ++n) {
                        const glm::dvec3 copy = p - glm::dvec3(32.0 * m, 32.0 * n, 0.0);
                        exact = std::min(exact, boxDistance(copy, glm::dvec3(4.0, 4.0, 4.0),
                                                            glm::dvec3(20.0, 12.0, 12.0)));
                    }
                }
                maxError = std::max(maxError, std::abs(tile.at(i, j, k) - exact));
            }
        }
    }
    EXPECT_LE(maxError, 1e-5);
}

/// A sphere of radius 6 texels at `centre` in a 32x32x16 tile, baked with exact texels.
SolidMeshBake bakeSphere(const BakeOptions& options, const glm::dvec3& centre) {
    const TriangleSoup sphere = makeIcosphereSoup(glm::dvec3(0.0), 1.0, 4);
    MeshPlacement placement;
    placement.fit = false;
    placement.scale = 6.0;
    placement.offsetTexels = centre;
    return bakeSolidMesh(sphere, placement, options, "sphere");
}

TEST(MeshBake, SphereTileIsTheAnalyticDistanceForAnyThreadCount) {
    BakeOptions options;
    options.size = {32, 32, 16};
    options.conservative.enabled = false;
    const glm::dvec3 centre(30.0, 16.5, 8.0);  // across the x wrap
    const double tolerance = inscribedTessellationError(makeIcosphereSoup(glm::dvec3(0.0), 6.0, 4),
                                                        glm::dvec3(0.0), 6.0);
    const auto bake = [&] { return bakeSphere(options, centre); };
    const SolidMeshBake single = onThreads(1, bake);
    const SolidMeshBake dual = onThreads(2, bake);
    EXPECT_GT(dual.insideTexels, 800u);  // 4/3 pi 6^3 = 905
    const std::span<const float> distances = dual.result.tile.distancesTexels();
    EXPECT_TRUE(std::ranges::equal(single.result.tile.distancesTexels(), distances));
    const Size3& size = options.size;
    double maxError = 0.0;
    for (int z = 0; z < size.depth; ++z) {
        for (int y = 0; y < size.height; ++y) {
            for (int x = 0; x < size.width; ++x) {
                glm::dvec3 offset = glm::dvec3(x + 0.5, y + 0.5, z + 0.5) - centre;
                offset.x -= size.width * std::round(offset.x / size.width);  // nearest copy
                const double analytic =
                    std::clamp(glm::length(offset) - 6.0, -double(size.depth), double(size.depth));
                const float baked = distances[(std::size_t(z) * size.height + y) * size.width + x];
                maxError = std::max(maxError, std::abs(baked - analytic));
            }
        }
    }
    EXPECT_LE(maxError, tolerance + 1e-5);  // float storage
}

TEST(MeshBake, LevelSetMarginsAreLeftOutOnlyWhenAsked) {
    // A sphere 2 texels above the floor: the margin below the tile holds distances under the
    // band when filled.
    BakeOptions options;
    options.size = {32, 32, 16};
    options.conservative.enabled = false;
    const glm::dvec3 centre(16.0, 16.0, 2.0);
    const SolidMeshBake filled = bakeSphere(options, centre);
    options.fillLevelSetMargins = false;
    const SolidMeshBake tileOnly = bakeSphere(options, centre);
    const std::span<const float> a = filled.result.tile.distancesTexels();
    const std::span<const float> b = tileOnly.result.tile.distancesTexels();
    EXPECT_TRUE(std::equal(a.begin(), a.end(), b.begin(), b.end()));
    // Voxel (16, 16, -3), centred at (16.5, 16.5, -2.5): inside the sphere, sqrt(20.75) - 6 =
    // -1.445 (the faces lie within 0.02 of it), far inside the band of 16.
    EXPECT_NEAR(filled.result.levelSet.voxelDistanceTexels(16, 16, -3), std::sqrt(20.75) - 6.0,
                0.02);
    EXPECT_EQ(tileOnly.result.levelSet.voxelDistanceTexels(16, 16, -3), 16.0f);
    EXPECT_EQ(tileOnly.result.levelSet.voxelDistanceTexels(16, 16, 0),
              filled.result.levelSet.voxelDistanceTexels(16, 16, 0));
    EXPECT_LT(tileOnly.result.levelSet.activeVoxelCount(),
              filled.result.levelSet.activeVoxelCount());
}

TEST(MeshBake, ConservativeTileNeverOverestimatesAtTexelCentres) {
    BakeOptions options;
    options.size = {32, 32, 16};
    const SolidMeshBake bake = bakeSphere(options, glm::dvec3(16.0, 16.0, 8.0));
    options.conservative.enabled = false;
    const SolidMeshBake exact = bakeSphere(options, glm::dvec3(16.0, 16.0, 8.0));
    const std::span<const float> lowered = bake.result.tile.distancesTexels();
    const std::span<const float> centres = exact.result.tile.distancesTexels();
    for (std::size_t n = 0; n < lowered.size(); ++n) ASSERT_LE(lowered[n], centres[n]);
}

TEST(MeshBake, ASlabKeepsItsExactDistancesDeepInsideAndMeetsTheCheck) {
    // A slab 8 texels thick across the whole (periodic) footprint: d = |z - 8| - 4, whose kink
    // at z = 8 lies midway between texel centres, 4 texels inside. Trilinear overestimates there
    // by up to 0.5 texel, yet reads -3 or less: no tracer samples there. Lowering the kink's
    // two texel planes across the tile (as the estimate did) cost RMS 0.11 > 0.1; those texels
    // keep their exact -3.5 now, and the tile meets both of check's targets.
    BakeOptions options;
    options.size = {32, 32, 16};
    // Overlapping periodic copies: the winding number makes them one slab.
    const TriangleSoup slab =
        makeBoxSoup(glm::dvec3(-4.0, -4.0, 4.0), glm::dvec3(36.0, 36.0, 12.0));
    MeshPlacement placement;
    placement.fit = false;
    const Tile tile = bakeSolidMesh(slab, placement, options, "slab").result.tile;
    for (int y = 0; y < 32; ++y) {
        for (int x = 0; x < 32; ++x) {
            ASSERT_FLOAT_EQ(tile.at(x, y, 7), -3.5f) << x << ", " << y;
            ASSERT_FLOAT_EQ(tile.at(x, y, 8), -3.5f) << x << ", " << y;
        }
    }
    const TileErrorReport report =
        measureTileError(tile, [](const glm::dvec3& p) { return std::abs(p.z - 8.0) - 4.0; });
    EXPECT_LE(report.rmsTexels, 0.1);
    EXPECT_LT(report.overestimateShare, 0.001);
    EXPECT_EQ(report.tracerOverestimates, 0);
    EXPECT_NEAR(report.maxAbsTexels, 0.5, 0.01);  // at the kink
    EXPECT_NEAR(report.maxAbsTruthTexels, -4.0, 0.02);
}

TEST(HeightMapBake, EveryMeasuredPointNearTheSurfaceIsWithinTheTolerance) {
    // A rough height map (pseudo-random heights over 0-14 texels on a 32 x 32 x 16 tile: slopes
    // up to 14 texels per texel). The conservative correction measures the exact distance to
    // the triangulated surface at the half-texel points near it, as a mesh bake's does, and
    // lowers until no such point reads more than the tolerance (0.05 texel) above it; the
    // curvature estimate alone left 0.25 texel where a tracer steps (1.5% of the points of a
    // 64 x 64 noise tile).
    HeightImage image;
    image.width = 32;
    image.height = 32;
    std::mt19937 random(3);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (int n = 0; n < 32 * 32; ++n) image.values.push_back(unit(random));
    BakeOptions options;
    options.size = {32, 32, 16};
    HeightMapOptions heights;
    heights.heightTexels = 14.0;
    const Tile tile = bakeHeightMap(image, heights, options).tile;
    const HeightFieldDistance truth(heightFieldFromImage(image, options.size, 14.0), 64.0);
    const TrilinearFilter filter(tile);
    double worst = -1.0;
    int measured = 0;
    for (int m = 1; m < 32; ++m) {
        for (int b = 0; b < 64; ++b) {
            for (int a = 0; a < 64; ++a) {
                const glm::dvec3 p(0.5 + 0.5 * a, 0.5 + 0.5 * b, 0.5 * m);
                const double exact = truth.signedDistanceTexels(p);
                if (std::abs(exact) > 2.0) continue;  // its corners within 3 texels: measured
                ++measured;
                worst = std::max(worst, double(filter.distanceTexels(glm::vec3(p))) - exact);
            }
        }
    }
    std::printf("[ figures  ] rough height map: largest overestimate %.4f texel at %d points\n",
                worst, measured);
    EXPECT_GT(measured, 20000);
    EXPECT_LE(worst, 0.05 + 1e-5);
}

TEST(MeshBake, SheetWithoutInsideNeedsUnsigned) {
    // A flat quad 4 texels above the floor: no inside anywhere.
    TriangleSoup sheet;
    sheet.positions = {{2, 2, 4}, {30, 2, 4}, {30, 30, 4}, {2, 30, 4}};
    sheet.triangles = {{0, 1, 2}, {0, 2, 3}};
    MeshPlacement placement;
    placement.fit = false;
    BakeOptions options;
    options.size = {32, 32, 8};
    options.conservative.enabled = false;
    try {
        bakeSolidMesh(sheet, placement, options, "sheet.obj");
        FAIL() << "a sheet baked without unsignedDistance";
    } catch (const InputError& error) {
        EXPECT_EQ(error.field(), "sign.unsignedDistance");
        EXPECT_NE(std::string(error.what()).find("sheet.obj"), std::string::npos);
    }
    MeshSignOptions sign;
    sign.unsignedDistance = true;
    sign.thicknessTexels = 2.0;
    const SolidMeshBake shell = bakeSolidMesh(sheet, placement, options, "sheet.obj", {}, sign);
    const Tile& tile = shell.result.tile;
    // Texel centres sit 0.5 texel from the sheet (z = 3.5, 4.5): 0.5 - 1 inside the shell.
    EXPECT_NEAR(tile.at(16, 16, 3), -0.5f, 1e-6f);
    EXPECT_NEAR(tile.at(16, 16, 4), -0.5f, 1e-6f);
    EXPECT_NEAR(tile.at(16, 16, 7), 2.5f, 1e-6f);
    // Two slices of texel columns x, y in [1.5, 30.5]: the edge columns are 0.71 texel away.
    EXPECT_EQ(shell.insideTexels, std::size_t(2 * 30 * 30));
    sign.thicknessTexels = -1.0;
    EXPECT_THROW(bakeSolidMesh(sheet, placement, options, "sheet.obj", {}, sign), InputError);
}

/// The box [lo, hi] without its top face (z = hi.z): open, its hole a known plane.
TriangleSoup makeOpenBoxSoup(const glm::dvec3& lo, const glm::dvec3& hi) {
    TriangleSoup box = makeBoxSoup(lo, hi);
    // makeBoxSoup's second quad (triangles 2 and 3) is the top face.
    box.triangles.erase(box.triangles.begin() + 2, box.triangles.begin() + 4);
    return box;
}

TEST(MeshSurface, ClosedMeshIsAllItsTrianglesWithoutCaps) {
    const Size3 tile{32, 32, 16};
    const TriangleSoup box = makeBoxSoup(glm::dvec3(5, 5, 2), glm::dvec3(15, 15, 12));
    const SoupDistance soup(box, tile);
    const MeshSurface surface(box, soup, tile);
    EXPECT_TRUE(surface.caps().triangles.empty());
    EXPECT_EQ(surface.trimmedTriangles(), 0u);
}

TEST(MeshSurface, OverlappingSpheresMeasureTheirUnionsSurface) {
    // Inside both spheres the walls of each are not surface (w = 2 on one side, 1 on the other):
    // trimmed away, every point takes the distance to the union's surface, within the
    // tessellation and the pieces (kSurfacePieceTexels) kept whole along the spheres' meeting
    // circle. Untrimmed, a point by an inner wall was up to its depth (7 texels here) off.
    const glm::dvec3 a(110.0, 128.0, 48.0), b(135.0, 130.0, 50.0);
    TriangleSoup soup = makeIcosphereSoup(a, 20.0, 3);
    append(soup, makeIcosphereSoup(b, 18.0, 3));
    const double tolerance =
        inscribedTessellationError(makeIcosphereSoup(a, 20.0, 3), a, 20.0) + kSurfacePieceTexels;
    const SoupDistance distance(soup, kLargeTile);
    const MeshSurface surface(soup, distance, kLargeTile);
    EXPECT_GT(surface.trimmedTriangles(), 0u);
    EXPECT_TRUE(surface.caps().triangles.empty());
    // The union's surface: each sphere outside the other ball, bounded by their meeting circle.
    const double ra = 20.0, rb = 18.0, apart = glm::length(b - a);
    const glm::dvec3 axis = (b - a) / apart;
    const double along = (apart * apart + ra * ra - rb * rb) / (2.0 * apart);
    const glm::dvec3 circleCentre = a + along * axis;
    const double circleRadius = std::sqrt(ra * ra - along * along);
    const auto toCircle = [&](const glm::dvec3& p) {
        const double height = glm::dot(p - circleCentre, axis);
        const double radial = glm::length(p - circleCentre - height * axis);
        return std::hypot(height, radial - circleRadius);
    };
    const auto toPart = [&](const glm::dvec3& p, const glm::dvec3& centre, double radius,
                            const glm::dvec3& other, double otherRadius) {
        const glm::dvec3 nearest = centre + radius * glm::normalize(p - centre);
        return glm::length(nearest - other) >= otherRadius
                   ? std::abs(glm::length(p - centre) - radius)
                   : toCircle(p);
    };
    double maxError = 0.0;
    int insideBoth = 0;
    for (const glm::dvec3& p :
         randomPoints(glm::dvec3(80, 100, 20), glm::dvec3(165, 160, 80), 20000, 3)) {
        const bool inA = glm::length(p - a) < ra, inB = glm::length(p - b) < rb;
        const double toSurface = std::min(toPart(p, a, ra, b, rb), toPart(p, b, rb, a, ra));
        const double exact = inA || inB ? -toSurface : toSurface;
        if (std::abs(exact) >= kCutoff - 1.0) continue;
        insideBoth += inA && inB;
        maxError = std::max(maxError, std::abs(surface.signedDistance(p, kCutoff) - exact));
    }
    EXPECT_LE(maxError, tolerance);
    EXPECT_GT(insideBoth, 100);  // the test measures the overlap
}

TEST(MeshBake, UnsignedShellSurfaceIsExactFromThreeTexelsThick) {
    // The unsigned distance has a crease on the sheet: trilinear filtering overestimates it by up
    // to half a texel (the sheet midway between texel centres), so the conservative correction
    // lowers the two texel layers beside it and the tile falls short of the truth within 1.5
    // texels of the sheet. The shell's surface, thickness / 2 from the sheet, lies beyond that
    // from 3 texels thick: there the tile is the exact distance within the correction's
    // tolerance (0.05 texel); at 1 texel it is 0.45 texel off (docs/pipeline.md).
    const auto shellSurfaceError = [](double height, double thickness) {
        TriangleSoup sheet;
        sheet.positions = {{2, 2, height}, {30, 2, height}, {30, 30, height}, {2, 30, height}};
        sheet.triangles = {{0, 1, 2}, {0, 2, 3}};
        MeshPlacement placement;
        placement.fit = false;
        BakeOptions options;
        options.size = {32, 32, 12};
        MeshSignOptions sign;
        sign.unsignedDistance = true;
        sign.thicknessTexels = thickness;
        const SolidMeshBake shell = bakeSolidMesh(sheet, placement, options, "sheet", {}, sign);
        const TrilinearFilter filter(shell.result.tile);
        double largest = 0.0;
        for (double x = 10.0; x < 20.0; x += 0.37) {
            for (double y = 10.0; y < 20.0; y += 0.41) {
                for (double z : {height - 0.5 * thickness, height + 0.5 * thickness}) {
                    largest = std::max(largest,
                                       std::abs(double(filter.distanceTexels(glm::vec3(x, y, z)))));
                }
            }
        }
        return largest;
    };
    for (double height : {4.0, 4.25, 4.5}) EXPECT_LE(shellSurfaceError(height, 3.0), 0.05 + 1e-6);
    EXPECT_NEAR(shellSurfaceError(4.0, 1.0), 0.45, 1e-3);
}

// A box off the texel grid (its top plane between voxel layers, its sides across cells).
const glm::dvec3 kBoxLow(5.3, 4.8, 2.2), kBoxHigh(15.6, 14.1, 11.7);

TEST(MeshSurface, CapOfAnOpenBoxIsItsMissingFace) {
    // A box that is closed but for its top face has w = 1/2 exactly on the missing face (the
    // closed box's 1/2 on its surface, minus the face's solid angle, 0 in its own plane): the
    // cap lies in the box's top plane, inside its top rectangle, and covers all of it (its
    // corners on edges that cross the walls, in the cells along the border, move onto the
    // border).
    const Size3 tile{32, 32, 16};
    const TriangleSoup open = makeOpenBoxSoup(kBoxLow, kBoxHigh);
    const SoupDistance soup(open, tile);
    ASSERT_FALSE(soup.windingChangesOnlyAcrossTheSurface());
    const MeshSurface surface(open, soup, tile);
    const TriangleSoup& cap = surface.caps();
    ASSERT_FALSE(cap.triangles.empty());
    for (const glm::dvec3& p : cap.positions) {
        EXPECT_NEAR(p.z, kBoxHigh.z, 1e-6);
        EXPECT_GE(p.x, kBoxLow.x - 1e-9);
        EXPECT_LE(p.x, kBoxHigh.x + 1e-9);
        EXPECT_GE(p.y, kBoxLow.y - 1e-9);
        EXPECT_LE(p.y, kBoxHigh.y + 1e-9);
    }
    // From a point of the missing face to the mesh and its cap: 0, but within a texel of the
    // top's corners, where the border turns inside a cell and the cap's corners moved onto one
    // side or the other may leave a sliver (0.18 texel measured).
    double farthest = 0.0, farthestNearCorners = 0.0;
    for (int y = 0; y <= 100; ++y) {
        for (int x = 0; x <= 100; ++x) {
            const glm::dvec3 p(glm::mix(kBoxLow.x, kBoxHigh.x, 0.01 * x),
                               glm::mix(kBoxLow.y, kBoxHigh.y, 0.01 * y), kBoxHigh.z);
            SoupDistance::NearestHint hint;
            const double toSurface = surface.unsignedDistance(p, 16.0, hint);
            const double toCorner = std::hypot(std::min(p.x - kBoxLow.x, kBoxHigh.x - p.x),
                                               std::min(p.y - kBoxLow.y, kBoxHigh.y - p.y));
            (toCorner < 1.0 ? farthestNearCorners : farthest) =
                std::max(toCorner < 1.0 ? farthestNearCorners : farthest, toSurface);
        }
    }
    EXPECT_LE(farthest, 1e-6);
    EXPECT_LE(farthestNearCorners, 0.25);
    // Above the middle of the hole the surface is the cap, not the walls 5 texels away.
    EXPECT_NEAR(surface.signedDistance(glm::dvec3(10.2, 9.7, 13.5), 16.0), 1.8, 1e-6);
    EXPECT_NEAR(surface.signedDistance(glm::dvec3(10.2, 9.7, 10.5), 16.0), -1.2, 1e-6);
}

TEST(MeshSurface, OpenBoxBakesAsTheClosedBoxForAnyThreadCount) {
    // The open box's surface is the closed box's: the tiles agree (float storage) wherever the
    // cap covers the hole; closed meshes bake without caps.
    BakeOptions options;
    options.size = {32, 32, 16};
    options.conservative.enabled = false;
    MeshPlacement placement;
    placement.fit = false;
    const TriangleSoup open = makeOpenBoxSoup(kBoxLow, kBoxHigh);
    const TriangleSoup closed = makeBoxSoup(kBoxLow, kBoxHigh);
    const auto bake = [&] { return bakeSolidMesh(open, placement, options, "open"); };
    const SolidMeshBake single = onThreads(1, bake);
    const SolidMeshBake dualBake = onThreads(2, bake);
    const std::span<const float> dual = dualBake.result.tile.distancesTexels();
    EXPECT_TRUE(std::ranges::equal(single.result.tile.distancesTexels(), dual));
    const SolidMeshBake reference = bakeSolidMesh(closed, placement, options, "closed");
    const std::span<const float> expected = reference.result.tile.distancesTexels();
    double maxDifference = 0.0;
    for (std::size_t n = 0; n < expected.size(); ++n)
        maxDifference = std::max(maxDifference, double(std::abs(dual[n] - expected[n])));
    EXPECT_LE(maxDifference, 1e-5);
}

}  // namespace
}  // namespace distile

namespace distile {
namespace {

TEST(BakeOptions, TheBandIsZeroForTheDepthOrOneTexelAndMore) {
    BakeOptions options;
    options.size = {8, 8, 16};
    EXPECT_EQ(validatedHalfBandTexels(options), 16.0f);  // 0: the tile depth
    options.halfBandTexels = 1.0f;
    EXPECT_EQ(validatedHalfBandTexels(options), 1.0f);
    options.halfBandTexels = 32.0f;
    EXPECT_EQ(validatedHalfBandTexels(options), 32.0f);  // twice the depth
    // Under a texel the band holds no texel but the surface's own: refused as the flag is, not by
    // the level set after the work started.
    for (const float band : {0.5f, 1e-30f, -1.0f, 32.5f, std::nanf("")}) {
        options.halfBandTexels = band;
        EXPECT_THROW(validatedHalfBandTexels(options), InputError) << band;
    }
    // Tiles deeper than the widest band (1024) take it by default; it used to be refused.
    options.size = {8, 8, 1100};
    options.halfBandTexels = 0.0f;
    EXPECT_EQ(validatedHalfBandTexels(options), 1024.0f);
}

TEST(Provenance, ARecordedSourceWithoutItsHashOrThatIsNoFileIsRefusedSayingSo) {
    // Without its hash the source read "has changed since the bake (content hash ..., recorded )".
    const TempFolder folder("distile_provenance_hash");
    const fs::path ring = fs::path(DISTILE_SOURCE_DIR) / "data" / "meshes" / "ring.obj";
    Tile tile({8, 8, 4});
    tile.provenance.source = "mesh";
    tile.provenance.sourceFile = ring;
    const auto refusal = [&] {
        try {
            recordedSourceFile(tile, "t.exr");
        } catch (const InputError& error) {
            return std::string(error.what());
        }
        return std::string("accepted");
    };
    EXPECT_NE(refusal().find("without its content hash"), std::string::npos) << refusal();
    tile.provenance.sourceFile = folder.path("");
    EXPECT_NE(refusal().find("is not a regular file"), std::string::npos) << refusal();
}

TEST(BakeCache, AMeshTileRecordsTheFileGivenNotTheCopyBakedBefore) {
    // Two copies of one mesh: the recipe names a file by its bytes, so both bake to one cached
    // tile, but each bake must record its own file, warm cache or cold.
    const TempFolder folder("distile_bake_cache_source");
    const fs::path ring = fs::path(DISTILE_SOURCE_DIR) / "data" / "meshes" / "ring.obj";
    for (const char* copy : {"a", "b"}) {
        fs::create_directories(folder.path(copy));
        fs::copy_file(ring, folder.path(copy) / "ring.obj");
    }
    const std::string recipe = R"({"bake": "mesh", "file": "ring.obj", "size": "32x32x16"})";
    setenv("DISTILE_CACHE", folder.path("cache").c_str(), 1);
    TileCache process, another;
    const auto a = bakeRecipeTile(recipe, folder.path("a"), "a", process);
    const auto fromProcess = bakeRecipeTile(recipe, folder.path("b"), "b", process);
    const auto fromDisk = bakeRecipeTile(recipe, folder.path("b"), "b", another);
    unsetenv("DISTILE_CACHE");
    EXPECT_EQ(a->provenance.sourceFile, folder.path("a") / "ring.obj");
    EXPECT_EQ(fromProcess->provenance.sourceFile, folder.path("b") / "ring.obj");
    EXPECT_EQ(fromDisk->provenance.sourceFile, folder.path("b") / "ring.obj");
    EXPECT_EQ(fromDisk->provenance.sourceHash, a->provenance.sourceHash);
    EXPECT_TRUE(std::ranges::equal(fromDisk->distancesTexels(), a->distancesTexels()));
    EXPECT_TRUE(std::ranges::equal(fromProcess->distancesTexels(), a->distancesTexels()));
}

TEST(BakeCache, ARecipesLevelSetIsBakedWithItsTileAndNoCacheIsReadOrWritten) {
    // A grating kept exact at the texel centres: the level set's voxels are the tile's texels.
    const TempFolder folder("distile_bake_cache_level_set");
    const std::string recipe =
        R"({"bake": "grating", "size": "32x32x16", "bars": 2, "exact_texels": true})";
    setenv("DISTILE_CACHE", folder.path("cache").c_str(), 1);
    const RecipeLevelSet baked = bakeRecipeLevelSet(recipe, ".", "g.json", 2, 1);
    EXPECT_FALSE(fs::exists(folder.path("cache")));  // level sets are not cached; nor is the tile
    TileCache process;
    const auto tile = bakeRecipeTile(recipe, ".", "g.json", process);
    unsetenv("DISTILE_CACHE");
    EXPECT_TRUE(std::ranges::equal(baked.tile->distancesTexels(), tile->distancesTexels()));
    EXPECT_EQ(baked.levelSet.tileSize(), (Size3{64, 32, 16}));
    const float band = baked.levelSet.halfBandTexels();
    int compared = 0;
    for (int k = 0; k < 16; k += 3)
        for (int j = 0; j < 32; j += 5)
            for (int i = 0; i < 32; i += 7) {
                const float texel = tile->at(i, j, k);
                if (std::abs(texel) >= band) continue;  // outside the band: the background
                ++compared;
                EXPECT_EQ(baked.levelSet.voxelDistanceTexels(i, j, k), texel);
                EXPECT_EQ(baked.levelSet.voxelDistanceTexels(i + 32, j, k), texel);
            }
    EXPECT_GT(compared, 100);
    // Repeats the level set refuses are refused under "repeat", before the bake.
    try {
        bakeRecipeLevelSet(recipe, ".", "g.json", 65, 1);
        ADD_FAILURE() << "65 repeats accepted";
    } catch (const InputError& error) {
        EXPECT_TRUE(std::string(error.what()).starts_with("g.json: repeat: 65x1 is not accepted"))
            << error.what();
    }
}

TEST(BakeCache, AScenesBakesReportTheirProgressAndTilesFromTheCacheNone) {
    // Two objects share one recipe: it is baked once, and reports under the first's field. A
    // second load reads it from the disk cache: no report. Each bake's callback ends with it.
    const TempFolder folder("distile_bake_cache_progress");
    const std::string material = R"({"tile": {"bake": "grating", "size": "32x32x16", "bars": 2}})";
    const std::string scene = R"({"objects": [{"mesh": "plane", "material": )" + material +
                              R"(}, {"mesh": "sphere", "material": )" + material + "}]}";
    setenv("DISTILE_CACHE", folder.path("cache").c_str(), 1);
    std::vector<std::string> bakes;
    std::vector<double> fractions;
    const auto token = std::make_shared<int>(0);
    const BakeProgress bakeProgress = [&](const std::string& what) {
        bakes.push_back(what);
        return ProgressCallback([&, token](double done) { fractions.push_back(done); });
    };
    TileCache first, second;
    loadSceneJson(scene, ".", "s.json", first, {}, bakeProgress);
    EXPECT_EQ(token.use_count(), 1);  // the bake's callback is gone
    loadSceneJson(scene, ".", "s.json", second, {}, bakeProgress);
    unsetenv("DISTILE_CACHE");
    ASSERT_EQ(bakes, std::vector<std::string>{"s.json: objects[0].material.tile"});
    ASSERT_GE(fractions.size(), 2u);
    EXPECT_TRUE(std::ranges::is_sorted(fractions));
    EXPECT_GT(fractions.front(), 0.0);
    EXPECT_LE(fractions.back(), 1.0);
}

TEST(BakeCache, AProceduralTileThatMissesTheCheckWarnsBakedOrCached) {
    // The default chain mail at 64 texels wide has wires 0.53 texel in radius: its bake misses
    // the check's tolerances. Two rings a row, tilted 5 degrees, with wires 2.1 texels thick,
    // pass. The verdict is in the tile, so a load from the disk cache (a new process's tiles)
    // warns as the bake did; a tile already loaded warns no more.
    const TempFolder folder("distile_bake_cache_check");
    const std::string thin = R"({"bake": "chainmail", "size": "64x64x16"})";
    const std::string thick =
        R"({"bake": "chainmail", "size": "64x64x16", "rings_per_row": 2, "rows": 2, "tilt": 5})";
    setenv("DISTILE_CACHE", folder.path("cache").c_str(), 1);
    for (const char* pass : {"baked", "cached"}) {
        SCOPED_TRACE(pass);
        TileCache process;
        std::vector<std::string> warnings;
        const auto warn = [&](const std::string& warning) { warnings.push_back(warning); };
        const auto thinTile = bakeRecipeTile(thin, ".", "thin.json", process, warn);
        bakeRecipeTile(thin, ".", "thin.json", process, warn);
        const auto thickTile = bakeRecipeTile(thick, ".", "thick.json", process, warn);
        EXPECT_TRUE(thinTile->provenance.check.starts_with(TileProvenance::kCheckBeyond));
        EXPECT_TRUE(thickTile->provenance.check.starts_with(TileProvenance::kCheckWithin));
        ASSERT_EQ(warnings.size(), 1u);
        EXPECT_TRUE(
            warnings[0].starts_with("thin.json misses distile check's "
                                    "tolerances: overestimates beyond 0.05 texel in "))
            << warnings[0];
    }
    unsetenv("DISTILE_CACHE");
    EXPECT_EQ(std::distance(fs::directory_iterator(folder.path("cache")), fs::directory_iterator()),
              2);
}

TEST(BakeCache, AFileOfAnotherRecipePutInPlaceOfAnEntryIsBakedAgain) {
    // Each entry was only checked to be a sound tile: a tile of another recipe copied over it
    // (here a grating over a chain mail) was rendered for it, from then on.
    const TempFolder folder("distile_bake_cache_foreign");
    const std::string chainmail =
        R"({"bake": "chainmail", "size": "32x32x8", "rings_per_row": 2, "rows": 2})";
    const std::string grating = R"({"bake": "grating", "size": "32x32x16", "bars": 2})";
    setenv("DISTILE_CACHE", folder.path("cache").c_str(), 1);
    TileCache first;
    const auto fresh = bakeRecipeTile(chainmail, ".", "c", first);
    const fs::path entry = fs::directory_iterator(folder.path("cache"))->path();
    bakeRecipeTile(grating, ".", "g", first);
    for (const auto& file : fs::directory_iterator(folder.path("cache"))) {
        if (file.path() != entry)
            fs::copy_file(file.path(), entry, fs::copy_options::overwrite_existing);
    }
    TileCache second;
    const auto again = bakeRecipeTile(chainmail, ".", "c", second);
    EXPECT_EQ(again->provenance.source, "chainmail");
    EXPECT_TRUE(std::ranges::equal(again->distancesTexels(), fresh->distancesTexels()));
    EXPECT_TRUE(again->provenance.recipeHash.empty());  // the cache's own mark stays there
    // The entry was replaced: a third process reads the chain mail from it.
    EXPECT_EQ(readTileExr(entry).provenance.source, "chainmail");
    unsetenv("DISTILE_CACHE");
}

TEST(BakeCache, ATileBakedFromOtherBytesThanTheRecipeNamesIsNotStored) {
    // A recipe names its input file by the bytes read first; the bake reads the file again. A
    // file replaced in between gave the cache an entry of the old bytes holding the new file's
    // tile, used from then on. The tile's provenance records the bytes it was baked from.
    const TempFolder folder("distile_bake_cache_changed");
    setenv("DISTILE_CACHE", folder.path("cache").c_str(), 1);
    const auto bakeFrom = [](const char* hash) {
        return [hash] {
            Tile tile(Size3{4, 4, 4}, 1.0f);
            tile.provenance.source = "heightmap";
            tile.provenance.sourceHash = hash;
            return tile;
        };
    };
    const auto changed =
        cachedBake("heightmap file A", bakeFrom("bbbbbbbbbbbbbbbb"), "aaaaaaaaaaaaaaaa");
    EXPECT_EQ(changed->provenance.sourceHash, "bbbbbbbbbbbbbbbb");  // this run shows what it read
    EXPECT_FALSE(fs::exists(folder.path("cache")) && !fs::is_empty(folder.path("cache")));
    cachedBake("heightmap file A", bakeFrom("aaaaaaaaaaaaaaaa"), "aaaaaaaaaaaaaaaa");
    EXPECT_EQ(std::distance(fs::directory_iterator(folder.path("cache")), fs::directory_iterator()),
              1);
    unsetenv("DISTILE_CACHE");
}

/// A chain-mail sphere on a bare floor, the camera looking at it from 3 units: everything moved
/// by `shift` world units.
std::string sphereSceneAt(double shift) {
    char text[1024];
    std::snprintf(text, sizeof text, R"({
      "camera": {"eye": [%.17g, %.17g, 1.6], "target": [%.17g, %.17g, 0.55], "fov_deg": 36},
      "lights": [{"direction": [-0.5, 0.4, -1.0], "angle_deg": 3}],
      "objects": [
        {"mesh": "sphere", "transform": {"translate": [%.17g, %.17g, 0.6], "scale": 0.6},
         "material": {"tile": {"bake": "chainmail", "size": "64x64x8"}, "uv_scale": [8, 4],
                      "depth": 0.03}},
        {"mesh": "plane", "transform": {"translate": [%.17g, %.17g, 0], "scale": 4}}]})",
                  shift, shift - 3.0, shift, shift, shift, shift, shift, shift);
    return text;
}

TEST(SceneFile, ASceneFarFromTheOriginRendersAsItDoesNearIt) {
    // Floats at 1e5 resolve 2^-7 world units, about a texel of this chain mail (0.0074 units):
    // placed there in float, the sphere's triangles fold its shell and 14% of its pixels change.
    // The loader moves the origin to the multiple of 1024 nearest the eye, so a shift by such a
    // multiple (98 x 1024) renders the very same image, and another (1e5, 672 units from the new
    // origin, where floats resolve 2^-14) the image up to that rounding.
    TileCache tiles;
    RenderOptions options;
    options.width = 160;
    options.height = 128;
    const auto load = [&](double shift) {
        return loadSceneJson(sphereSceneAt(shift), ".", "sphere.json", tiles);
    };
    const SceneFile near = load(0.0), onGrid = load(98.0 * 1024.0), offGrid = load(1e5);
    EXPECT_EQ(onGrid.scene.camera.eye, near.scene.camera.eye);
    EXPECT_EQ(offGrid.scene.camera.eye,
              glm::vec3(1e5 - 98.0 * 1024.0, 1e5 - 3.0 - 98.0 * 1024.0, 1.6f));
    const RenderResult nearImage = renderScene(near.scene, options);
    const RenderResult onGridImage = renderScene(onGrid.scene, options);
    const RenderResult offGridImage = renderScene(offGrid.scene, options);
    EXPECT_TRUE(onGridImage.warnings.empty());
    EXPECT_TRUE(offGridImage.warnings.empty());
    EXPECT_TRUE(onGridImage.image.rgbLinear == nearImage.image.rgbLinear);
    // Off the grid: most pixels the same; a few along ring edges, where a move of 2^-14 world
    // units (under 0.01 texel) takes a pixel's ray across the edge.
    std::size_t differing = 0;
    for (std::size_t i = 0; i < nearImage.image.rgbLinear.size(); ++i)
        differing +=
            glm::length(offGridImage.image.rgbLinear[i] - nearImage.image.rgbLinear[i]) > 0.02f;
    // Measured: 0.1% of the pixels (14% with the scene placed in float at 1e5).
    EXPECT_LT(differing, nearImage.image.rgbLinear.size() / 100);

    // The origin follows the target, not the eye: a sphere at the world origin seen through a
    // telescope from 1e5 units stays where it is. Moved near the eye, its shell folded in float.
    const SceneFile telescope = loadSceneJson(R"({
      "camera": {"eye": [0, -1e5, 0], "target": [0, 0, 0], "fov_deg": 0.002},
      "objects": [{"mesh": "sphere", "material": {"tile": {"bake": "chainmail", "size": "64x64x8"},
                   "uv_scale": [8, 4], "depth": 0.03}}]})",
                                              ".", "telescope.json", tiles);
    EXPECT_EQ(telescope.scene.camera.target, glm::vec3(0.0f));
    options.width = 64;
    options.height = 48;
    EXPECT_EQ(renderScene(telescope.scene, options).warnings, std::vector<std::string>{});
}
}  // namespace
}  // namespace distile
