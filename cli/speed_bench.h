/// @file
/// `distile bench --speed -o DIR` (issue 6): the acceptance measurements of the renderer's speed.
/// distile against Embree and vdb_render on the chain-mail sheet, the cost of repetition (uv scale
/// 16x), every RenderSkips switch on and off on four scenes (time and image difference), the bake
/// cache, and thread-count independence. Writes DIR/speed.csv (one row per measurement),
/// DIR/speed.md (tables and a verdict per acceptance point) and the scenes under DIR/scenes/.
#pragma once

#include "cli/bench_common.h"

namespace distile::cli {

/// Runs the speed report with `arguments` (outputDir, quick, peers, width, height). Renders are
/// timed as the minimum of 3 runs (2 with quick). Throws InputError when the output folder cannot
/// be created or written.
void runSpeedBench(const BenchArguments& arguments);

}  // namespace distile::cli
