// The `distile` command. Thin: parses the command line, fills the libraries' option structs,
// calls them, reports. Errors become one line on stderr and a non-zero exit status.
#include "cli/app.h"
#include "cli/commands.h"

int main(int argc, char** argv) {
    return distile::cli::runCommandLine(argc, argv, [argv](CLI::App& app) {
        distile::cli::addBakeCommand(app);
        distile::cli::addRenderCommand(app);
        distile::cli::addCheckCommand(app);
        distile::cli::addCompareCommand(app);
        distile::cli::addViewCommands(app);
        distile::cli::addBenchLauncher(app, argv);
    });
}
