/// @file
/// The frame of distile's programs, the `distile` command and distile-bench (bench/): --threads,
/// --version, one subcommand, and bad input as one line on stderr with exit status 2.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

namespace distile::cli {

constexpr int kExitFailure = 1;  ///< an internal failure (a bug, or the system)
constexpr int kExitInput = 2;    ///< bad input: arguments, files, scenes

/// Parses `argv` with the subcommands `addCommands` adds to the app and runs the one given.
/// Returns the exit status: 0, kExitInput for bad input (InputError, FormatError, a command line
/// CLI11 rejects), kExitFailure for any other exception; a command may also exit by itself.
int runCommandLine(int argc, char** argv, const std::function<void(CLI::App&)>& addCommands);

}  // namespace distile::cli
