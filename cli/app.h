/// @file
/// The frame of distile's programs, the `distile` command and distile-bench (bench/): --threads,
/// --version, one subcommand, and bad input as one line on stderr with exit status 2.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

namespace distile::cli {

/// Exit statuses, one meaning each (`distile --help` and docs/pipeline.md say them): 0 success;
/// 1 the work was done and failed its own test (a check beyond its tolerances, a failed benchmark
/// case); 2 refused input (a bad option, file, scene or mesh, an output that cannot be written,
/// input that needs more memory than there is; nothing is written); 3 an internal failure, a bug
/// in distile (InternalError or an exception nobody expected).
constexpr int kExitFailure = 1;  ///< the work failed its test
constexpr int kExitInput = 2;    ///< refused input: arguments, files, scenes, meshes, outputs
constexpr int kExitBug = 3;      ///< an internal failure: a bug
/// The exit statuses as `--help` shows them.
inline constexpr const char* kExitStatusHelp =
    "Exit status: 0 success; 1 a check or benchmark case beyond its tolerances; 2 refused input "
    "(a bad option, file, scene or mesh, an output that cannot be written, input needing more "
    "memory than there is; nothing written); 3 an internal failure (a bug in distile).";

/// Parses `argv` with the subcommands `addCommands` adds to the app and runs the one given.
/// Returns the exit status: 0; kExitInput for bad input (InputError, FormatError, a command line
/// CLI11 rejects), for an output that cannot be written (std::system_error) and for
/// std::bad_alloc; kExitBug for InternalError and any other exception. A command may also exit
/// by itself (kExitFailure). Every error is one line on stderr.
int runCommandLine(int argc, char** argv, const std::function<void(CLI::App&)>& addCommands);

}  // namespace distile::cli
