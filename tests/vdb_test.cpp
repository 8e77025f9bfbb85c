// Tests of vdb/: the chain-mail distance against closed-form torus geometry, and level sets.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <iterator>
#include <numbers>
#include <random>

#include "common/error.h"
#include "detail_meshes.h"
#include "vdb/chainmail.h"
#include "vdb/grating.h"
#include "vdb/height_field.h"
#include "vdb/level_set.h"
#include "vdb/mesh_level_set.h"
#include "vdb/procedural.h"

namespace distile {
namespace {

constexpr double kPi = 3.14159265358979323846;
const Size3 kDefaultTile{256, 256, 16};

/// Closed-form geometry of ring (column, row) of the default lattice, as chainmail.h documents it.
struct Ring {
    glm::dvec3 centre;
    glm::dvec3 axis;  ///< unit normal of the ring's plane
    glm::dvec3 u, v;  ///< unit vectors spanning the ring's plane
};

Ring ring(const ChainmailOptions& options, const Size3& tile, int column, int row) {
    const double spacing = double(tile.width) / options.ringsPerRow;
    const double rowSpacing = double(tile.height) / options.rowsPerTile;
    const bool odd = (row % 2 + 2) % 2 == 1;
    const double tilt = (odd ? -1.0 : 1.0) * options.tiltDeg * kPi / 180.0;
    Ring result;
    result.centre = {column * spacing + (odd ? 0.5 * spacing : 0.0), row * rowSpacing,
                     0.5 * tile.depth};
    result.axis = {std::sin(tilt), 0.0, std::cos(tilt)};
    result.u = {std::cos(tilt), 0.0, -std::sin(tilt)};
    result.v = {0.0, 1.0, 0.0};
    return result;
}

/// The default tile's distance to the nearest European 4-in-1 ring by trying every ring from 6
/// spacings left of the tile to 6 right, 12 rows below to 12 above: enough for points over the
/// tile up to about 300 texels above or below it.
double europeanDistanceBruteForce(const ChainmailOptions& options, const glm::dvec3& p) {
    const double spacing = double(kDefaultTile.width) / options.ringsPerRow;
    const double ringRadius = options.ringRadiusSpacings * spacing;
    const double wireRadius = options.wireRadiusSpacings * spacing;
    double distance = 1e300;
    for (int row = -12; row < options.rowsPerTile + 12; ++row) {
        for (int column = -6; column < options.ringsPerRow + 6; ++column) {
            const Ring r = ring(options, kDefaultTile, column, row);
            const glm::dvec3 offset = p - r.centre;
            const double inPlane = std::hypot(glm::dot(offset, r.u), glm::dot(offset, r.v));
            distance = std::min(
                distance, std::hypot(inPlane - ringRadius, glm::dot(offset, r.axis)) - wireRadius);
        }
    }
    return distance;
}

TEST(Chainmail, CentrelineIsOneWireRadiusInsideAndTubeSurfaceIsZero) {
    // Exact: on a ring's centreline the nearest surface is its own tube, r away; on the tube's
    // surface the distance is 0 unless another ring intersects this one (it must not).
    const ChainmailOptions options;
    const Chainmail chainmail(options, kDefaultTile);
    const double spacing = 256.0 / options.ringsPerRow;
    const double ringRadius = options.ringRadiusSpacings * spacing;
    const double wireRadius = options.wireRadiusSpacings * spacing;
    for (int row = 0; row < 2; ++row) {
        const Ring r = ring(options, kDefaultTile, 3, row + 4);
        for (int i = 0; i < 360; ++i) {
            const double angle = 2.0 * kPi * i / 360.0;
            const glm::dvec3 radial = std::cos(angle) * r.u + std::sin(angle) * r.v;
            const glm::dvec3 centreline = r.centre + ringRadius * radial;
            EXPECT_NEAR(chainmail.signedDistanceTexels(centreline), -wireRadius, 1e-9);
            for (int j = 0; j < 12; ++j) {
                const double tubeAngle = 2.0 * kPi * j / 12.0;
                const glm::dvec3 surface = centreline + wireRadius * (std::cos(tubeAngle) * radial +
                                                                      std::sin(tubeAngle) * r.axis);
                EXPECT_NEAR(chainmail.signedDistanceTexels(surface), 0.0, 1e-9);
            }
        }
    }
}

TEST(Chainmail, EachRingLinksItsFourDiagonalNeighbours) {
    // The centreline of a linked neighbour crosses this ring's disk an odd number of times; the
    // same-row and two-rows-away neighbours do not pass through it.
    const ChainmailOptions options;
    const double ringRadius = options.ringRadiusSpacings * 256.0 / options.ringsPerRow;
    const Ring centre = ring(options, kDefaultTile, 4, 4);
    auto crossings = [&](int column, int row) {
        const Ring other = ring(options, kDefaultTile, column, row);
        int count = 0;
        constexpr int kSteps = 4000;
        auto point = [&](int step) {
            const double angle = 2.0 * kPi * step / kSteps;
            return other.centre +
                   ringRadius * (std::cos(angle) * other.u + std::sin(angle) * other.v);
        };
        for (int step = 0; step < kSteps; ++step) {
            const glm::dvec3 a = point(step);
            const glm::dvec3 b = point(step + 1);
            const double sa = glm::dot(a - centre.centre, centre.axis);
            const double sb = glm::dot(b - centre.centre, centre.axis);
            if ((sa < 0.0) != (sb < 0.0)) {
                const glm::dvec3 crossing = a + (b - a) * (sa / (sa - sb));
                if (glm::length(crossing - centre.centre) < ringRadius) ++count;
            }
        }
        return count;
    };
    // Row 4 is even; rows 3 and 5 are shifted by half a spacing: diagonal neighbours are columns
    // 3 and 4 of those rows.
    EXPECT_EQ(crossings(3, 3) % 2, 1);
    EXPECT_EQ(crossings(4, 3) % 2, 1);
    EXPECT_EQ(crossings(3, 5) % 2, 1);
    EXPECT_EQ(crossings(4, 5) % 2, 1);
    EXPECT_EQ(crossings(5, 4), 0);
    EXPECT_EQ(crossings(4, 6), 0);
}

TEST(Chainmail, MatchesBruteForceMinimumOverAllRingsAndIsPeriodic) {
    const ChainmailOptions options;
    const Chainmail chainmail(options, kDefaultTile);
    std::mt19937 random(7);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int sample = 0; sample < 300; ++sample) {
        // Includes points far above and below the tile, where many rings are candidates.
        const glm::dvec3 p{unit(random) * 256.0, unit(random) * 256.0, -40.0 + unit(random) * 96.0};
        const double expected = europeanDistanceBruteForce(options, p);
        EXPECT_NEAR(chainmail.signedDistanceTexels(p), expected, 1e-9)
            << "at " << p.x << "," << p.y << "," << p.z;
        // Periodic with the tile: shifting by W or H, or many tiles, changes nothing.
        EXPECT_NEAR(chainmail.signedDistanceTexels(p + glm::dvec3(256.0, 0.0, 0.0)), expected,
                    1e-9);
        EXPECT_NEAR(chainmail.signedDistanceTexels(p + glm::dvec3(0.0, -256.0, 0.0)), expected,
                    1e-9);
        EXPECT_NEAR(chainmail.signedDistanceTexels(p + glm::dvec3(256.0 * 37, 256.0 * 11, 0.0)),
                    expected, 1e-7);
    }
}

TEST(Chainmail, DefaultRingsStayInsideTheTileDepth) {
    const Chainmail chainmail(ChainmailOptions{}, kDefaultTile);
    EXPECT_LE(chainmail.heightTexels(), 16.0 - 1.0);
    // Everywhere on the top and bottom planes the rings are at least half a texel away.
    for (int y = 0; y < 256; ++y) {
        for (int x = 0; x < 256; ++x) {
            EXPECT_GT(chainmail.signedDistanceTexels({x + 0.25, y + 0.75, 0.0}), 0.5);
            EXPECT_GT(chainmail.signedDistanceTexels({x + 0.25, y + 0.75, 16.0}), 0.5);
        }
    }
}

TEST(ChainmailTessellation, VerticesLieOnTheSurfaceAndFacesWithinTheChordBound) {
    // Coarse segments, so the bound is large enough to be tested from both sides:
    // (22.5 + 2.1)(1 - cos(pi/32)) + 2.1 (1 - cos(pi/8)) = 0.118 + 0.160 = 0.278 texel.
    const Chainmail chainmail(ChainmailOptions{}, kDefaultTile);
    const int around = 32, tube = 8;
    const TriangleSoup soup = tessellateChainmail(chainmail, around, tube);
    const double bound = chainmailTessellationErrorTexels(chainmail, around, tube);
    EXPECT_NEAR(bound, 24.6 * (1.0 - std::cos(kPi / around)) + 2.1 * (1.0 - std::cos(kPi / tube)),
                1e-12);
    ASSERT_EQ(soup.positions.size(), std::size_t(8 * 10 * around * tube));
    ASSERT_EQ(soup.triangles.size(), 2 * soup.positions.size());
    ASSERT_NO_THROW(validateTriangleSoup(soup, "tessellated chain mail"));
    // Vertices are points of the analytic tori: zero up to double rounding of ~25-texel values.
    for (const glm::dvec3& position : soup.positions)
        ASSERT_LT(std::abs(chainmail.signedDistanceTexels(position)), 1e-9) << position.x;
    double largestCentroidError = 0.0;
    for (const glm::uvec3& triangle : soup.triangles) {
        const glm::dvec3 a = soup.positions[triangle[0]];
        const glm::dvec3 b = soup.positions[triangle[1]];
        const glm::dvec3 c = soup.positions[triangle[2]];
        const glm::dvec3 centroid = (a + b + c) / 3.0;
        const double distance = chainmail.signedDistanceTexels(centroid);
        largestCentroidError = std::max(largestCentroidError, std::abs(distance));
        ASSERT_LE(std::abs(distance), bound);
        // Counter-clockwise seen from outside: the face normal points up the distance gradient.
        const glm::dvec3 normal = glm::cross(b - a, c - a);
        const double h = 1e-4;
        const glm::dvec3 gradient{
            chainmail.signedDistanceTexels(centroid + glm::dvec3(h, 0, 0)) -
                chainmail.signedDistanceTexels(centroid - glm::dvec3(h, 0, 0)),
            chainmail.signedDistanceTexels(centroid + glm::dvec3(0, h, 0)) -
                chainmail.signedDistanceTexels(centroid - glm::dvec3(0, h, 0)),
            chainmail.signedDistanceTexels(centroid + glm::dvec3(0, 0, h)) -
                chainmail.signedDistanceTexels(centroid - glm::dvec3(0, 0, h))};
        ASSERT_GT(glm::dot(normal, gradient), 0.0);
    }
    // The bound is not vacuous: centroids (not the faces' farthest points) reach over half of it.
    EXPECT_GT(largestCentroidError, 0.5 * bound);
}

TEST(ChainmailTessellation, RejectsTheJapaneseWeaveAndBadSegmentCounts) {
    EXPECT_THROW(tessellateChainmail(Chainmail(japanese4in1Defaults(), kDefaultTile), 64, 16),
                 InputError);
    const Chainmail chainmail(ChainmailOptions{}, kDefaultTile);
    EXPECT_THROW(tessellateChainmail(chainmail, 2, 16), InputError);
    EXPECT_THROW(tessellateChainmail(chainmail, 64, 4097), InputError);
    EXPECT_THROW(chainmailTessellationErrorTexels(chainmail, 64, 0), InputError);
}

TEST(Chainmail, RejectsOptionsThatCannotWork) {
    ChainmailOptions odd;
    odd.rowsPerTile = 9;
    EXPECT_THROW(Chainmail(odd, kDefaultTile), InputError);
    ChainmailOptions tall;
    tall.tiltDeg = 45.0;
    EXPECT_THROW(Chainmail(tall, kDefaultTile), InputError);
    ChainmailOptions thick;
    thick.wireRadiusSpacings = 0.9;
    EXPECT_THROW(Chainmail(thick, kDefaultTile), InputError);
    EXPECT_THROW(Chainmail(ChainmailOptions{}, Size3{256, 256, 8}), InputError);
    EXPECT_THROW(Chainmail(ChainmailOptions{}, Size3{256, 0, 16}), InputError);
}

class LevelSetTest : public ::testing::Test {
  protected:
    void SetUp() override {
        folder_ = std::filesystem::temp_directory_path() /
                  ("distile_vdb_test_" +
                   std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
        std::filesystem::create_directories(folder_);
    }
    void TearDown() override { std::filesystem::remove_all(folder_); }
    std::filesystem::path folder_;
};

TEST_F(LevelSetTest, StoresTheDistanceAtVoxelCentresWithinTheBand) {
    // A plane at z = 5.3: voxel (i, j, k) is centred at z = k + 0.5, so it holds k + 0.5 - 5.3
    // (float of a double), and voxels beyond the band hold +/- the half band.
    const Size3 size{16, 8, 12};
    const float halfBand = 4.0f;
    const LevelSet levelSet = LevelSet::fromDistance([](const glm::dvec3& p) { return p.z - 5.3; },
                                                     size, halfBand, "plane", "{}");
    for (int k = -4; k < 16; ++k) {
        const double expected = std::clamp(k + 0.5 - 5.3, -double(halfBand), double(halfBand));
        EXPECT_FLOAT_EQ(levelSet.voxelDistanceTexels(3, 5, k), float(expected)) << "k=" << k;
    }
    // Active: the voxels of the footprint with |d| < 4: k + 0.5 in (1.3, 9.3) -> k = 1..8.
    EXPECT_EQ(levelSet.activeVoxelCount(), std::size_t(16 * 8 * 8));
    EXPECT_EQ(levelSet.tileSize(), size);
    EXPECT_FLOAT_EQ(levelSet.halfBandTexels(), halfBand);
}

TEST_F(LevelSetTest, SavesAndLoadsAndCopiesTheTileVoxels) {
    const Size3 size{8, 8, 6};
    const LevelSet levelSet = LevelSet::fromDistance(
        [](const glm::dvec3& p) { return glm::length(p - glm::dvec3(4, 4, 3)) - 2.0; }, size, 6.0f,
        "sphere", "{\"r\":2}");
    const auto file = folder_ / "sphere.vdb";
    levelSet.save(file);
    const LevelSet loaded = LevelSet::load(file);
    EXPECT_EQ(loaded.tileSize(), size);
    EXPECT_EQ(loaded.source(), "sphere");
    EXPECT_EQ(loaded.params(), "{\"r\":2}");
    std::vector<float> texels(size.texelCount());
    loaded.copyTileVoxels(texels);
    for (int k = 0; k < size.depth; ++k) {
        for (int j = 0; j < size.height; ++j) {
            for (int i = 0; i < size.width; ++i) {
                const double expected =
                    glm::length(glm::dvec3(i + 0.5, j + 0.5, k + 0.5) - glm::dvec3(4, 4, 3)) - 2.0;
                EXPECT_FLOAT_EQ(texels[i + size.width * (j + size.height * k)], float(expected));
            }
        }
    }
}

TEST_F(LevelSetTest, SavesTheSameBytesOnAnyThreadCountAndEveryTime) {
    // OpenVDB stamps each file with a random UUID; save() makes it a hash of the content instead.
    const auto bytesOf = [](const std::filesystem::path& file) {
        std::ifstream in(file, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    const auto saved = [&](int threads, const std::string& name) {
        const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        const LevelSet levelSet = LevelSet::fromDistance(
            [](const glm::dvec3& p) { return glm::length(p - glm::dvec3(8, 8, 4)) - 3.0; },
            Size3{16, 16, 8}, 4.0f, "sphere", "{\"r\":3}");
        levelSet.save(folder_ / name);
        return bytesOf(folder_ / name);
    };
    const std::string first = saved(1, "one.vdb");
    ASSERT_GT(first.size(), 57u);
    // Compared as a whole (a mismatch shows the UUIDs, not the binary file).
    const std::string two = saved(2, "two.vdb");
    EXPECT_TRUE(two == first) << two.substr(21, 36) << " vs " << first.substr(21, 36);
    const std::string again = saved(2, "again.vdb");
    EXPECT_TRUE(again == first) << again.substr(21, 36) << " vs " << first.substr(21, 36);
    EXPECT_NO_THROW(LevelSet::load(folder_ / "again.vdb"));
    const LevelSet other = LevelSet::fromDistance(
        [](const glm::dvec3& p) { return glm::length(p - glm::dvec3(8, 8, 4)) - 2.0; },
        Size3{16, 16, 8}, 4.0f, "sphere", "{\"r\":2}");
    other.save(folder_ / "other.vdb");
    EXPECT_NE(bytesOf(folder_ / "other.vdb").substr(21, 36), first.substr(21, 36));
}

TEST_F(LevelSetTest, RejectsMissingAndCorruptedFiles) {
    EXPECT_THROW(LevelSet::load(folder_ / "missing.vdb"), InputError);
    const LevelSet levelSet = LevelSet::fromDistance([](const glm::dvec3& p) { return p.z - 2.0; },
                                                     Size3{8, 8, 4}, 2.0f, "plane", "{}");
    const auto file = folder_ / "plane.vdb";
    levelSet.save(file);
    const auto bytes = std::filesystem::file_size(file);
    std::filesystem::resize_file(file, bytes / 2);
    EXPECT_THROW(LevelSet::load(file), FormatError);
    std::ofstream(folder_ / "text.vdb") << "not a vdb file at all";
    EXPECT_THROW(LevelSet::load(folder_ / "text.vdb"), FormatError);
}

TEST(LevelSet, RejectsBadBands) {
    auto plane = [](const glm::dvec3& p) { return p.z; };
    EXPECT_THROW(LevelSet::fromDistance(plane, Size3{8, 8, 4}, 0.5f, "", ""), InputError);
    EXPECT_THROW(LevelSet::fromDistance(plane, Size3{8, 8, 4}, std::nanf(""), "", ""), InputError);
}

// ---- mesh level sets ---------------------------------------------------------------------------

TEST(MeshLevelSet, BoxDistancesAreExact) {
    // Axis-aligned box, corners off the voxel grid: outside the faces the distance is exact.
    const Size3 tile{32, 32, 16};
    const TriangleSoup box =
        test::makeBoxSoup(glm::dvec3(10.25, 9.75, 4.5), glm::dvec3(20.5, 22.25, 11.5));
    const LevelSet levelSet = levelSetFromMesh(box, tile, 4.0f, "box", "{}");
    EXPECT_EQ(levelSet.tileSize(), tile);
    EXPECT_EQ(levelSet.source(), "box");
    // Voxel (15, 15, k) has centre z = k + 0.5: above the top face z = 11.5 by k - 11.
    // OpenVDB computes point-triangle distances in float: 1e-4 texel covers the rounding.
    EXPECT_NEAR(levelSet.voxelDistanceTexels(15, 15, 13), 2.0, 1e-4);
    EXPECT_NEAR(levelSet.voxelDistanceTexels(15, 15, 9), -2.0, 1e-4);
    EXPECT_NEAR(levelSet.voxelDistanceTexels(15, 15, 14), 3.0, 1e-4);
    EXPECT_FLOAT_EQ(levelSet.voxelDistanceTexels(2, 2, 8), 4.0f);  // outside the band
}

/// Baking a mesh shifted by whole texels in x and y gives the same tile, cyclically shifted:
/// so the tile's values across x = 0/W and y = 0/H continue as they do inside (no seam).
void expectShiftInvariant(const TriangleSoup& mesh, const Size3& tile, int shiftX, int shiftY) {
    TriangleSoup shifted = mesh;
    for (glm::dvec3& p : shifted.positions) p += glm::dvec3(shiftX, shiftY, 0.0);
    const LevelSet a = levelSetFromMesh(mesh, tile, float(tile.depth), "mesh", "{}");
    const LevelSet b = levelSetFromMesh(shifted, tile, float(tile.depth), "mesh", "{}");
    double worst = 0.0;
    glm::ivec3 worstAt(0);
    double worstNear = 0.0;
    for (int k = 0; k < tile.depth; ++k) {
        for (int j = 0; j < tile.height; ++j) {
            for (int i = 0; i < tile.width; ++i) {
                const int si = (i + shiftX) % tile.width, sj = (j + shiftY) % tile.height;
                const double difference =
                    std::abs(a.voxelDistanceTexels(i, j, k) - b.voxelDistanceTexels(si, sj, k));
                if (std::abs(a.voxelDistanceTexels(i, j, k)) <= 2.0f) {
                    worstNear = std::max(worstNear, difference);
                }
                if (difference > worst) {
                    worst = difference;
                    worstAt = glm::ivec3(i, j, k);
                }
            }
        }
    }
    std::printf(
        "[ figures  ] mesh level set shifted by (%d, %d) texels: max change %.3g texels "
        "within 2 texels of the surface, %.3g anywhere\n",
        shiftX, shiftY, worstNear, worst);
    // OpenVDB's mesh-to-volume is exact near the triangles but propagates nearest triangles
    // approximately farther out (measured: up to ~0.25 texel at 4 texels), and the float
    // rounding of shifted positions changes which voxels it gets slightly wrong. Near the
    // surface (measured 2e-6) the 0.01 seam tolerance holds; farther out OpenVDB's own
    // approximation (< 0.5 texel) is the bound.
    EXPECT_LE(worstNear, 0.01);
    EXPECT_LE(worst, 0.5) << "at voxel " << worstAt.x << " " << worstAt.y << " " << worstAt.z
                          << ": " << a.voxelDistanceTexels(worstAt.x, worstAt.y, worstAt.z);
}

TEST(MeshLevelSet, MeshAcrossTheTileEdgeIsSeamless) {
    const Size3 tile{48, 40, 12};
    // Torus centred near the corner: it crosses x = 0 and y = 0 and continues across the wrap.
    const TriangleSoup torus = test::makeTorusSoup(glm::dvec3(3.3, 2.6, 6.1), 10.0, 3.5, 64, 32);
    expectShiftInvariant(torus, tile, 17, 23);
    // The wrapped part is really there: x = W - 0.5 is as close to the tube as x = -0.5 would be.
    const LevelSet levelSet = levelSetFromMesh(torus, tile, 12.0f, "torus", "{}");
    // Voxel (47, 2, 6) centre (47.5, 2.5, 6.5) is the point (-0.5, 2.5, 6.5) of the unwrapped
    // torus: 3.8 from its axis, 6.2 texels from the tube's centre line, 2.7 outside; tessellation
    // (64 x 32) moves the surface by < 0.06 texel.
    const double expected = std::hypot(10.0 - std::hypot(-0.5 - 3.3, 2.5 - 2.6), 0.4) - 3.5;
    EXPECT_NEAR(levelSet.voxelDistanceTexels(47, 2, 6), expected, 0.06);
}

TEST(MeshLevelSet, RejectsBadInput) {
    const Size3 tile{16, 16, 8};
    const TriangleSoup box = test::makeBoxSoup(glm::dvec3(4.0), glm::dvec3(6.0));
    EXPECT_THROW(levelSetFromMesh(TriangleSoup{}, tile, 4.0f, "", ""), InputError);
    TriangleSoup nan = box;
    nan.positions[3].y = std::nan("");
    EXPECT_THROW(levelSetFromMesh(nan, tile, 4.0f, "", ""), InputError);
    TriangleSoup outOfRange = box;
    outOfRange.triangles[5].z = 99;
    EXPECT_THROW(levelSetFromMesh(outOfRange, tile, 4.0f, "", ""), InputError);
    EXPECT_THROW(levelSetFromMesh(box, tile, 0.5f, "", ""), InputError);
    EXPECT_THROW(levelSetFromMesh(box, Size3{1, 16, 8}, 4.0f, "", ""), InputError);
}

}  // namespace
}  // namespace distile

// ---- Japanese 4-in-1 chain mail, grating, procedural access, repeated level sets -------------

namespace distile {
namespace {

/// Closed-form Japanese 4-in-1 geometry as chainmail.h documents it: a torus by centre, unit axis,
/// centreline radius and wire radius.
struct Torus {
    glm::dvec3 centre;
    glm::dvec3 axis;
    double ringRadius;
    double wireRadius;
};

double torusDistanceBruteForce(const Torus& torus, const glm::dvec3& p) {
    const glm::dvec3 offset = p - torus.centre;
    const double along = glm::dot(offset, torus.axis);
    const double inPlane = glm::length(offset - along * torus.axis);
    return std::hypot(inPlane - torus.ringRadius, along) - torus.wireRadius;
}

std::vector<Torus> japaneseRings(const ChainmailOptions& options, const Size3& tile,
                                 int reachCells) {
    const double s = double(tile.width) / options.ringsPerRow;
    const double t = double(tile.height) / options.rowsPerTile;
    const double z = 0.5 * tile.depth;
    std::vector<Torus> rings;
    for (int j = -reachCells; j < options.rowsPerTile + reachCells; ++j) {
        for (int i = -reachCells; i < options.ringsPerRow + reachCells; ++i) {
            rings.push_back({{i * s, j * t, z},
                             {0, 0, 1},
                             options.ringRadiusSpacings * s,
                             options.wireRadiusSpacings * s});
            rings.push_back({{(i + 0.5) * s, j * t, z},
                             {0, 1, 0},
                             options.smallRingRadiusSpacings * s,
                             options.smallWireRadiusSpacings * s});
            rings.push_back({{i * s, (j + 0.5) * t, z},
                             {1, 0, 0},
                             options.smallRingRadiusSpacings * s,
                             options.smallWireRadiusSpacings * s});
        }
    }
    return rings;
}

TEST(JapaneseChainmail, MatchesBruteForceMinimumOverAllRingsAndIsPeriodic) {
    const ChainmailOptions options = japanese4in1Defaults();
    const Chainmail chainmail(options, kDefaultTile);
    const std::vector<Torus> rings = japaneseRings(options, kDefaultTile, 3);
    std::mt19937 random(17);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int sample = 0; sample < 300; ++sample) {
        // Includes points far above and below, where many rings are candidates.
        const glm::dvec3 p{unit(random) * 256.0, unit(random) * 256.0, -40.0 + unit(random) * 96.0};
        double expected = 1e300;
        for (const Torus& ring : rings)
            expected = std::min(expected, torusDistanceBruteForce(ring, p));
        // Both are sums of a few double operations on values below 300: 1e-9 is ~1e5 ulps of slack.
        EXPECT_NEAR(chainmail.signedDistanceTexels(p), expected, 1e-9)
            << p.x << "," << p.y << "," << p.z;
        EXPECT_NEAR(chainmail.signedDistanceTexels(p + glm::dvec3(256.0, 0.0, 0.0)), expected,
                    1e-9);
        EXPECT_NEAR(chainmail.signedDistanceTexels(p + glm::dvec3(-256.0 * 5, 256.0 * 9, 0.0)),
                    expected, 1e-8);
    }
}

// Far above or below the rings the distance is the slab's: a lower bound of the exact distance
// (sphere tracing's steps stay safe) and within the slab's thickness plus a spacing of it. Before,
// the lattice search visited every ring within the point's distance: a point 1e13 texels away (a
// reference render's ray through a shell 3e-14 units deep) did not return in 5 minutes.
TEST(Chainmail, FarFromItsRingsTheDistanceIsTheSlabsAndNeverAboveTheExactOne) {
    const ChainmailOptions european;
    const ChainmailOptions japanese = japanese4in1Defaults();
    const std::vector<Torus> japaneseTori = japaneseRings(japanese, kDefaultTile, 6);
    std::mt19937 random(23);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (const ChainmailOptions* options : {&european, &japanese}) {
        const Chainmail chainmail(*options, kDefaultTile);
        const double halfHeight = 0.5 * chainmail.heightTexels();
        const double spacing = double(kDefaultTile.width) / options->ringsPerRow;
        // Every point of the tile is within the exact range.
        EXPECT_GE(chainmail.farSlabTexels(), double(kDefaultTile.depth));
        for (int sample = 0; sample < 200; ++sample) {
            const double aboveSlab = chainmail.farSlabTexels() + 1.0 + 20.0 * unit(random);
            const double side = sample % 2 == 0 ? 1.0 : -1.0;
            const glm::dvec3 p{unit(random) * 256.0, unit(random) * 256.0,
                               0.5 * kDefaultTile.depth + side * (halfHeight + aboveSlab)};
            double exact = 1e300;
            if (options == &european) {
                exact = europeanDistanceBruteForce(european, p);
            } else {
                for (const Torus& ring : japaneseTori)
                    exact = std::min(exact, torusDistanceBruteForce(ring, p));
            }
            const double distance = chainmail.signedDistanceTexels(p);
            EXPECT_NEAR(distance, aboveSlab, 1e-9) << p.x << "," << p.y << "," << p.z;
            EXPECT_LE(distance, exact + 1e-9) << p.x << "," << p.y << "," << p.z;
            EXPECT_GE(distance, exact - (2.0 * halfHeight + spacing))
                << p.x << "," << p.y << "," << p.z;
        }
        const glm::dvec3 far{10.0, 20.0, 0.5 * kDefaultTile.depth + 1e13};
        EXPECT_DOUBLE_EQ(chainmail.signedDistanceTexels(far), 1e13 - halfHeight);
    }
}

TEST(JapaneseChainmail, CentrelinesAreOneWireInsideRingsDoNotTouchAndFitTheDepth) {
    const ChainmailOptions options = japanese4in1Defaults();
    const Chainmail chainmail(options, kDefaultTile);
    const double s = 32.0;
    for (int i = 0; i < 360; ++i) {
        const double angle = 2.0 * kPi * i / 360.0;
        // Large ring (2, 3): centreline in the plane z = 8.
        const glm::dvec3 large{2 * s + 13.75 * std::cos(angle), 3 * s + 13.75 * std::sin(angle),
                               8.0};
        EXPECT_NEAR(chainmail.signedDistanceTexels(large), -1.5, 1e-9);
        // Small ring between (2, 3) and (3, 3): centreline in the x-z plane.
        const glm::dvec3 small{2.5 * s + 6.0 * std::cos(angle), 3 * s, 8.0 + 6.0 * std::sin(angle)};
        EXPECT_NEAR(chainmail.signedDistanceTexels(small), -1.25, 1e-9);
    }
    // Linked wires keep 1 texel of clearance (file note): the distance from one ring's surface to
    // any other ring is >= 1, so nowhere is a point inside two rings; sample on each wire's
    // surface and check the distance to the union there is exactly 0 (no other ring intersects).
    for (int i = 0; i < 720; ++i) {
        const double angle = 2.0 * kPi * i / 720.0;
        for (int j = 0; j < 8; ++j) {
            const double tube = 2.0 * kPi * j / 8.0;
            const glm::dvec3 radial{std::cos(angle), 0.0, std::sin(angle)};
            const glm::dvec3 onSmall = glm::dvec3(2.5 * s, 3 * s, 8.0) +
                                       (6.0 + 1.25 * std::cos(tube)) * radial +
                                       glm::dvec3(0.0, 1.25 * std::sin(tube), 0.0);
            EXPECT_NEAR(chainmail.signedDistanceTexels(onSmall), 0.0, 1e-9);
        }
    }
    EXPECT_LE(chainmail.heightTexels(), 15.0);
    for (int y = 0; y < 256; ++y) {
        for (int x = 0; x < 256; ++x) {
            EXPECT_GT(chainmail.signedDistanceTexels({x + 0.25, y + 0.75, 0.0}), 0.5);
            EXPECT_GT(chainmail.signedDistanceTexels({x + 0.25, y + 0.75, 16.0}), 0.5);
        }
    }
}

TEST(JapaneseChainmail, SmallRingsThreadBothLargeRings) {
    // The small ring's centreline crosses each joined large ring's disk once inside the disk
    // (at x = 2.5 s - 6 = 74, inside ring 2 whose centreline radius reaches 64 + 13.75) and once
    // outside it, so it is linked with both; the large rings' planes are z = 8.
    const double s = 32.0;
    auto insideLargeDisk = [&](double x, int column) { return std::abs(x - column * s) < 13.75; };
    EXPECT_TRUE(insideLargeDisk(2.5 * s - 6.0, 2));
    EXPECT_FALSE(insideLargeDisk(2.5 * s + 6.0, 2));
    EXPECT_TRUE(insideLargeDisk(2.5 * s + 6.0, 3));
    EXPECT_FALSE(insideLargeDisk(2.5 * s - 6.0, 3));
    // Parameters that would make neighbouring large rings touch are refused.
    ChainmailOptions touching = japanese4in1Defaults();
    touching.ringRadiusSpacings = 0.48;
    EXPECT_THROW(Chainmail(touching, kDefaultTile), InputError);
    ChainmailOptions tall = japanese4in1Defaults();
    tall.smallRingRadiusSpacings = 0.3;
    EXPECT_THROW(Chainmail(tall, kDefaultTile), InputError);
}

/// Exact distance to a rounded rectangle, written differently from grating.cpp: outside the inner
/// rectangle (the rectangle shrunk by the radius) it is the distance to that rectangle minus the
/// radius (the nearest boundary point lies on the ray from the nearest inner point); inside it,
/// the nearest boundary point is on the nearest straight side.
double roundedRectangleBruteForce(double u, double v, double halfU, double halfV, double radius) {
    const double innerU = halfU - radius;
    const double innerV = halfV - radius;
    const double toInner =
        std::hypot(u - std::clamp(u, -innerU, innerU), v - std::clamp(v, -innerV, innerV));
    if (toInner > 0.0) return toInner - radius;
    return -std::min(halfU - std::abs(u), halfV - std::abs(v));
}

TEST(Grating, MatchesBruteForceOverAllBarsClosedFormPointsAndIsPeriodic) {
    const GratingOptions options;
    const Grating grating(options, kDefaultTile);
    const double spacing = 256.0 / options.barsPerTile;
    const double offset = 0.5 * (options.barHeightTexels + options.layerGapTexels);
    std::mt19937 random(19);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int sample = 0; sample < 2000; ++sample) {
        const glm::dvec3 p{unit(random) * 256.0, unit(random) * 256.0, -10.0 + unit(random) * 36.0};
        double expected = 1e300;
        for (int k = -2; k < options.barsPerTile + 2; ++k) {
            const double centre = (k + 0.5) * spacing;
            expected = std::min(expected, roundedRectangleBruteForce(
                                              p.y - centre, p.z - 8.0 - offset, 4.0, 3.0, 3.0));
            expected = std::min(expected, roundedRectangleBruteForce(
                                              p.x - centre, p.z - 8.0 + offset, 4.0, 3.0, 3.0));
        }
        EXPECT_NEAR(grating.signedDistanceTexels(p), expected, 1e-9)
            << p.x << "," << p.y << "," << p.z;
        EXPECT_NEAR(grating.signedDistanceTexels(p + glm::dvec3(256.0 * 3, -256.0, 0.0)), expected,
                    1e-9);
    }
    // Closed form: the top face of an upper bar is at z = 8 + 0.5 + 6 = 14.5, its centre line at
    // y = 16; the bar's core is 3 texels (half the height) inside; the gap's middle is 0.5 away.
    EXPECT_NEAR(grating.signedDistanceTexels({100.0, 16.0, 14.5}), 0.0, 1e-12);
    EXPECT_NEAR(grating.signedDistanceTexels({100.0, 16.0, 11.5}), -3.0, 1e-12);
    EXPECT_NEAR(grating.signedDistanceTexels({16.0, 16.0, 8.0}), 0.5, 1e-12);
    // Beside a rounded edge: the edge circle's centre is at (y, z) = (16 + 1, 11.5), radius 3.
    EXPECT_NEAR(grating.signedDistanceTexels({100.0, 17.0 + 3.0, 11.5 + 4.0}), 5.0 - 3.0, 1e-12);
    EXPECT_EQ(grating.heightTexels(), 13.0);
    for (int y = 0; y < 256; ++y) {
        for (int x = 0; x < 256; ++x) {
            EXPECT_GT(grating.signedDistanceTexels({x + 0.5, y + 0.5, 0.0}), 0.5);
            EXPECT_GT(grating.signedDistanceTexels({x + 0.5, y + 0.5, 16.0}), 0.5);
        }
    }
}

TEST(Grating, RejectsOptionsThatCannotWork) {
    GratingOptions wide;
    wide.barWidthTexels = 40.0;
    EXPECT_THROW(Grating(wide, kDefaultTile), InputError);
    GratingOptions touching;
    touching.layerGapTexels = 0.0;
    EXPECT_THROW(Grating(touching, kDefaultTile), InputError);
    GratingOptions tall;
    tall.barHeightTexels = 8.0;
    EXPECT_THROW(Grating(tall, kDefaultTile), InputError);
    GratingOptions round;
    round.edgeRadiusTexels = 3.5;
    EXPECT_THROW(Grating(round, kDefaultTile), InputError);
}

TEST(Procedural, GivesEachPatternsDistanceSourceAndParams) {
    ProceduralOptions options;
    options.kind = ProceduralKind::Grating;
    const ProceduralDistance grating = proceduralDistance(options, kDefaultTile);
    EXPECT_EQ(grating.source, "grating");
    EXPECT_EQ(grating.paramsJson, Grating(GratingOptions{}, kDefaultTile).paramsJson());
    const glm::dvec3 p{12.3, 45.6, 7.8};
    EXPECT_EQ(grating.signedDistanceTexels(p),
              Grating(GratingOptions{}, kDefaultTile).signedDistanceTexels(p));
    options.kind = ProceduralKind::Chainmail;
    options.chainmail = japanese4in1Defaults();
    const ProceduralDistance japanese = proceduralDistance(options, kDefaultTile);
    EXPECT_EQ(japanese.source, "chainmail");
    EXPECT_NE(japanese.paramsJson.find("\"weave\":\"japanese4in1\""), std::string::npos);
    EXPECT_NE(japanese.paramsJson.find("\"ring_radius_spacings\":0.4296875"), std::string::npos);
    EXPECT_EQ(japanese.signedDistanceTexels(p),
              Chainmail(japanese4in1Defaults(), kDefaultTile).signedDistanceTexels(p));
    // The default European weave keeps its provenance text.
    EXPECT_EQ(Chainmail(ChainmailOptions{}, kDefaultTile).paramsJson(),
              "{\"weave\":\"european4in1\",\"rings_per_row\":8,\"rows_per_tile\":10,\"ring_radius_"
              "spacings\":0.703125,"
              "\"wire_radius_spacings\":0.065625,\"tilt_deg\":12}");
}

TEST(LevelSetRepeat, CopiesTheTileWithOffsetsAndChecksTheCounts) {
    const Size3 size{8, 6, 4};
    const LevelSet levelSet = LevelSet::fromDistance(
        [](const glm::dvec3& p) {
            return std::sin(0.7 * p.x) + std::cos(1.1 * p.y) + 0.3 * p.z - 1.0;
        },
        size, 3.0f, "wave", "{}");
    const LevelSet repeated = levelSet.repeated(3, 2);
    EXPECT_EQ(repeated.tileSize(), (Size3{24, 12, 4}));
    EXPECT_EQ(repeated.source(), "wave");
    EXPECT_FLOAT_EQ(repeated.halfBandTexels(), 3.0f);
    for (int k = -3; k < 7; ++k)
        for (int j = 0; j < 12; ++j)
            for (int i = 0; i < 24; ++i)
                ASSERT_EQ(repeated.voxelDistanceTexels(i, j, k),
                          levelSet.voxelDistanceTexels(i % 8, j % 6, k))
                    << i << "," << j << "," << k;
    EXPECT_THROW(levelSet.repeated(0, 2), InputError);
    EXPECT_THROW(levelSet.repeated(2, 65), InputError);
}

/// A smooth periodic height field on a W x H tile, heights in [1, 13] texels.
HeightField wavyHeightField(const Size3& tile) {
    HeightField field;
    field.width = tile.width;
    field.height = tile.height;
    const double tau = 2.0 * std::numbers::pi;
    for (int j = 0; j < tile.height; ++j) {
        for (int i = 0; i < tile.width; ++i) {
            const double u = (i + 0.5) / tile.width, v = (j + 0.5) / tile.height;
            field.heightsTexels.push_back(7.0 + 4.0 * std::sin(tau * u) * std::cos(2.0 * tau * v) +
                                          2.0 * std::cos(tau * (u + v)));
        }
    }
    return field;
}

TEST(HeightFieldLevelSet, FlatFieldIsExactlyZMinusHeight) {
    const Size3 tile{24, 20, 16};
    HeightField field;
    field.width = tile.width;
    field.height = tile.height;
    field.heightsTexels.assign(std::size_t(tile.width) * tile.height, 5.25);
    const float band = 6.0f;
    const LevelSet levelSet = levelSetFromHeightField(field, tile, band, "heightmap", "{}");
    double maxError = 0.0;
    for (int k = -6; k < tile.depth + 6; ++k) {
        for (int j = 0; j < tile.height; ++j) {
            for (int i = 0; i < tile.width; ++i) {
                const double expected = std::clamp(k + 0.5 - 5.25, -double(band), double(band));
                maxError =
                    std::max(maxError, std::abs(levelSet.voxelDistanceTexels(i, j, k) - expected));
            }
        }
    }
    // Float storage of values up to 16 texels: a few ulp (1e-6 each) at most.
    EXPECT_LT(maxError, 1e-5);
    EXPECT_DOUBLE_EQ(heightFieldSurfaceTexels(field, -3.7, 41.2), 5.25);
}

TEST(HeightFieldLevelSet, SurfaceInterpolatesTheNodesPeriodically) {
    const Size3 tile{8, 8, 16};
    HeightField field = wavyHeightField(tile);
    // At a node: the node; halfway along the diagonal of a cell: the mean of its two ends; one
    // period away: the same.
    EXPECT_DOUBLE_EQ(heightFieldSurfaceTexels(field, 3.5, 4.5), field.node(3, 4));
    EXPECT_NEAR(heightFieldSurfaceTexels(field, 4.0, 5.0),
                0.5 * (field.node(3, 4) + field.node(4, 5)), 1e-12);
    EXPECT_NEAR(heightFieldSurfaceTexels(field, 4.0 + 8.0, 5.0 - 16.0),
                heightFieldSurfaceTexels(field, 4.0, 5.0), 1e-12);
    // Across the wrap: between node 7 and node 8 = node 0.
    EXPECT_NEAR(heightFieldSurfaceTexels(field, 8.0, 0.5),
                0.5 * (field.node(7, 0) + field.node(0, 0)), 1e-12);
}

TEST(HeightFieldLevelSet, ShiftedFieldGivesTheShiftedLevelSetAcrossTheWrap) {
    // Seams: the level set of the field shifted by (s, t) nodes is the level set shifted by
    // (s, t) voxels, so values next to x = 0/W and y = 0/H equal interior ones. Both are exact
    // distances up to float rounding; 0.01 texel is the seam tolerance.
    const Size3 tile{32, 24, 16};
    const HeightField field = wavyHeightField(tile);
    HeightField shifted = field;
    const int s = 13, t = 7;
    for (int j = 0; j < tile.height; ++j) {
        for (int i = 0; i < tile.width; ++i) {
            shifted.heightsTexels[std::size_t(i) + std::size_t(j) * tile.width] =
                field.node(i + s, j + t);
        }
    }
    const LevelSet a = levelSetFromHeightField(field, tile, 16.0f, "heightmap", "{}");
    const LevelSet b = levelSetFromHeightField(shifted, tile, 16.0f, "heightmap", "{}");
    double maxDifference = 0.0;
    for (int k = 0; k < tile.depth; ++k) {
        for (int j = 0; j < tile.height; ++j) {
            for (int i = 0; i < tile.width; ++i) {
                const float wrapped =
                    a.voxelDistanceTexels((i + s) % tile.width, (j + t) % tile.height, k);
                maxDifference = std::max(
                    maxDifference, double(std::abs(b.voxelDistanceTexels(i, j, k) - wrapped)));
            }
        }
    }
    EXPECT_LE(maxDifference, 0.01);
    // The values on both sides of x = 0 (and y = 0) differ by at most the surface's slope.
    for (int j = 0; j < tile.height; ++j) {
        EXPECT_LE(
            std::abs(a.voxelDistanceTexels(0, j, 8) - a.voxelDistanceTexels(tile.width - 1, j, 8)),
            1.0);
    }
}

TEST(HeightFieldLevelSet, RejectsBadFields) {
    const Size3 tile{8, 8, 8};
    HeightField field;
    field.width = 8;
    field.height = 8;
    field.heightsTexels.assign(64, 2.0);
    EXPECT_NO_THROW(validateHeightField(field, tile, "test"));
    HeightField wrongSize = field;
    wrongSize.width = 4;
    EXPECT_THROW(levelSetFromHeightField(wrongSize, tile, 4.0f, "", ""), InputError);
    HeightField nan = field;
    nan.heightsTexels[5] = std::nan("");
    EXPECT_THROW(levelSetFromHeightField(nan, tile, 4.0f, "", ""), InputError);
    HeightField tooHigh = field;
    tooHigh.heightsTexels[5] = 8.5;
    EXPECT_THROW(levelSetFromHeightField(tooHigh, tile, 4.0f, "", ""), InputError);
    EXPECT_THROW(levelSetFromHeightField(field, tile, 0.5f, "", ""), InputError);
}

}  // namespace
}  // namespace distile
