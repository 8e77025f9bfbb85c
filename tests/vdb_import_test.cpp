// Level sets made elsewhere (vdb/vdb_volume.h) baked into tiles (bake/vdb_bake.h), against the
// analytic sphere.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <optional>
#include <string>
#include <vector>

#include "bake/vdb_bake.h"
#include "common/error.h"
#include "sampler/tile_error.h"
#include "tests/temp_folder.h"
#include "vdb/vdb_volume.h"

namespace distile {
namespace {

namespace fs = std::filesystem;

class VdbImport : public ::testing::Test {
  protected:
    fs::path path(const std::string& name) const { return folder_.path(name); }

  private:
    TempFolder folder_{"distile_vdb_import"};
};

/// A unit-radius sphere off the origin, on a voxel lattice of 0.07 units turned 30 degrees: the
/// voxels are neither the tile's texels nor aligned with them.
SphereVolumeOptions rotatedSphere() {
    SphereVolumeOptions sphere;
    sphere.radiusWorld = 1.0;
    sphere.centreWorld = {0.3, -0.2, 0.1};
    sphere.voxelSizeWorld = 0.07;
    sphere.rotationDegrees = 30.0;
    return sphere;
}

/// 12 texels per unit, the centre at texel (32, 32, 16) of a 64x64x32 tile.
VdbPlacement sphereInTile(const SphereVolumeOptions& sphere) {
    VdbPlacement placement;
    placement.mode = VdbPlacement::Mode::Explicit;
    placement.scale = 12.0;
    placement.offsetTexels = glm::dvec3(32.0, 32.0, 16.0) - 12.0 * sphere.centreWorld;
    return placement;
}

struct SphereErrors {
    double centreMaxNear = 0.0;  ///< largest |error| at texel centres with |truth| <= 2
    double centreRms = 0.0;      ///< RMS at all texel centres (truth clamped to the band)
    int centreSignErrors = 0;    ///< texel centres with |truth| > 0.5 and the other sign
    TileErrorReport sampled;     ///< the default (conservative) tile, trilinear, random points
};

/// The bake of `file` against the exact sphere distance, |p - (32, 32, 16)| - 12 texels.
SphereErrors measureSphere(const fs::path& file, const VdbPlacement& placement,
                           const std::string& gridName = "", std::optional<double> iso = {}) {
    const VdbVolume volume = VdbVolume::read(file, gridName, iso);
    BakeOptions options;
    options.size = {64, 64, 32};
    const VdbBakeResult baked = bakeVdb(volume, placement, options, file.filename().string());
    auto truth = [](const glm::dvec3& p) {
        return glm::length(p - glm::dvec3(32.0, 32.0, 16.0)) - 12.0;
    };
    SphereErrors errors;
    double sumSquares = 0.0;
    const Size3 size = options.size;
    for (int k = 0; k < size.depth; ++k) {
        for (int j = 0; j < size.height; ++j) {
            for (int i = 0; i < size.width; ++i) {
                const double exact = std::clamp(truth({i + 0.5, j + 0.5, k + 0.5}), -32.0, 32.0);
                const double value = baked.bake.levelSet.voxelDistanceTexels(i, j, k);
                const double error = value - exact;
                sumSquares += error * error;
                if (std::abs(exact) <= 2.0)
                    errors.centreMaxNear = std::max(errors.centreMaxNear, std::abs(error));
                if (std::abs(exact) > 0.5 && (exact < 0.0) != (value < 0.0))
                    ++errors.centreSignErrors;
            }
        }
    }
    errors.centreRms = std::sqrt(sumSquares / double(size.texelCount()));
    TileErrorOptions sampling;
    sampling.truthClampTexels = 32.0;
    errors.sampled = measureTileError(baked.bake.tile, truth, sampling);
    std::printf(
        "%s: texel centres: near max %.4f RMS %.4f; tile (trilinear): near p99.9 %.4f "
        "RMS %.4f sign errors %d\n",
        file.filename().c_str(), errors.centreMaxNear, errors.centreRms,
        errors.sampled.nearP999Texels, errors.sampled.rmsTexels, errors.sampled.signErrors);
    return errors;
}

/// Tolerances: the texel-centre distances come from trilinear interpolation of exact voxel values
/// on the 0.84-texel lattice and from the polygonised surface; both err by about h^2 / (8 R) ~
/// 0.01 texel on this sphere, so 0.1 near the surface and 0.05 RMS leave room without hiding a
/// wrong transform (a misplaced or unscaled sphere errs by texels). The trilinear tile is held to
/// the acceptance figures: p99.9 <= 0.5, RMS <= 0.1 texel, no sign errors.
void expectTheSphere(const SphereErrors& errors) {
    EXPECT_LE(errors.centreMaxNear, 0.1);
    EXPECT_LE(errors.centreRms, 0.05);
    EXPECT_EQ(errors.centreSignErrors, 0);
    EXPECT_LE(errors.sampled.nearP999Texels, 0.5);
    EXPECT_LE(errors.sampled.rmsTexels, 0.1);
    EXPECT_EQ(errors.sampled.signErrors, 0);
}

// The source band (3 voxels, 2.5 texels) is far thinner than the tile's (32 texels): beyond it
// the distances are rebuilt from the surface.
TEST_F(VdbImport, RotatedSphereWithAThinBandMatchesTheAnalyticSphere) {
    const SphereVolumeOptions sphere = rotatedSphere();
    writeSphereVolume(path("sphere.vdb"), sphere);
    const VdbVolume volume = VdbVolume::read(path("sphere.vdb"));
    EXPECT_TRUE(VdbDistance(volume, {12.0, glm::dvec3(0.0)}, {64, 64, 32}, 32.0f).rebuilt());
    const SphereErrors errors = measureSphere(path("sphere.vdb"), sphereInTile(sphere));
    expectTheSphere(errors);
}

// A file whose background (what reads back beyond the band) is far wider than its band: the
// band was taken from the background, so past the real band the background's +-10 units read
// as distances (here RMS 17 texels, 1408 sign errors). The band is what the values reach.
TEST_F(VdbImport, ABackgroundWiderThanTheBandIsNotTakenForTheBand) {
    SphereVolumeOptions sphere = rotatedSphere();
    sphere.backgroundWorld = 10.0;  // 120 texels; the band is 3 voxels, 0.21 units
    writeSphereVolume(path("sphere.vdb"), sphere);
    const VdbVolume volume = VdbVolume::read(path("sphere.vdb"));
    // The largest stored value (under 0.21 units) and a voxel (0.07): about 3.3 texels, not 120.
    const double band = VdbSourceSampler(volume, {12.0, glm::dvec3(0.0)}).bandTexels();
    EXPECT_GT(band, 12.0 * 0.2);
    EXPECT_LT(band, 12.0 * 0.29);
    EXPECT_TRUE(VdbDistance(volume, {12.0, glm::dvec3(0.0)}, {64, 64, 32}, 32.0f).rebuilt());
    expectTheSphere(measureSphere(path("sphere.vdb"), sphereInTile(sphere)));
}

// A band as wide as the tile needs: the source's own values everywhere, no rebuild.
// The rebuilt band (surface refined in parallel, distances a row per task) is the same on one
// thread as on two.
TEST_F(VdbImport, RebuiltBandDoesNotDependOnTheThreadCount) {
    const SphereVolumeOptions sphere = rotatedSphere();
    writeSphereVolume(path("sphere.vdb"), sphere);
    const VdbVolume volume = VdbVolume::read(path("sphere.vdb"));
    BakeOptions options;
    options.size = {64, 64, 32};
    auto bake = [&](int threads) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        return bakeVdb(volume, sphereInTile(sphere), options, "sphere.vdb").bake.tile;
    };
    const Tile one = bake(1);
    const Tile two = bake(2);
    EXPECT_TRUE(std::equal(one.distancesTexels().begin(), one.distancesTexels().end(),
                           two.distancesTexels().begin()));
}

TEST_F(VdbImport, RotatedSphereWithAWideBandUsesTheSourceValues) {
    SphereVolumeOptions sphere = rotatedSphere();
    sphere.halfWidthVoxels = 40.0f;  // 40 * 0.07 * 12 = 33.6 texels >= 32
    writeSphereVolume(path("wide.vdb"), sphere);
    const VdbVolume volume = VdbVolume::read(path("wide.vdb"));
    EXPECT_FALSE(VdbDistance(volume, {12.0, glm::dvec3(0.0)}, {64, 64, 32}, 32.0f).rebuilt());
    const SphereErrors errors = measureSphere(path("wide.vdb"), sphereInTile(sphere));
    expectTheSphere(errors);
}

// A fog volume (density 1 inside, a linear ramp across 3 voxels) at iso 0.5 is the same sphere;
// its values are not distances, so all of them are rebuilt.
TEST_F(VdbImport, FogSphereAtTheIsoValueMatchesTheAnalyticSphere) {
    SphereVolumeOptions sphere = rotatedSphere();
    sphere.fog = true;
    sphere.gridName = "density";
    writeSphereVolume(path("fog.vdb"), sphere);
    EXPECT_THROW(VdbVolume::read(path("fog.vdb")), InputError);  // no level set
    try {
        VdbVolume::read(path("fog.vdb"), "density");
        FAIL() << "a fog volume without an iso value was accepted";
    } catch (const InputError& error) {
        EXPECT_EQ(error.field(), "iso");
        EXPECT_NE(std::string(error.what()).find("fog volume"), std::string::npos) << error.what();
    }
    const VdbVolume volume = VdbVolume::read(path("fog.vdb"), "density", 0.5);
    EXPECT_FALSE(volume.isLevelSet());
    const SphereErrors errors =
        measureSphere(path("fog.vdb"), sphereInTile(sphere), "density", 0.5);
    expectTheSphere(errors);
    // The file's only float grid, with an iso value, needs no name.
    EXPECT_EQ(VdbVolume::read(path("fog.vdb"), "", 0.5).gridName(), "density");
}

TEST_F(VdbImport, AFileOfSeveralGridsHasEachReadByName) {
    // Each grid's data follows its descriptor: the header check once read the descriptors back
    // to back and refused every file of two or more grids as truncated.
    SphereVolumeOptions a = rotatedSphere(), b = rotatedSphere(), fog = rotatedSphere();
    a.gridName = "a";
    b.gridName = "b";
    b.radiusWorld = 0.5;
    b.centreWorld = a.centreWorld;
    fog.gridName = "density";
    fog.fog = true;
    writeSphereVolumes(path("three.vdb"), {a, b, fog});
    std::vector<std::string> names;
    for (const VdbGridInfo& grid : listVdbGrids(path("three.vdb"))) names.push_back(grid.name);
    EXPECT_EQ(names, (std::vector<std::string>{"a", "b", "density"}));
    try {
        VdbVolume::read(path("three.vdb"));
        FAIL() << "two level sets, and no grid named";
    } catch (const InputError& error) {
        EXPECT_EQ(error.field(), "grid");
        EXPECT_NE(std::string(error.what()).find("several level sets"), std::string::npos)
            << error.what();
    }
    // Each grid is the sphere it holds: a's surface lies 12 texels from the centre, b's 6.
    expectTheSphere(measureSphere(path("three.vdb"), sphereInTile(a), "a"));
    const VdbVolume half = VdbVolume::read(path("three.vdb"), "b");
    EXPECT_NEAR(half.surfaceBoundsWorld().max.x - half.surfaceBoundsWorld().min.x, 1.0, 0.02);
    EXPECT_FALSE(VdbVolume::read(path("three.vdb"), "density", 0.5).isLevelSet());
}

// Fit: the surface's box (2 units) spans the 64-texel footprint: 32 texels per unit, the sphere
// centred, its bottom on the floor.
TEST_F(VdbImport, FitPutsTheSurfaceBoxOnTheFootprint) {
    SphereVolumeOptions sphere = rotatedSphere();
    writeSphereVolume(path("sphere.vdb"), sphere);
    const VdbVolume volume = VdbVolume::read(path("sphere.vdb"));
    BakeOptions options;
    options.size = {64, 64, 72};  // the polygonised sphere's box is not exactly a cube
    options.halfBandTexels = 4.0f;
    const VdbBakeResult baked = bakeVdb(volume, VdbPlacement(), options, "sphere.vdb");
    EXPECT_NEAR(baked.placement.scale, 32.0, 0.5);
    const glm::dvec3 centre =
        baked.placement.scale * sphere.centreWorld + baked.placement.offsetTexels;
    // The box is the polygonised surface's: within a small fraction of a texel of the sphere's.
    EXPECT_NEAR(centre.x, 32.0, 0.05);
    EXPECT_NEAR(centre.y, 32.0, 0.05);
    EXPECT_NEAR(centre.z, baked.placement.scale * 1.0, 0.5);
    EXPECT_EQ(baked.bake.tile.provenance.source, "vdb");
    EXPECT_NE(baked.bake.tile.provenance.params.find("\"grid\":\"surface\""), std::string::npos)
        << baked.bake.tile.provenance.params;
    EXPECT_FALSE(baked.seamMismatchTexels);
    options.size = {64, 64, 16};  // the fitted sphere is 64 texels tall
    EXPECT_THROW(bakeVdb(volume, VdbPlacement(), options, "sphere.vdb"), InputError);
}

TEST_F(VdbImport, RefusesWindowsOutsideTheGridOrOfTheWrongAspect) {
    writeSphereVolume(path("sphere.vdb"), rotatedSphere());
    const VdbVolume volume = VdbVolume::read(path("sphere.vdb"));
    BakeOptions options;
    options.size = {32, 32, 16};
    auto bakeWindow = [&](const Bounds3& window) {
        VdbPlacement placement;
        placement.mode = VdbPlacement::Mode::Window;
        placement.windowWorld = window;
        return bakeVdb(volume, placement, options, "sphere.vdb");
    };
    auto expectWindowError = [&](const Bounds3& window) {
        try {
            bakeWindow(window);
            ADD_FAILURE() << "window accepted";
        } catch (const InputError& error) {
            EXPECT_EQ(error.field(), "placement.windowWorld") << error.what();
        }
    };
    expectWindowError({{5.0, 5.0, 0.0}, {6.0, 6.0, 0.5}});   // outside
    expectWindowError({{0.0, 0.0, 0.0}, {1.0, 0.5, 0.5}});   // aspect 2:1, tile 1:1
    expectWindowError({{0.0, 0.0, -1.0}, {1.0, 1.0, 1.0}});  // 64 texels tall
    expectWindowError({{1.0, 0.0, 0.0}, {0.0, 1.0, 0.5}});   // empty
    // Cut off-centre in x, centred in y: the x faces differ, the y faces agree.
    const VdbBakeResult inside = bakeWindow({{-0.5, -0.7, -0.4}, {0.5, 0.3, 0.1}});
    ASSERT_TRUE(inside.seamMismatchTexels);
    EXPECT_GT(inside.seamMismatchTexels->x, 1.0);
    EXPECT_LT(inside.seamMismatchTexels->y, 0.1);
}

TEST_F(VdbImport, RefusesMissingCorruptAndUnknownInputs) {
    EXPECT_THROW(VdbVolume::read(path("missing.vdb")), InputError);
    std::ofstream(path("text.vdb")) << "not a vdb file\n";
    EXPECT_THROW(VdbVolume::read(path("text.vdb")), FormatError);
    writeSphereVolume(path("sphere.vdb"), rotatedSphere());
    try {
        VdbVolume::read(path("sphere.vdb"), "density");
        FAIL() << "a missing grid was accepted";
    } catch (const InputError& error) {
        EXPECT_EQ(error.field(), "grid");
        EXPECT_NE(std::string(error.what()).find("'surface' (float, level set)"), std::string::npos)
            << error.what();
    }
    EXPECT_THROW(VdbVolume::read(path("sphere.vdb"), "", std::nan("")), InputError);
    EXPECT_THROW(VdbVolume::read(path("sphere.vdb"), "", 5.0), FormatError);  // no crossing
    const std::uintmax_t size = fs::file_size(path("sphere.vdb"));
    fs::copy_file(path("sphere.vdb"), path("truncated.vdb"));
    fs::resize_file(path("truncated.vdb"), size / 2);
    EXPECT_THROW(VdbVolume::read(path("truncated.vdb")), FormatError);
}

}  // namespace
}  // namespace distile
