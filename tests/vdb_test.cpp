// Tests of vdb/: the chain-mail distance against closed-form torus geometry, and level sets.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include <glm/geometric.hpp>

#include "common/error.h"
#include "vdb/chainmail.h"
#include "vdb/level_set.h"

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
    result.centre = {column * spacing + (odd ? 0.5 * spacing : 0.0), row * rowSpacing, 0.5 * tile.depth};
    result.axis = {std::sin(tilt), 0.0, std::cos(tilt)};
    result.u = {std::cos(tilt), 0.0, -std::sin(tilt)};
    result.v = {0.0, 1.0, 0.0};
    return result;
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
                const glm::dvec3 surface =
                    centreline + wireRadius * (std::cos(tubeAngle) * radial + std::sin(tubeAngle) * r.axis);
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
            return other.centre + ringRadius * (std::cos(angle) * other.u + std::sin(angle) * other.v);
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
    const double spacing = 256.0 / options.ringsPerRow;
    const double ringRadius = options.ringRadiusSpacings * spacing;
    const double wireRadius = options.wireRadiusSpacings * spacing;
    std::mt19937 random(7);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int sample = 0; sample < 300; ++sample) {
        // Includes points far above and below the tile, where many rings are candidates.
        const glm::dvec3 p{unit(random) * 256.0, unit(random) * 256.0, -40.0 + unit(random) * 96.0};
        double expected = 1e300;
        for (int row = -12; row < 22; ++row) {
            for (int column = -6; column < 14; ++column) {
                const Ring r = ring(options, kDefaultTile, column, row);
                const glm::dvec3 offset = p - r.centre;
                const double inPlane = std::hypot(glm::dot(offset, r.u), glm::dot(offset, r.v));
                expected = std::min(expected, std::hypot(inPlane - ringRadius, glm::dot(offset, r.axis)) - wireRadius);
            }
        }
        EXPECT_NEAR(chainmail.signedDistanceTexels(p), expected, 1e-9) << "at " << p.x << "," << p.y << "," << p.z;
        // Periodic with the tile: shifting by W or H, or many tiles, changes nothing.
        EXPECT_NEAR(chainmail.signedDistanceTexels(p + glm::dvec3(256.0, 0.0, 0.0)), expected, 1e-9);
        EXPECT_NEAR(chainmail.signedDistanceTexels(p + glm::dvec3(0.0, -256.0, 0.0)), expected, 1e-9);
        EXPECT_NEAR(chainmail.signedDistanceTexels(p + glm::dvec3(256.0 * 37, 256.0 * 11, 0.0)), expected, 1e-7);
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
                  ("distile_vdb_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
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
    const LevelSet levelSet = LevelSet::fromDistance([](const glm::dvec3& p) { return p.z - 5.3; }, size, halfBand,
                                                     "plane", "{}");
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
        [](const glm::dvec3& p) { return glm::length(p - glm::dvec3(4, 4, 3)) - 2.0; }, size, 6.0f, "sphere", "{\"r\":2}");
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
                const double expected = glm::length(glm::dvec3(i + 0.5, j + 0.5, k + 0.5) - glm::dvec3(4, 4, 3)) - 2.0;
                EXPECT_FLOAT_EQ(texels[i + size.width * (j + size.height * k)], float(expected));
            }
        }
    }
}

TEST_F(LevelSetTest, RejectsMissingAndCorruptedFiles) {
    EXPECT_THROW(LevelSet::load(folder_ / "missing.vdb"), InputError);
    const LevelSet levelSet =
        LevelSet::fromDistance([](const glm::dvec3& p) { return p.z - 2.0; }, Size3{8, 8, 4}, 2.0f, "plane", "{}");
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

}  // namespace
}  // namespace distile
