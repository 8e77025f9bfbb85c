#include "cli/app.h"

#include <tbb/global_control.h>

#include <cstdio>
#include <memory>

#include "common/error.h"

namespace distile::cli {

namespace {

int parseAndRun(int argc, char** argv, const std::function<void(CLI::App&)>& addCommands) {
    CLI::App app{
        "distile: volumetric distance detail. Bakes detail (chain mail, ...) into exact, periodic "
        "distance tiles\n"
        "(OpenVDB level set -> 256x256x16 EXR atlas) and renders them on base meshes with a CPU "
        "sphere tracer.\n"};
    app.name("distile");
    app.footer(kExitStatusHelp);
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
    addCommands(app);
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

int runCommandLine(int argc, char** argv, const std::function<void(CLI::App&)>& addCommands) {
    try {
        return parseAndRun(argc, argv, addCommands);
    } catch (const InputError& error) {
        std::fprintf(stderr, "distile: error: %s\n", error.what());
        return kExitInput;
    } catch (const FormatError& error) {
        std::fprintf(stderr, "distile: error: %s\n", error.what());
        return kExitInput;
    } catch (const std::exception& error) {
        std::fprintf(stderr, "distile: error: %s\n", error.what());
        return kExitFailure;
    }
}

}  // namespace distile::cli
