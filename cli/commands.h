/// @file
/// The subcommands of `distile`. Each adds itself to the app; its callback runs the command when
/// it was given, and throws InputError/FormatError for bad input (main turns those into one line
/// on stderr and exit status 2).
#pragma once

#include <CLI/CLI.hpp>

namespace distile::cli {

void addBakeCommand(CLI::App& app);
void addRenderCommand(CLI::App& app);
void addCheckCommand(CLI::App& app);
void addCompareCommand(CLI::App& app);
void addBenchCommand(CLI::App& app);

}  // namespace distile::cli
