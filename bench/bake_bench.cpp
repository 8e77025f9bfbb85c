// Baking the default chain-mail tile two ways in one process:
//  - procedural: distile's bake (exact analytic distance into the level set, then the
//    conservative tile), band = the tile depth;
//  - mesh: the same rings tessellated finely and converted with OpenVDB's mesh-to-level-set
//    (vdb/mesh_level_set.h) at a half band of 3 voxels, voxel size 1 texel.
// Both report their error against the analytic distance over the voxels where both are defined
// (the mesh level set's band, |d| < 3, inside the tile's footprint and depth) as counters.
// And the mesh bake (bake/solid_mesh.h: exact BVH distance, winding-number sign) against OpenVDB's
// mesh-to-level-set (bake/bake.h bakeMesh) on the chain mail tessellated at three sizes (argument:
// triangles per ring, about 3 k, 100 k and 1 M triangles in all), both at voxel size 1 texel and
// the half band `bake mesh` uses (the tile depth), conservative lowering off. meshToLevelSet
// always fills the whole level set, the tile and its band margin above and below it (three times
// the tile's voxels); the mesh bake does so only when the level set is kept (`--vdb`), so it is
// timed both ways: bakeMeshWindingNumber (the tile only, as `bake mesh` without --vdb and scenes
// bake) and bakeMeshWindingNumberWithMargins (the same voxels as meshToLevelSet). A third,
// bakeMeshWindingNumberConservative, is what `bake mesh` and scenes run by default: the tile with
// its conservative lowering, measured against exact distances at the half-texel points near the
// surface (bake/conservative.h); its errors are those of the lowered tile. Counters: the
// error against the exact distance to the same mesh (CGAL, truth/mesh_truth.h) at random voxel
// centres of the tile within 2 texels of the surface (max, RMS), at all of them (all_max, against
// the exact distance clamped to the half band) and the sign errors at all sampled voxels.
// Run: build/bin/bake_bench [--benchmark_filter=...]; compare the times of one run.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <glm/vec3.hpp>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <vector>

#include "bake/bake.h"
#include "bake/solid_mesh.h"
#include "common/triangle_soup.h"
#include "truth/mesh_truth.h"
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

/// The default chain mail with `segmentsAround` x `segmentsTube` quads per ring.
struct ChainmailMesh {
    TriangleSoup soup;
    std::unique_ptr<MeshDistance> truth;  ///< exact periodic distance to `soup`
};
const ChainmailMesh& chainmailMeshOfSize(int segmentsAround, int segmentsTube) {
    static std::map<std::pair<int, int>, ChainmailMesh> meshes;
    ChainmailMesh& mesh = meshes[{segmentsAround, segmentsTube}];
    if (mesh.soup.triangles.empty()) {
        mesh.soup =
            tessellateChainmail(Chainmail(ChainmailOptions{}, kTile), segmentsAround, segmentsTube);
        mesh.truth = std::make_unique<MeshDistance>(mesh.soup, MeshDistance::Periodic{kTile});
    }
    return mesh;
}

/// Errors of a tile (exact texels) against the exact mesh distance at random voxel centres.
void setMeshErrorCounters(benchmark::State& state, const Tile& tile, const ChainmailMesh& mesh) {
    std::mt19937 random(7);
    std::uniform_int_distribution<int> i(0, kTile.width - 1), j(0, kTile.height - 1),
        k(0, kTile.depth - 1);
    // Both bakes clamp at the half band, the tile depth.
    const double halfBand = double(kTile.depth);
    double maxError = 0.0, allMaxError = 0.0, sumSquares = 0.0, near = 0.0, signErrors = 0.0;
    for (int n = 0; n < 20000; ++n) {
        const int x = i(random), y = j(random), z = k(random);
        const double truth = mesh.truth->signedDistance({x + 0.5, y + 0.5, z + 0.5});
        const double baked = tile.at(x, y, z);
        if (std::abs(truth) > 1e-6 && (truth < 0.0) != (baked < 0.0)) signErrors += 1.0;
        allMaxError =
            std::max(allMaxError, std::abs(baked - std::clamp(truth, -halfBand, halfBand)));
        if (std::abs(truth) > 2.0) continue;
        near += 1.0;
        maxError = std::max(maxError, std::abs(baked - truth));
        sumSquares += (baked - truth) * (baked - truth);
    }
    state.counters["triangles"] = double(mesh.soup.triangles.size());
    state.counters["near_max_error_texels"] = maxError;
    state.counters["near_rms_error_texels"] = near > 0.0 ? std::sqrt(sumSquares / near) : 0.0;
    state.counters["all_max_error_texels"] = allMaxError;
    state.counters["sign_errors"] = signErrors;
}

/// Argument pairs (segments around the ring, around the wire): 3 k, 100 k and 1 M triangles.
void meshSizes(benchmark::internal::Benchmark* benchmark) {
    benchmark->Args({8, 3})->Args({48, 13})->Args({160, 40});
}

BakeOptions exactTexelOptions(bool fillLevelSetMargins) {
    BakeOptions options;
    options.conservative.enabled = false;
    options.fillLevelSetMargins = fillLevelSetMargins;
    return options;
}

MeshPlacement asTessellated() {
    MeshPlacement placement;
    placement.fit = false;
    return placement;
}

void bakeMeshWindingNumberOf(benchmark::State& state, const BakeOptions& options) {
    const ChainmailMesh& mesh = chainmailMeshOfSize(int(state.range(0)), int(state.range(1)));
    std::optional<SolidMeshBake> bake;
    for (auto _ : state) {
        bake.emplace(bakeSolidMesh(mesh.soup, asTessellated(), options, "chainmail"));
        benchmark::DoNotOptimize(bake->result.tile.distancesTexels().data());
    }
    setMeshErrorCounters(state, bake->result.tile, mesh);
}

/// The tile alone: what `bake mesh` without --vdb and a scene compute.
void bakeMeshWindingNumber(benchmark::State& state) {
    bakeMeshWindingNumberOf(state, exactTexelOptions(false));
}
BENCHMARK(bakeMeshWindingNumber)
    ->Apply(meshSizes)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->UseRealTime();

/// The whole level set, margins included, as meshToLevelSet computes it (`bake mesh --vdb`).
void bakeMeshWindingNumberWithMargins(benchmark::State& state) {
    bakeMeshWindingNumberOf(state, exactTexelOptions(true));
}
BENCHMARK(bakeMeshWindingNumberWithMargins)
    ->Apply(meshSizes)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->UseRealTime();

/// The tile with its conservative lowering, as `bake mesh` and scenes bake by default.
void bakeMeshWindingNumberConservative(benchmark::State& state) {
    BakeOptions options;
    options.fillLevelSetMargins = false;
    bakeMeshWindingNumberOf(state, options);
}
BENCHMARK(bakeMeshWindingNumberConservative)
    ->Apply(meshSizes)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->UseRealTime();

void bakeMeshOpenVdb(benchmark::State& state) {
    const ChainmailMesh& mesh = chainmailMeshOfSize(int(state.range(0)), int(state.range(1)));
    std::optional<BakeResult> bake;
    for (auto _ : state) {
        bake.emplace(bakeMesh(mesh.soup, asTessellated(), exactTexelOptions(true)));
        benchmark::DoNotOptimize(bake->tile.distancesTexels().data());
    }
    setMeshErrorCounters(state, bake->tile, mesh);
}
BENCHMARK(bakeMeshOpenVdb)
    ->Apply(meshSizes)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->UseRealTime();

}  // namespace
}  // namespace distile

BENCHMARK_MAIN();
