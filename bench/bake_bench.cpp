// Baking the default chain-mail tile two ways in one process (issue #3):
//  - procedural: distile's bake (exact analytic distance into the level set, then the
//    conservative tile), band = the tile depth;
//  - mesh: the same rings tessellated finely and converted with OpenVDB's mesh-to-level-set
//    (vdb/mesh_level_set.h) at a half band of 3 voxels, voxel size 1 texel.
// Both report their error against the analytic distance over the voxels where both are defined
// (the mesh level set's band, |d| < 3, inside the tile's footprint and depth) as counters.
// Run: build/bin/bake_bench [--benchmark_filter=...]; compare the two times of one run.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <glm/vec3.hpp>
#include <optional>
#include <vector>

#include "common/triangle_soup.h"
#include "sampler/bake.h"
#include "vdb/chainmail.h"
#include "vdb/mesh_level_set.h"

namespace distile {
namespace {

constexpr double kPi = 3.14159265358979323846;
const Size3 kTile{256, 256, 16};

/// The default European 4-in-1 rings whose centres lie in the tile footprint (the periodic bake
/// supplies their copies across the edges), each a torus of `around` x `tube` quads. At 256 x 48
/// the inscribed polygons deviate from the true surface by at most R(1 - cos(pi/256)) +
/// r(1 - cos(pi/48)) = 22.5 * 7.5e-5 + 2.1 * 2.1e-3 < 0.006 texel.
TriangleSoup tessellatedChainmail(int around, int tube) {
    const ChainmailOptions options;
    const double spacing = double(kTile.width) / options.ringsPerRow;
    const double rowSpacing = double(kTile.height) / options.rowsPerTile;
    const double ringRadius = options.ringRadiusSpacings * spacing;
    const double wireRadius = options.wireRadiusSpacings * spacing;
    TriangleSoup soup;
    for (int row = 0; row < options.rowsPerTile; ++row) {
        const bool odd = row % 2 == 1;
        const double tilt = (odd ? -1.0 : 1.0) * options.tiltDeg * kPi / 180.0;
        for (int column = 0; column < options.ringsPerRow; ++column) {
            const glm::dvec3 centre{column * spacing + (odd ? 0.5 * spacing : 0.0),
                                    row * rowSpacing, 0.5 * kTile.depth};
            const auto first = unsigned(soup.positions.size());
            for (int i = 0; i < around; ++i) {
                const double a = 2.0 * kPi * i / around;
                for (int j = 0; j < tube; ++j) {
                    const double b = 2.0 * kPi * j / tube;
                    // Torus in the ring's frame (axis local z), then rotated about y by the tilt:
                    // the inverse of the rotation in vdb/chainmail.cpp.
                    const glm::dvec3 local{(ringRadius + wireRadius * std::cos(b)) * std::cos(a),
                                           (ringRadius + wireRadius * std::cos(b)) * std::sin(a),
                                           wireRadius * std::sin(b)};
                    const glm::dvec3 offset{std::cos(tilt) * local.x + std::sin(tilt) * local.z,
                                            local.y,
                                            -std::sin(tilt) * local.x + std::cos(tilt) * local.z};
                    soup.positions.push_back(centre + offset);
                }
            }
            auto vertex = [&](int i, int j) {
                return first + unsigned((i % around) * tube + (j % tube));
            };
            for (int i = 0; i < around; ++i) {
                for (int j = 0; j < tube; ++j) {
                    // Counter-clockwise seen from outside.
                    soup.triangles.push_back(
                        {vertex(i, j), vertex(i + 1, j), vertex(i + 1, j + 1)});
                    soup.triangles.push_back(
                        {vertex(i, j), vertex(i + 1, j + 1), vertex(i, j + 1)});
                }
            }
        }
    }
    return soup;
}

struct VoxelErrors {
    double rms = 0.0;
    double max = 0.0;
    double voxels = 0.0;
};

/// Error against the analytic chain mail of `levelSet` at the voxels where `reference` (the mesh
/// level set) has |d| < its half band, inside the footprint and depth of the tile.
VoxelErrors voxelErrors(const LevelSet& levelSet, const LevelSet& reference) {
    const Chainmail chainmail(ChainmailOptions{}, kTile);
    VoxelErrors errors;
    double sumSquares = 0.0;
    for (int k = 0; k < kTile.depth; ++k) {
        for (int j = 0; j < kTile.height; ++j) {
            for (int i = 0; i < kTile.width; ++i) {
                if (!(std::abs(reference.voxelDistanceTexels(i, j, k)) <
                      reference.halfBandTexels()))
                    continue;
                const double truth = chainmail.signedDistanceTexels({i + 0.5, j + 0.5, k + 0.5});
                const double error =
                    std::abs(double(levelSet.voxelDistanceTexels(i, j, k)) - truth);
                sumSquares += error * error;
                errors.max = std::max(errors.max, error);
                errors.voxels += 1.0;
            }
        }
    }
    errors.rms = errors.voxels > 0.0 ? std::sqrt(sumSquares / errors.voxels) : 0.0;
    return errors;
}

const TriangleSoup& chainmailMesh() {
    static const TriangleSoup soup = tessellatedChainmail(256, 48);
    return soup;
}

constexpr float kMeshHalfBand = 3.0f;

void setErrorCounters(benchmark::State& state, const VoxelErrors& errors) {
    state.counters["rms_error_texels"] = errors.rms;
    state.counters["max_error_texels"] = errors.max;
    state.counters["compared_voxels"] = errors.voxels;
}

void bakeChainmailProcedural(benchmark::State& state) {
    std::optional<BakeResult> result;
    for (auto _ : state) {
        result.emplace(bakeChainmail(ChainmailOptions{}, BakeOptions{}));
        benchmark::DoNotOptimize(result->tile.distancesTexels().data());
    }
    const LevelSet mesh = levelSetFromMesh(chainmailMesh(), kTile, kMeshHalfBand, "mesh", "{}");
    setErrorCounters(state, voxelErrors(result->levelSet, mesh));
}
BENCHMARK(bakeChainmailProcedural)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();

void bakeChainmailMeshToLevelSet(benchmark::State& state) {
    const TriangleSoup& soup = chainmailMesh();
    std::optional<LevelSet> levelSet;
    for (auto _ : state) {
        levelSet.emplace(levelSetFromMesh(soup, kTile, kMeshHalfBand, "mesh", "{}"));
        benchmark::DoNotOptimize(levelSet->activeVoxelCount());
    }
    state.counters["triangles"] = double(soup.triangles.size());
    setErrorCounters(state, voxelErrors(*levelSet, *levelSet));
}
BENCHMARK(bakeChainmailMeshToLevelSet)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();

}  // namespace
}  // namespace distile

BENCHMARK_MAIN();
