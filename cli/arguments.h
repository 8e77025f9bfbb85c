/// @file
/// Checks shared by the commands, run before any work so a bad argument costs nothing and
/// leaves nothing behind.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>

#include "common/error.h"
#include "common/size3.h"

namespace distile::cli {

/// "WxHxD" to a validated Size3; InputError naming `option` otherwise.
Size3 parseSize(const std::string& text, const std::string& option);

/// Throws InputError unless `path` has one of `extensions` (case-insensitive) and its folder
/// exists.
void requireOutput(const std::filesystem::path& path, const std::string& option,
                   std::initializer_list<const char*> extensions);

/// A CLI11 check that the value is a finite number in [lowest, highest]. CLI::Range alone lets NaN
/// through (every comparison with NaN is false), which would switch a tolerance off.
CLI::Validator finiteRange(double lowest, double highest);

/// A CLI11 check that the value is an integer in [lowest, highest]. CLI::Range reports "8.5" as
/// out of range when it is not an integer.
CLI::Validator integerRange(std::int64_t lowest, std::int64_t highest);

}  // namespace distile::cli
