// Micro-benchmarks: filter samples and whole sphere-traced marches on the default chain-mail
// tile, and the bake itself. Run: build/bin/distile_bench [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include <glm/geometric.hpp>

#include "render/march.h"
#include "sampler/bake.h"
#include "sampler/filters.h"

namespace distile {
namespace {

const Tile& chainmailTile() {
    static const Tile tile = bakeChainmail(ChainmailOptions{}, BakeOptions{}).tile;
    return tile;
}

std::vector<glm::vec3> randomPoints(std::size_t count) {
    std::mt19937 random(11);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<glm::vec3> points(count);
    for (auto& p : points) p = {unit(random) * 256.0f, unit(random) * 256.0f, unit(random) * 16.0f};
    return points;
}

template <class Filter>
void sampleDistance(benchmark::State& state) {
    const Filter filter(chainmailTile());
    const auto points = randomPoints(1 << 16);
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(filter.distanceTexels(points[i++ & 0xffff]));
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(sampleDistance<NearestFilter>);
BENCHMARK(sampleDistance<TrilinearFilter>);

void trilinearGradient(benchmark::State& state) {
    const TrilinearFilter filter(chainmailTile());
    const auto points = randomPoints(1 << 16);
    std::size_t i = 0;
    for (auto _ : state) benchmark::DoNotOptimize(filter.gradient(points[i++ & 0xffff]));
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(trilinearGradient);

/// One march per item from a random entry point at 35 degrees above the tile, the budget given.
void marchChainmail(benchmark::State& state) {
    const TrilinearFilter filter(chainmailTile());
    auto entries = randomPoints(1 << 12);
    for (auto& p : entries) p.z = 16.0f;
    const glm::vec3 direction = glm::normalize(glm::vec3(0.6f, 0.55f, -0.58f));
    const int budget = int(state.range(0));
    std::size_t i = 0;
    std::int64_t iterations = 0;
    for (auto _ : state) {
        const MarchResult result = march(filter, entries[i++ & 0xfff], direction, Floor::Solid, budget, 0.02f);
        iterations += result.iterations;
        benchmark::DoNotOptimize(result);
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["iterations/ray"] = benchmark::Counter(double(iterations) / double(state.iterations()));
}
BENCHMARK(marchChainmail)->Arg(8)->Arg(16)->Arg(64);

void bakeDefaultChainmail(benchmark::State& state) {
    for (auto _ : state) benchmark::DoNotOptimize(bakeChainmail(ChainmailOptions{}, BakeOptions{}).tile.size());
}
BENCHMARK(bakeDefaultChainmail)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace
}  // namespace distile

BENCHMARK_MAIN();
