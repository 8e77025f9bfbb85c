// The `distile` command. Thin: parses the command line, fills the libraries' option structs,
// calls them, reports. Errors become one line on stderr and a non-zero exit status.

#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>

#include "cli/commands.h"
#include "common/error.h"

namespace {

constexpr int kExitFailure = 1;  ///< an internal failure (a bug, or the system)
constexpr int kExitInput = 2;    ///< bad input: arguments, files, scenes

int run(int argc, char** argv) {
    CLI::App app{
        "distile: volumetric distance detail. Bakes detail (chain mail, ...) into exact, periodic "
        "distance tiles\n"
        "(OpenVDB level set -> 256x256x16 EXR atlas) and renders them on base meshes with a CPU "
        "sphere tracer.\n"};
    app.name("distile");
    app.require_subcommand(1);
    app.fallthrough();  // --threads may also follow the subcommand
    app.set_version_flag("--version", "distile 0.1.0");
    int threads = 0;
    app.add_option("--threads", threads, "Worker threads (default: all cores)")
        ->check(CLI::Range(1, 1024));
    // The thread limit must be in force before a command's callback runs.
    std::unique_ptr<tbb::global_control> threadLimit;
    app.parse_complete_callback([&] {
        if (threads > 0) {
            threadLimit = std::make_unique<tbb::global_control>(
                tbb::global_control::max_allowed_parallelism, std::size_t(threads));
        }
    });
    distile::cli::addBakeCommand(app);
    distile::cli::addRenderCommand(app);
    distile::cli::addCheckCommand(app);
    distile::cli::addCompareCommand(app);
    distile::cli::addBenchCommand(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::Success& success) {  // --help, --version
        return app.exit(success);
    } catch (const CLI::ParseError& error) {
        std::fprintf(stderr, "distile: error: %s (see distile --help)\n", error.what());
        return kExitInput;
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const distile::InputError& error) {
        std::fprintf(stderr, "distile: error: %s\n", error.what());
        return kExitInput;
    } catch (const distile::FormatError& error) {
        std::fprintf(stderr, "distile: error: %s\n", error.what());
        return kExitInput;
    } catch (const std::exception& error) {
        std::fprintf(stderr, "distile: error: %s\n", error.what());
        return kExitFailure;
    }
}
