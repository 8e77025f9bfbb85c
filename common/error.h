/// @file
/// The two exception types every distile entry point throws. Messages name the file or field,
/// the bad value and what is accepted, in one line, so the command can print them as they are.
#pragma once

#include <stdexcept>
#include <string>

namespace distile {

/// A value the caller passed (a size, a parameter, a path, a scene field) is not acceptable.
struct InputError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// A file exists but its contents are not what distile reads (truncated, corrupted, wrong kind).
struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

}  // namespace distile
