#include "bench/main_job_bench.h"

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench/bench_common.h"
#include "bench/peers/peers.h"
#include "render/renderer.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

double median(std::vector<double> values) {
    std::sort(values.begin(), values.end());
    const std::size_t middle = values.size() / 2;
    return values.size() % 2 ? values[middle] : 0.5 * (values[middle - 1] + values[middle]);
}

std::string fixed(double value, int digits) {
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", digits, value);
    return text;
}

/// Wall seconds of one run of `program` with `arguments`, start to exit.
double processSeconds(const fs::path& program, const std::vector<std::string>& arguments,
                      const fs::path& workDir, const std::string& logName) {
    const auto start = std::chrono::steady_clock::now();
    runProgram(program, arguments, workDir, logName);
    return secondsSince(start);
}

/// The least-squares fit of T(n) = serial + parallel / n to render times on n = 1 ... N threads
/// (Amdahl's law): the serial share is serial / (serial + parallel), the part of a one-thread
/// render that more threads do not shorten.
double amdahlSerialShare(const std::vector<double>& secondsByThreads) {
    const std::size_t count = secondsByThreads.size();
    if (count < 2) return 1.0;
    double sumX = 0.0, sumY = 0.0, sumXX = 0.0, sumXY = 0.0;
    for (std::size_t index = 0; index < count; ++index) {
        const double x = 1.0 / double(index + 1);
        sumX += x;
        sumY += secondsByThreads[index];
        sumXX += x * x;
        sumXY += x * secondsByThreads[index];
    }
    const double parallel =
        (double(count) * sumXY - sumX * sumY) / (double(count) * sumXX - sumX * sumX);
    const double serial = (sumY - parallel * sumX) / double(count);
    return std::clamp(serial / (serial + parallel), 0.0, 1.0);
}

}  // namespace

MainJobReport measureMainJob(const fs::path& outputDir, const Scene& demo, int width, int height,
                             int processRuns, int renderRuns,
                             const std::function<void(const std::string&)>& say) {
    MainJobReport report;
    const fs::path workDir = outputDir / "main_job";
    fs::create_directories(workDir);
    std::error_code error;
    const fs::path program = fs::read_symlink("/proc/self/exe", error).parent_path() / "distile";
    if (error || !fs::is_regular_file(program, error))
        throw std::runtime_error(
            "bench --speed: the distile program is not beside distile-bench (" + program.string() +
            ")");
    const int threads =
        int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));

    // F. Whole processes, alternated so a slow spell of the shared machine hits both alike; one
    // untimed run first (the tile from the bake cache into the page cache).
    const std::string image = (workDir / "demo.png").string();
    const std::string size = std::to_string(width) + "x" + std::to_string(height);
    const std::vector<std::string> shadowed{"render",
                                            "-o",
                                            image,
                                            "--width",
                                            std::to_string(width),
                                            "--height",
                                            std::to_string(height)};
    std::vector<std::string> unshadowed = shadowed;
    unshadowed.insert(unshadowed.end(), {"--shadows", "none"});
    processSeconds(program, shadowed, workDir, "render_shadows");
    std::vector<double> withShadows, withoutShadows, start;
    for (int run = 0; run < processRuns; ++run) {
        withShadows.push_back(processSeconds(program, shadowed, workDir, "render_shadows"));
        withoutShadows.push_back(processSeconds(program, unshadowed, workDir, "render_none"));
        start.push_back(processSeconds(program, {"--help"}, workDir, "help"));
    }
    const double shadowsSeconds = median(withShadows), noneSeconds = median(withoutShadows);
    const double startSeconds = median(start);
    const double ratio = shadowsSeconds / noneSeconds;
    say("  distile render (demo, whole process): shadows " + fixed(shadowsSeconds, 3) +
        " s, --shadows none " + fixed(noneSeconds, 3) + " s (ratio " + fixed(ratio, 2) +
        "); process start (--help) " + fixed(startSeconds, 3) + " s; medians of " +
        std::to_string(processRuns));
    report.csv = "section,what,threads,seconds,compared_seconds\n";
    report.csv += "main job,distile render demo whole process: shadows against none," +
                  std::to_string(threads) + "," + fixed(shadowsSeconds, 4) + "," +
                  fixed(noneSeconds, 4) + "\n";
    report.csv += "main job,distile --help whole process (start-up)," + std::to_string(threads) +
                  "," + fixed(startSeconds, 4) + ",\n";
    report.markdown +=
        "\n## F. The main job: `distile render` of the demo, whole processes\n\n"
        "Process start to image written (`distile render -o demo.png`, " +
        size + ", the demo scene), median wall time of " + std::to_string(processRuns) +
        " runs each, the two alternated after one untimed run; the process start alone is "
        "`distile --help`.\n\n| run | s |\n|---|---|\n| shadows (default) | " +
        fixed(shadowsSeconds, 3) + " |\n| --shadows none | " + fixed(noneSeconds, 3) +
        " |\n| shadows / none | " + fixed(ratio, 3) + " |\n| distile --help | " +
        fixed(startSeconds, 3) + " |\n";
    report.verdicts.push_back(std::string(ratio <= 2.0 ? "**pass**" : "**FAIL**") +
                              " main job: the demo with shadows / without = " + fixed(ratio, 3) +
                              " (whole processes, <= 2)");
    report.verdicts.push_back(std::string(shadowsSeconds <= 0.6 ? "**pass**" : "**FAIL**") +
                              " main job: `distile render` of the demo at " + size +
                              ", process start to image written, " + fixed(shadowsSeconds, 3) +
                              " s on " + std::to_string(threads) +
                              " threads (<= 0.6 s on 2 cores; the machine's load counts here)");

    // G. Scaling: the demo's render (shadows on) in this process on 1 ... N threads.
    const int hardwareThreads = std::max(1, tbb::info::default_concurrency());
    RenderOptions options;
    options.width = width;
    options.height = height;
    std::vector<double> secondsByThreads;
    report.markdown +=
        "\n## G. Scaling: the demo's render against the thread count\n\n"
        "`renderScene` of the demo (" +
        size + ", shadows on), median of " + std::to_string(renderRuns) +
        " runs per thread count after one untimed render; an Amdahl fit "
        "T(n) = serial + parallel / n by least squares.\n\n"
        "| threads | s | speed-up |\n|---|---|---|\n";
    renderScene(demo, options);
    for (int count = 1; count <= hardwareThreads; ++count) {
        const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                        std::size_t(count));
        std::vector<double> runs;
        for (int run = 0; run < renderRuns; ++run) {
            const auto begin = std::chrono::steady_clock::now();
            renderScene(demo, options);
            runs.push_back(secondsSince(begin));
        }
        secondsByThreads.push_back(median(runs));
        report.markdown += "| " + std::to_string(count) + " | " +
                           fixed(secondsByThreads.back(), 3) + " | " +
                           fixed(secondsByThreads.front() / secondsByThreads.back(), 2) + " |\n";
        report.csv += "scaling,demo render," + std::to_string(count) + "," +
                      fixed(secondsByThreads.back(), 4) + "," + fixed(secondsByThreads.front(), 4) +
                      "\n";
        say("  demo render on " + std::to_string(count) +
            " thread(s): " + fixed(secondsByThreads.back(), 3) + " s");
    }
    const double serialShare = amdahlSerialShare(secondsByThreads);
    report.markdown += "\nSerial share (Amdahl fit over 1 ... " + std::to_string(hardwareThreads) +
                       " threads): " + fixed(100.0 * serialShare, 1) + "%" +
                       (hardwareThreads == 2 ? " (two points: the fit is exact)" : "") + ".\n";
    report.csv += "scaling,serial share (Amdahl fit)," + std::to_string(hardwareThreads) + "," +
                  fixed(serialShare, 4) + ",\n";
    say("  serial share (Amdahl fit): " + fixed(100.0 * serialShare, 1) + "%");
    return report;
}

}  // namespace distile::cli
