// distile-bench: the `distile bench` command in a program of its own, so that the `distile`
// command does not link the peers (Embree, vdb_render) and the stress cases. `distile bench ...`
// runs it with the same arguments (cli/bench_launcher.cpp); it can also be run directly, as
// `distile-bench bench ...`.
#include "cli/app.h"
#include "cli/commands.h"

int main(int argc, char** argv) {
    return distile::cli::runCommandLine(argc, argv,
                                        [](CLI::App& app) { distile::cli::addBenchCommand(app); });
}
