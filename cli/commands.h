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
/// `view` (a web page of the tile) and `preview` (a contact sheet of its slices).
void addViewCommands(CLI::App& app);
/// The benchmarks (bench/bench_command.cpp), in distile-bench.
void addBenchCommand(CLI::App& app);
/// `bench` in the `distile` command: runs distile-bench with `argv` (cli/bench_launcher.cpp), or
/// throws InputError when it was not built.
void addBenchLauncher(CLI::App& app, char** argv);

}  // namespace distile::cli
