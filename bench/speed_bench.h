/// @file
/// `distile bench --speed -o DIR`: the acceptance measurements of the renderer's speed.
/// distile against Embree and vdb_render on the chain-mail sheet, the cost of repetition (uv scale
/// 16x), every RenderSkips switch on and off on six scenes (time and image difference), the bake
/// cache, thread-count independence, and on curved bases the curved shell march against the
/// planar one (time, and error against the world reference). Writes DIR/speed.csv (one row per
/// measurement), DIR/speed.md (tables and a verdict per acceptance point) and the scenes under
/// DIR/scenes/.
#pragma once

#include "bench/bench_common.h"

namespace distile::cli {

/// Runs the speed report with `arguments` (outputDir, quick, peers, width, height). Renders are
/// timed as the minimum of 3 runs (2 with quick). Throws InputError when the output folder cannot
/// be created or written.
void runSpeedBench(const BenchArguments& arguments);

}  // namespace distile::cli
