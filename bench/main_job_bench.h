/// @file
/// The main job as a user meets it, for `distile bench --speed`: `distile render` of the built-in
/// demo as whole processes (start to image written), with shadows and without, and the demo's
/// render time against the thread count with the serial share of an Amdahl fit.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "render/scene.h"

namespace distile::cli {

struct MainJobReport {
    std::string markdown;  ///< the report's sections, headings included
    std::vector<std::string>
        verdicts;     ///< one line per acceptance point, "**pass** ..." or "**FAIL** ..."
    std::string csv;  ///< main_job.csv: one row per measurement
};

/// Times `distile render -o DIR/main_job/demo.png` (the program beside this one) at `width` x
/// `height` with adaptive shadows and with --shadows none, alternated, `processRuns` of each, and
/// `distile --help` (the process start alone); then renders `demo` at that size (shadows on, the
/// other options at their defaults) in this process on 1 ... N threads (N: the hardware
/// threads), the median of `renderRuns` each. Times are
/// medians of wall time. `say` gets a line per measurement. Throws std::runtime_error when the
/// program is missing or fails.
MainJobReport measureMainJob(const std::filesystem::path& outputDir, const Scene& demo, int width,
                             int height, int processRuns, int renderRuns,
                             const std::function<void(const std::string&)>& say);

}  // namespace distile::cli
