/// @file
/// The one way distile writes an output file: into a temporary file beside the target, renamed
/// over the target only once the write succeeded. A failed run never leaves a half-written file
/// where a good one was.
#pragma once

#include <filesystem>
#include <functional>

namespace distile {

/// Calls `write` with a temporary path in the target's folder that keeps the target's extension
/// (so writers that choose the format by extension, like OpenImageIO, still work), then renames
/// it to `target`. If `write` throws, the temporary file is removed and the exception propagates.
/// Throws InputError if the target's folder does not exist.
void writeAtomically(const std::filesystem::path& target,
                     const std::function<void(const std::filesystem::path& temporary)>& write);

}  // namespace distile
