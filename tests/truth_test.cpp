// Tests of truth/: CGAL distances against closed-form ones, topology checks, and the acceptance
// figures of baked meshes (level set against the exact mesh distance).
#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

#include "bake/bake.h"
#include "common/error.h"
#include "detail_meshes.h"
#include "truth/mesh_truth.h"
#include "vdb/height_field.h"
#include "vdb/mesh_level_set.h"

namespace distile {
namespace {

using test::makeBoxSoup;
using test::makeTorusSoup;

double boxSignedDistance(const glm::dvec3& p, const glm::dvec3& lo, const glm::dvec3& hi) {
    const glm::dvec3 centre = 0.5 * (lo + hi);
    const glm::dvec3 q = glm::abs(p - centre) - 0.5 * (hi - lo);
    return glm::length(glm::max(q, 0.0)) + std::min(std::max(q.x, std::max(q.y, q.z)), 0.0);
}

double torusSignedDistance(const glm::dvec3& p, const glm::dvec3& centre, double R, double r) {
    const glm::dvec3 q = p - centre;
    return std::hypot(std::hypot(q.x, q.y) - R, q.z) - r;
}

TEST(MeshDistance, UnitCubeMatchesClosedForm) {
    const glm::dvec3 lo(0.0), hi(1.0);
    const MeshDistance cube(makeBoxSoup(lo, hi));
    ASSERT_TRUE(cube.hasSign());
    std::mt19937 random(7);
    std::uniform_real_distribution<double> coordinate(-1.0, 2.0);
    for (int n = 0; n < 2000; ++n) {
        const glm::dvec3 p(coordinate(random), coordinate(random), coordinate(random));
        const double expected = boxSignedDistance(p, lo, hi);
        // Both are exact in double precision: only rounding differs.
        EXPECT_NEAR(cube.signedDistance(p), expected, 1e-12) << p.x << " " << p.y << " " << p.z;
        EXPECT_NEAR(cube.unsignedDistance(p), std::abs(expected), 1e-12);
    }
    double t = 0.0;
    ASSERT_TRUE(cube.rayHit(glm::dvec3(0.5, 0.5, 3.0), glm::dvec3(0.0, 0.0, -2.0), t));
    EXPECT_NEAR(t, 1.0, 1e-12);  // hits z = 1 at origin + 1 * direction
    EXPECT_FALSE(cube.rayHit(glm::dvec3(0.5, 0.5, 3.0), glm::dvec3(0.0, 0.0, 1.0), t));
}

TEST(MeshDistance, TessellatedTorusWithinSagittaOfAnalytic) {
    const glm::dvec3 centre(0.0);
    const double R = 2.0, r = 0.5;
    const int major = 128, minor = 64;
    const MeshDistance torus(makeTorusSoup(centre, R, r, major, minor));
    ASSERT_TRUE(torus.hasSign());
    // The mesh lies within the chord sagitta of the analytic surface (and inside it: the
    // vertices are on it, the chords cut inwards), so distances differ by at most that.
    const double tolerance = test::torusTessellationError(R, r, major, minor) + 1e-9;
    std::mt19937 random(11);
    std::uniform_real_distribution<double> xy(-3.0, 3.0), z(-1.0, 1.0);
    for (int n = 0; n < 2000; ++n) {
        const glm::dvec3 p(xy(random), xy(random), z(random));
        EXPECT_NEAR(torus.signedDistance(p), torusSignedDistance(p, centre, R, r), tolerance);
    }
}

TEST(MeshDistance, PeriodicSeesCopiesAcrossTheWrap) {
    // A box crossing x = W: at x = 0.5 its copy shifted by -W is 0.5 texels away.
    const Size3 tile{32, 32, 8};
    const TriangleSoup box = makeBoxSoup(glm::dvec3(30.0, 10.0, 2.0), glm::dvec3(34.0, 14.0, 6.0));
    const MeshDistance periodic(box, MeshDistance::Periodic{tile});
    const MeshDistance plain(box);
    const glm::dvec3 p(2.5, 12.0, 4.0);
    EXPECT_NEAR(periodic.signedDistance(p), 0.5, 1e-12);
    EXPECT_NEAR(plain.signedDistance(p), 27.5, 1e-12);
    EXPECT_TRUE(periodic.isInside(glm::dvec3(1.0, 12.0, 4.0)));
    EXPECT_FALSE(plain.isInside(glm::dvec3(1.0, 12.0, 4.0)));
}

/// The nearest first hit over the copies (m W, n H, 0), m and n in [-reach, reach], by querying
/// every copy (the brute force that MeshDistance::firstHit avoids).
std::optional<MeshDistance::RayHit> bruteForceFirstHit(const MeshDistance& plain, const Size3& tile,
                                                       int reach, const glm::dvec3& origin,
                                                       const glm::dvec3& direction,
                                                       double maxDistance) {
    std::optional<MeshDistance::RayHit> best;
    for (int m = -reach; m <= reach; ++m) {
        for (int n = -reach; n <= reach; ++n) {
            const glm::dvec3 shift(m * tile.width, n * tile.height, 0.0);
            const auto hit = plain.firstHit(origin - shift, direction, maxDistance);
            if (hit && (!best || hit->distance < best->distance)) best = hit;
        }
    }
    return best;
}

TEST(MeshDistance, PeriodicFirstHitIsTheNearestOverAllCopies) {
    // A torus across the x = 0 and y = 0 borders (R 9, r 3, centre (3, 2, 4) in 32 x 32 x 8).
    // Rays enter at the top z = D and descend at elevations from 60 degrees down to 0.1 degree;
    // each travels to the floor or until its xy path has covered 80 texels, so it stays inside
    // the 7 x 7 block of copies the brute force queries (the block reaches 96 texels from the
    // tile in x and y, minus the torus' 12-texel extent around its centre).
    const Size3 tile{32, 32, 8};
    const TriangleSoup torus = makeTorusSoup(glm::dvec3(3.0, 2.0, 4.0), 9.0, 3.0, 48, 16);
    const MeshDistance periodic(torus, MeshDistance::Periodic{tile});
    const MeshDistance plain(torus);
    std::mt19937 random(5);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const double elevationsDeg[] = {60.0, 30.0, 10.0, 3.0, 1.0, 0.3, 0.1};
    int hits = 0, rays = 0;
    for (const double elevationDeg : elevationsDeg) {
        for (int n = 0; n < 60; ++n) {
            const double azimuth = 2.0 * std::numbers::pi * unit(random);
            const double elevation = elevationDeg * std::numbers::pi / 180.0;
            const glm::dvec3 direction(std::cos(elevation) * std::cos(azimuth),
                                       std::cos(elevation) * std::sin(azimuth),
                                       -std::sin(elevation));
            const glm::dvec3 origin(tile.width * unit(random), tile.height * unit(random),
                                    tile.depth);
            const double maxDistance =
                std::min(origin.z / std::sin(elevation), 80.0 / std::cos(elevation));
            const auto expected =
                bruteForceFirstHit(plain, tile, 3, origin, direction, maxDistance);
            const auto found = periodic.firstHit(origin, direction, maxDistance);
            ++rays;
            ASSERT_EQ(found.has_value(), expected.has_value())
                << "elevation " << elevationDeg << " azimuth " << azimuth;
            if (!found) continue;
            ++hits;
            // The same CGAL queries on the same shifted origins: only the order differs.
            EXPECT_NEAR(found->distance, expected->distance, 1e-9);
            EXPECT_NEAR(glm::dot(found->normal, expected->normal), 1.0, 1e-12);
            EXPECT_LE(glm::dot(found->normal, direction), 0.0);  // faces the ray
        }
    }
    // Enough of the rays meet the torus for the comparison to mean something.
    EXPECT_GT(hits, rays / 3);
    EXPECT_LT(hits, rays);
    // A 0.1-degree ray along y = 2 (through the tori's centres) over its whole path to the floor
    // (4584 texels, 143 tiles): above the tubes (z <= 7) for its first 573 texels, then into one.
    // The brute force queries every copy along the strip it crosses.
    const double elevation = 0.1 * std::numbers::pi / 180.0;
    const glm::dvec3 grazing(std::cos(elevation), 0.0, -std::sin(elevation));
    const glm::dvec3 start(16.0, 2.0, 8.0);
    const double toFloor = 8.0 / std::sin(elevation);
    std::optional<MeshDistance::RayHit> nearest;
    for (int m = -1; m <= 145; ++m) {
        const auto hit =
            plain.firstHit(start - glm::dvec3(m * tile.width, 0.0, 0.0), grazing, toFloor);
        if (hit && (!nearest || hit->distance < nearest->distance)) nearest = hit;
    }
    const auto found = periodic.firstHit(start, grazing, toFloor);
    ASSERT_TRUE(nearest.has_value());
    ASSERT_TRUE(found.has_value());
    EXPECT_GT(found->distance, 1.0 / std::sin(elevation));
    EXPECT_NEAR(found->distance, nearest->distance, 1e-9);
    EXPECT_THROW(periodic.firstHit(glm::dvec3(16.0, 16.0, 8.0), grazing,
                                   std::numeric_limits<double>::infinity()),
                 InputError);
}

TEST(MeshDistance, PeriodicDistanceIsTheNearestOverAllCopies) {
    // Points anywhere in the tile's slab and beyond it, against every copy of a 7 x 7 block (the
    // torus spans 24 texels, so a copy farther than 3 tiles is never the nearest).
    const Size3 tile{32, 32, 8};
    const TriangleSoup torus = makeTorusSoup(glm::dvec3(3.0, 2.0, 4.0), 9.0, 3.0, 48, 16);
    const MeshDistance periodic(torus, MeshDistance::Periodic{tile});
    const MeshDistance plain(torus);
    std::mt19937 random(9);
    std::uniform_real_distribution<double> xy(-40.0, 72.0), z(-20.0, 28.0);
    for (int n = 0; n < 300; ++n) {
        const glm::dvec3 p(xy(random), xy(random), z(random));
        double nearest = HUGE_VAL;
        for (int i = -3; i <= 3; ++i)
            for (int j = -3; j <= 3; ++j)
                nearest = std::min(
                    nearest,
                    plain.unsignedDistance(p - glm::dvec3(i * tile.width, j * tile.height, 0)));
        EXPECT_EQ(periodic.unsignedDistance(p), nearest) << p.x << " " << p.y << " " << p.z;
    }
}

TEST(MeshDistance, PeriodicFirstHitFindsTheCopyAcrossTheBorder) {
    // A box at x in [2, 6]; a ray from x = 30 heading +x meets its copy at x in [34, 38] after 4
    // texels in x, on that copy's -x face. The unshifted box is behind the ray.
    const Size3 tile{32, 32, 8};
    const TriangleSoup box = makeBoxSoup(glm::dvec3(2.0, 14.0, 0.0), glm::dvec3(6.0, 18.0, 4.0));
    const MeshDistance periodic(box, MeshDistance::Periodic{tile});
    const MeshDistance plain(box);
    const glm::dvec3 origin(30.0, 16.0, 3.0);
    const glm::dvec3 direction = glm::normalize(glm::dvec3(1.0, 0.0, -0.01));
    EXPECT_FALSE(plain.firstHit(origin, direction, 100.0).has_value());
    const auto hit = periodic.firstHit(origin, direction, 100.0);
    ASSERT_TRUE(hit.has_value());
    EXPECT_NEAR(hit->distance, 4.0 / direction.x, 1e-12);
    EXPECT_NEAR(glm::distance(hit->normal, glm::dvec3(-1.0, 0.0, 0.0)), 0.0, 1e-12);
    // Beyond the max distance there is nothing.
    EXPECT_FALSE(periodic.firstHit(origin, direction, 3.9).has_value());
}

TEST(MeshDistance, FirstHitNormalIsTheHitFaceNormal) {
    // Rays from outside onto each face of the unit cube at random points: the normal is the
    // face's outward normal, exactly (an axis-aligned triangle's cross product has one non-zero
    // component), whichever way the triangles are wound.
    const TriangleSoup cube = makeBoxSoup(glm::dvec3(0.0), glm::dvec3(1.0));
    TriangleSoup inverted = cube;
    for (glm::uvec3& triangle : inverted.triangles) std::swap(triangle.y, triangle.z);
    std::mt19937 random(3);
    std::uniform_real_distribution<double> inFace(0.05, 0.95), slant(-0.3, 0.3);
    for (const TriangleSoup& soup : {cube, inverted}) {
        const MeshDistance distance(soup);
        for (int axis = 0; axis < 3; ++axis) {
            for (const double side : {-1.0, 1.0}) {
                glm::dvec3 faceNormal(0.0);
                faceNormal[axis] = side;
                for (int n = 0; n < 20; ++n) {
                    glm::dvec3 onFace(inFace(random), inFace(random), inFace(random));
                    onFace[axis] = side > 0.0 ? 1.0 : 0.0;
                    glm::dvec3 direction(slant(random), slant(random), slant(random));
                    direction[axis] = -side;
                    direction = glm::normalize(direction);
                    const glm::dvec3 origin = onFace - 2.0 * direction;
                    const auto hit = distance.firstHit(origin, direction, 10.0);
                    ASSERT_TRUE(hit.has_value());
                    EXPECT_NEAR(hit->distance, 2.0, 1e-12);
                    EXPECT_EQ(hit->normal, faceNormal);
                }
            }
        }
    }
}

TEST(MeshDistance, OpenMeshHasNoSign) {
    TriangleSoup open = makeBoxSoup(glm::dvec3(0.0), glm::dvec3(1.0));
    open.triangles.pop_back();
    const MeshDistance distance(open);
    EXPECT_FALSE(distance.hasSign());
    EXPECT_THROW(distance.signedDistance(glm::dvec3(0.5)), InputError);
    EXPECT_NEAR(distance.unsignedDistance(glm::dvec3(0.5, 0.5, -1.0)), 1.0, 1e-12);
}

TEST(InspectMesh, ClosedOpenNonManifoldDegenerate) {
    const MeshTopology cube = inspectMesh(makeBoxSoup(glm::dvec3(0.0), glm::dvec3(1.0)));
    EXPECT_TRUE(cube.closed);
    EXPECT_TRUE(cube.manifold);
    EXPECT_TRUE(cube.selfIntersectionTested);
    EXPECT_FALSE(cube.selfIntersecting);
    EXPECT_EQ(cube.boundaryEdges, 0u);
    EXPECT_EQ(cube.degenerateFaces, 0u);
    EXPECT_TRUE(cube.isSolid());

    TriangleSoup open = makeBoxSoup(glm::dvec3(0.0), glm::dvec3(1.0));
    open.triangles.pop_back();  // one missing triangle leaves a hole with 3 border edges
    const MeshTopology openTopology = inspectMesh(open);
    EXPECT_FALSE(openTopology.closed);
    EXPECT_EQ(openTopology.boundaryEdges, 3u);
    EXPECT_FALSE(openTopology.isSolid());

    // Two cubes sharing one corner vertex: closed, but that vertex is non-manifold.
    TriangleSoup pinched = makeBoxSoup(glm::dvec3(0.0), glm::dvec3(1.0));
    const TriangleSoup second = makeBoxSoup(glm::dvec3(1.0), glm::dvec3(2.0));
    const unsigned base = unsigned(pinched.positions.size());
    for (const glm::dvec3& p : second.positions) pinched.positions.push_back(p);
    for (glm::uvec3 t : second.triangles) {
        for (int c = 0; c < 3; ++c) t[c] = t[c] == 0 ? 7u : t[c] + base;  // share (1,1,1)
        pinched.triangles.push_back(t);
    }
    const MeshTopology pinchedTopology = inspectMesh(pinched);
    EXPECT_TRUE(pinchedTopology.closed);
    EXPECT_FALSE(pinchedTopology.manifold);
    EXPECT_FALSE(pinchedTopology.isSolid());

    // Two overlapping cubes: closed and manifold, but self-intersecting.
    TriangleSoup overlapping = makeBoxSoup(glm::dvec3(0.0), glm::dvec3(1.0));
    const TriangleSoup shifted = makeBoxSoup(glm::dvec3(0.5), glm::dvec3(1.5));
    for (const glm::dvec3& p : shifted.positions) overlapping.positions.push_back(p);
    for (const glm::uvec3& t : shifted.triangles)
        overlapping.triangles.push_back(t + glm::uvec3(8u));
    const MeshTopology overlappingTopology = inspectMesh(overlapping);
    EXPECT_TRUE(overlappingTopology.manifold);
    EXPECT_TRUE(overlappingTopology.selfIntersecting);

    TriangleSoup degenerate = makeBoxSoup(glm::dvec3(0.0), glm::dvec3(1.0));
    degenerate.triangles.emplace_back(0u, 1u, 1u);
    EXPECT_EQ(inspectMesh(degenerate).degenerateFaces, 1u);

    EXPECT_THROW(inspectMesh(TriangleSoup{}), InputError);
}

TEST(InspectMesh, LargeMeshesTakeTheFastPathOnlyWhenTheyAreOrientedManifolds) {
    // Above kMaxSelfIntersectionFaces a closed, consistently oriented soup whose vertices each
    // have one fan is found manifold without CGAL; a pinched vertex, a flipped face and a hole
    // are still found.
    const TriangleSoup torus = makeTorusSoup(glm::dvec3(0.0), 10.0, 3.0, 400, 260);
    ASSERT_GT(torus.triangles.size(), kMaxSelfIntersectionFaces);
    const MeshTopology whole = inspectMesh(torus);
    EXPECT_TRUE(whole.closed);
    EXPECT_TRUE(whole.manifold);
    EXPECT_FALSE(whole.selfIntersectionTested);
    EXPECT_EQ(whole.degenerateFaces, 0u);

    // A second torus touching the first at one shared vertex.
    TriangleSoup pinched = torus;
    const TriangleSoup second = makeTorusSoup(glm::dvec3(26.0, 0.0, 0.0), 10.0, 3.0, 8, 6);
    const glm::dvec3 touching = torus.positions[0];  // (13, 0, 0): the outer equator
    const unsigned base = unsigned(pinched.positions.size());
    pinched.positions.insert(pinched.positions.end(), second.positions.begin(),
                             second.positions.end());
    unsigned shared = UINT_MAX;
    for (unsigned v = 0; v < second.positions.size(); ++v) {
        if (glm::length(second.positions[v] - touching) < 1e-9) shared = v;
    }
    ASSERT_NE(shared, UINT_MAX);
    for (glm::uvec3 t : second.triangles) {
        for (int c = 0; c < 3; ++c) t[c] = t[c] == shared ? 0u : t[c] + base;
        pinched.triangles.push_back(t);
    }
    const MeshTopology pinchedTopology = inspectMesh(pinched);
    EXPECT_TRUE(pinchedTopology.closed);
    EXPECT_FALSE(pinchedTopology.manifold);

    TriangleSoup flipped = torus;
    std::swap(flipped.triangles[5].y, flipped.triangles[5].z);
    const MeshTopology flippedTopology = inspectMesh(flipped);
    EXPECT_TRUE(flippedTopology.closed);
    EXPECT_TRUE(flippedTopology.manifold);  // orientable: CGAL orients it

    TriangleSoup open = torus;
    open.triangles.pop_back();
    const MeshTopology openTopology = inspectMesh(open);
    EXPECT_FALSE(openTopology.closed);
    EXPECT_EQ(openTopology.boundaryEdges, 3u);
}

/// Acceptance: the baked level set against the exact mesh distance at random voxel centres of
/// the tile. Prints the figures; asserts max error <= 0.5 texel within 2 texels of the surface
/// (the tolerance). OpenVDB's own inside test is approximate in the voxels the triangles
/// cut (a few dozen of 100,000 voxel centres within 0.1 texel of a torus get the wrong sign), so
/// the bake takes the sign of voxels within 1 texel of the surface from the exact CGAL test:
/// with it there must be no sign error at all; without it, none farther than 0.1 texel.
void expectLevelSetMatchesMesh(const char* name, const TriangleSoup& meshTexels, const Size3& tile,
                               int samples = 100000, bool exactSign = true) {
    const MeshDistance truth(meshTexels, MeshDistance::Periodic{tile});
    ASSERT_TRUE(truth.hasSign());
    const InsideTest insideTest = [&truth](const glm::dvec3& p) { return truth.isInside(p); };
    const LevelSet levelSet = levelSetFromMesh(meshTexels, tile, float(tile.depth), name, "{}", {},
                                               exactSign ? insideTest : InsideTest());
    std::mt19937 random(1234);
    std::uniform_int_distribution<int> i(0, tile.width - 1), j(0, tile.height - 1),
        k(0, tile.depth - 1);
    double maxErrorNear = 0.0, sumSquaredNear = 0.0;
    std::size_t near = 0, signErrors = 0, signErrorsFar = 0;
    for (int n = 0; n < samples; ++n) {
        const int x = i(random), y = j(random), z = k(random);
        const double exact = truth.signedDistance(glm::dvec3(x + 0.5, y + 0.5, z + 0.5));
        const double baked = levelSet.voxelDistanceTexels(x, y, z);
        // A point on the surface (|exact| < 1e-6) has no sign to get wrong.
        if (std::abs(exact) > 1e-6 && (exact < 0.0) != (baked < 0.0)) {
            ++signErrors;
            if (std::abs(exact) > 0.1) ++signErrorsFar;
        }
        if (std::abs(exact) <= 2.0) {
            ++near;
            maxErrorNear = std::max(maxErrorNear, std::abs(baked - exact));
            sumSquaredNear += (baked - exact) * (baked - exact);
        }
    }
    std::printf(
        "[ figures  ] %s %s vs mesh (CGAL), %d voxel centres, %s sign: within 2 texels (%zu): "
        "max %.2e RMS %.2e texels; sign errors %zu (%zu farther than 0.1 texel)\n",
        name, toString(tile).c_str(), samples, exactSign ? "exact" : "OpenVDB", near, maxErrorNear,
        near ? std::sqrt(sumSquaredNear / near) : 0.0, signErrors, signErrorsFar);
    ASSERT_GT(near, 1000u);  // the test measures something
    EXPECT_LE(maxErrorNear, 0.5);
    EXPECT_EQ(signErrorsFar, 0u);
    if (exactSign) {
        EXPECT_EQ(signErrors, 0u);
    }
}

TEST(MeshBakeAcceptance, TorusMatchesMeshDistance) {
    const Size3 tile{64, 64, 16};
    ASSERT_NO_FATAL_FAILURE(expectLevelSetMatchesMesh(
        "torus", makeTorusSoup(glm::dvec3(32.3, 31.7, 8.1), 20.0, 5.0, 96, 48), tile));
}

TEST(MeshBakeAcceptance, TorusWithOpenVdbSignHasNoFarSignErrors) {
    const Size3 tile{64, 64, 16};
    ASSERT_NO_FATAL_FAILURE(expectLevelSetMatchesMesh(
        "torus", makeTorusSoup(glm::dvec3(32.3, 31.7, 8.1), 20.0, 5.0, 96, 48), tile, 20000,
        false));
}

TEST(MeshBakeAcceptance, CubeMatchesMeshDistance) {
    const Size3 tile{64, 64, 16};
    ASSERT_NO_FATAL_FAILURE(expectLevelSetMatchesMesh(
        "cube", makeBoxSoup(glm::dvec3(20.2, 18.9, 3.3), glm::dvec3(41.7, 44.1, 12.6)), tile));
}

TEST(MeshBakeAcceptance, TorusAcrossTheTileEdgeMatchesPeriodicMeshDistance) {
    const Size3 tile{64, 64, 16};
    ASSERT_NO_FATAL_FAILURE(expectLevelSetMatchesMesh(
        "torus across x=0,y=0", makeTorusSoup(glm::dvec3(3.3, 60.2, 8.1), 14.0, 5.0, 96, 48), tile,
        20000));
}

TEST(MeshBake, FitPlacementAndSign) {
    // A unit torus (R = 1, r = 0.25: 2.5 x 2.5 x 0.5) fitted to 40x40: scale 16, 8 texels tall.
    const TriangleSoup torus = makeTorusSoup(glm::dvec3(0.0), 1.0, 0.25, 96, 48);
    BakeOptions options;
    options.size = {40, 40, 12};
    const TriangleSoup placed = placeMesh(torus, MeshPlacement{}, options.size);
    const Bounds3 box = boundsOf(placed);
    EXPECT_NEAR(box.min.x, 0.0, 1e-9);
    EXPECT_NEAR(box.max.x, 40.0, 1e-9);
    EXPECT_NEAR(box.min.z, 0.0, 1e-9);
    EXPECT_NEAR(box.max.z, 8.0, 1e-9);
    const BakeResult result = bakeMesh(torus, MeshPlacement{}, options);
    // Tube centre (x = 20 + 16 * 1, y = 20, z = 4) is 4 texels deep.
    EXPECT_NEAR(result.levelSet.voxelDistanceTexels(35, 19, 3), -4.0 + 0.75, 0.1);

    options.size = {40, 40, 6};  // 8 texels tall does not fit 6
    EXPECT_THROW(bakeMesh(torus, MeshPlacement{}, options), InputError);
    EXPECT_THROW(placeMesh(torus, MeshPlacement{false, 0.0, glm::dvec3(0.0)}, options.size),
                 InputError);
    EXPECT_THROW(placeMesh(torus, MeshPlacement{false, 1e30, glm::dvec3(0.0)}, options.size),
                 InputError);
}

TEST(HeightMapBake, MatchesBruteForceDistanceToTheTriangulatedSurface) {
    // A random 16x16 image stretched over a 24x20x10 tile (bilinear, periodic), heights 0..9.
    HeightImage image;
    image.width = image.height = 16;
    std::mt19937 random(77);
    std::uniform_real_distribution<float> value(0.0f, 1.0f);
    for (int n = 0; n < 256; ++n) image.values.push_back(value(random));
    const Size3 tile{24, 20, 10};
    const HeightField field = heightFieldFromImage(image, tile, 9.0);
    const float band = 10.0f;
    const LevelSet levelSet = levelSetFromHeightField(field, tile, band, "heightmap", "{}");
    // Truth: CGAL's exact distance to every triangle of the surface with 12 periodic cells around
    // the footprint (more than the band, so no nearer triangle is left out); sign from z.
    const MeshDistance truth(heightFieldTriangles(field, 12));
    double maxError = 0.0;
    int compared = 0, signErrors = 0;
    for (int k = -3; k < tile.depth + 3; ++k) {
        for (int j = 0; j < tile.height; ++j) {
            for (int i = 0; i < tile.width; ++i) {
                const glm::dvec3 p(i + 0.5, j + 0.5, k + 0.5);
                const double h = heightFieldSurfaceTexels(field, p.x, p.y);
                const double exact = (p.z < h ? -1.0 : 1.0) * truth.unsignedDistance(p);
                if (std::abs(exact) >= band - 0.01) continue;  // clamped to the band
                const double baked = levelSet.voxelDistanceTexels(i, j, k);
                maxError = std::max(maxError, std::abs(baked - exact));
                if (std::abs(exact) > 1e-6 && (baked < 0.0) != (exact < 0.0)) ++signErrors;
                ++compared;
            }
        }
    }
    std::printf(
        "[ figures  ] heightmap 16x16 on %s: %d voxels vs brute force, max error %.2e texels\n",
        toString(tile).c_str(), compared, maxError);
    ASSERT_GT(compared, 3000);
    // Exact up to storing the distance as a float (values up to 10 texels: ulp 1e-6).
    EXPECT_LT(maxError, 1e-4);
    EXPECT_EQ(signErrors, 0);
}

TEST(HeightMapBake, ImageIsSampledPeriodicallyAndBilinearly) {
    HeightImage image;
    image.width = 2;
    image.height = 1;
    image.values = {0.0f, 1.0f};
    // 4 texel columns over 2 pixels: node centres at pixel coordinates -0.25, 0.25, 0.75, 1.25,
    // i.e. wrapped blends of the two pixels.
    const HeightField field = heightFieldFromImage(image, Size3{4, 4, 8}, 8.0);
    EXPECT_NEAR(field.node(0, 0), 8.0 * 0.25, 1e-12);
    EXPECT_NEAR(field.node(1, 0), 8.0 * 0.25, 1e-12);
    EXPECT_NEAR(field.node(2, 0), 8.0 * 0.75, 1e-12);
    EXPECT_NEAR(field.node(3, 0), 8.0 * 0.75, 1e-12);
    EXPECT_THROW(heightFieldFromImage(image, Size3{4, 4, 8}, 9.0), InputError);  // above D
    EXPECT_THROW(heightFieldFromImage(HeightImage{}, Size3{4, 4, 8}, 4.0), InputError);
}

}  // namespace
}  // namespace distile
