/// @file
/// Checks shared by the commands, run before any work so a bad argument costs nothing and
/// leaves nothing behind.
#pragma once

#include <filesystem>
#include <initializer_list>
#include <string>

#include "common/size3.h"

namespace distile::cli {

/// "WxHxD" to a validated Size3; InputError naming `option` otherwise.
Size3 parseSize(const std::string& text, const std::string& option);

/// Throws InputError unless `path` has one of `extensions` (case-insensitive) and its folder
/// exists.
void requireOutput(const std::filesystem::path& path, const std::string& option,
                   std::initializer_list<const char*> extensions);

/// Lower-case extension with the dot, e.g. ".exr".
std::string lowerExtension(const std::filesystem::path& path);

}  // namespace distile::cli
