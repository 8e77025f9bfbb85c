// Baking the default chain-mail tile two ways in one process:
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

#include "bake/bake.h"
#include "common/triangle_soup.h"
#include "vdb/chainmail.h"
#include "vdb/mesh_level_set.h"

namespace distile {
namespace {

const Size3 kTile{256, 256, 16};

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

/// The default rings whose centres lie in the tile footprint (the periodic bake supplies their
/// copies across the edges). At 256 x 48 segments the faces stay within
/// chainmailTessellationErrorTexels() = 0.0063 texel of the true surface.
const TriangleSoup& chainmailMesh() {
    static const TriangleSoup soup =
        tessellateChainmail(Chainmail(ChainmailOptions{}, kTile), 256, 48);
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
