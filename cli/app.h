/// @file
/// The frame of distile's programs, the `distile` command and distile-bench (bench/): --threads,
/// --version, one subcommand, and bad input as one line on stderr with exit status 2.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

namespace distile::cli {

/// Exit statuses, one meaning each (`distile --help` says them): 0 success; 1 the work itself
/// failed (a check beyond its tolerances, a failed benchmark case, a system error or a bug); 2
/// refused input (a bad option, file, scene or mesh, before anything is written).
constexpr int kExitFailure = 1;  ///< the work failed
constexpr int kExitInput = 2;    ///< refused input: arguments, files, scenes, meshes
/// The exit statuses as `--help` shows them.
inline constexpr const char* kExitStatusHelp =
    "Exit status: 0 success; 1 the work failed (a check beyond its tolerances, a failed benchmark "
    "case, a system error); 2 refused input (a bad option, file, scene or mesh; nothing written).";

/// Parses `argv` with the subcommands `addCommands` adds to the app and runs the one given.
/// Returns the exit status: 0, kExitInput for bad input (InputError, FormatError, a command line
/// CLI11 rejects), kExitFailure for any other exception; a command may also exit by itself.
int runCommandLine(int argc, char** argv, const std::function<void(CLI::App&)>& addCommands);

}  // namespace distile::cli
