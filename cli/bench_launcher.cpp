// `distile bench`: runs distile-bench, built in bench/ next to the `distile` program, with the
// same arguments (the benchmarks link the peers and the stress cases, which distile does not).
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "cli/commands.h"
#include "common/error.h"

namespace distile::cli {

namespace {

namespace fs = std::filesystem;

/// Replaces this process by distile-bench from this program's folder, with `argv`.
[[noreturn]] void runDistileBench(char** argv) {
    std::error_code error;
    const fs::path self = fs::read_symlink("/proc/self/exe", error);
    const fs::path bench = self.parent_path() / "distile-bench";
    if (error || !fs::is_regular_file(bench, error)) {
        throw InputError("bench: the benchmarks were not built (" + bench.string() +
                         " is missing); configure with -DDISTILE_BUILD_BENCH=ON and build "
                         "distile-bench");
    }
    std::fflush(stdout);
    std::fflush(stderr);
    execv(bench.c_str(), argv);
    throw std::runtime_error("bench: cannot run " + bench.string() + ": " + std::strerror(errno));
}

}  // namespace

void addBenchLauncher(CLI::App& app, char** argv) {
    CLI::App* command = app.add_subcommand(
        "bench",
        "Time against error on the flat chain-mail sheet, next to Embree and vdb_render; the "
        "speed report (--speed) and the stress cases (--stress). Runs distile-bench; see "
        "`distile bench --help`");
    // Every argument after `bench` is distile-bench's: --help, and --threads too (not taken by
    // distile's own options).
    command->prefix_command();
    command->set_help_flag();
    command->fallthrough(false);
    command->callback([argv] { runDistileBench(argv); });
}

}  // namespace distile::cli
