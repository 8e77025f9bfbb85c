/// @file
/// The one way distile writes output files: into a temporary file beside the target, renamed
/// over the target only once the write succeeded. A failed run never leaves a half-written file
/// where a good one was, and a command with several outputs writes all of them or none. A run
/// killed before it could remove its temporaries (".NAME.partial-PID-N.EXT") leaves them; the
/// next write of the same target removes those of processes that no longer exist.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace distile {

/// Calls `write` with a temporary path in the target's folder that keeps the target's extension
/// (so writers that choose the format by extension, like OpenImageIO, still work), then renames
/// it to `target`. If `write` throws, the temporary file is removed and the exception propagates.
/// Throws InputError if the target's folder does not exist.
void writeAtomically(const std::filesystem::path& target,
                     const std::function<void(const std::filesystem::path& temporary)>& write);

/// The output files of one command, written all or none. add() checks a target before any work
/// (not a folder, its folder exists and takes a new file) by creating an empty temporary file
/// beside it; the command writes the temporaries; commit() renames each over its target.
/// Destroyed before commit() (an error on the way), it removes its temporaries, so a failed
/// command leaves no output behind.
class OutputFiles {
  public:
    OutputFiles() = default;
    OutputFiles(const OutputFiles&) = delete;
    OutputFiles& operator=(const OutputFiles&) = delete;
    ~OutputFiles();

    /// Reserves `target` and returns the temporary path to write it to (same folder, same
    /// extension). Throws InputError naming `shownAs` (the flag or field that named it) if
    /// `target` is a folder, was added already, or its folder does not exist or refuses a new
    /// file.
    std::filesystem::path add(const std::filesystem::path& target, const std::string& shownAs);

    /// Renames every temporary file over its target, in the order they were added. Throws
    /// std::filesystem::filesystem_error if a rename fails (the others are then removed).
    void commit();

  private:
    /// (temporary, target) pairs not yet renamed.
    std::vector<std::pair<std::filesystem::path, std::filesystem::path>> files_;
};

}  // namespace distile
