// The `distile` command. Thin: parses the command line, fills the libraries' option structs,
// calls them, reports. Errors become one line on stderr and a non-zero exit status.
#include <cstdio>
#include <cstdlib>

#include "cli/app.h"
#include "cli/commands.h"

int main(int argc, char** argv) {
    const int status = distile::cli::runCommandLine(argc, argv, [argv](CLI::App& app) {
        distile::cli::addBakeCommand(app);
        distile::cli::addRenderCommand(app);
        distile::cli::addCheckCommand(app);
        distile::cli::addCompareCommand(app);
        distile::cli::addViewCommands(app);
        distile::cli::addBenchLauncher(app, argv);
    });
#ifdef DISTILE_SANITIZE
    return status;  // the leak check runs at a normal exit
#else
    // Every command has written, closed and renamed its files and freed what it held by now; what
    // a normal exit would still do is join idle worker threads and run the static destructors of
    // OpenImageIO's ~260 libraries: 15-30 ms after `distile render` wrote its image, for nothing.
    std::fflush(nullptr);
    std::_Exit(status);
#endif
}
