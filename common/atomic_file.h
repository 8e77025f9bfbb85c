/// @file
/// The one way distile writes output files: into a temporary file beside the target, renamed
/// over the target only once the write succeeded. A failed run never leaves a half-written file
/// where a good one was, and a command with several outputs writes all of them or none. A run
/// interrupted by a signal removes its temporaries (".NAME.partial-SCOPE-PID-N.EXT") if the
/// program asked for it (removeTemporariesOnSignal); one killed outright leaves them, and the
/// next write of the same target removes those of processes that no longer exist (those of
/// another machine or PID namespace once a week old: detail::temporaryScope).
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace distile {

namespace detail {
/// Hex digits of temporaryScope().
inline constexpr std::size_t kScopeDigits = 8;
/// Where the PIDs in temporary names mean processes: kScopeDigits hex digits of a hash of this
/// boot of the machine and this process's PID namespace. Containers sharing a folder (a bake
/// cache on a volume) each have their own process 7: their temporaries have different names,
/// and a run neither takes another scope's live temporary for a dead one nor writes into it.
const std::string& temporaryScope();
}  // namespace detail

/// From now on, the signals that end a process by default (SIGINT, SIGTERM, SIGHUP, SIGQUIT,
/// SIGALRM, SIGUSR1, SIGUSR2, SIGXCPU; those not ignored) remove the temporary files being written
/// before the process ends as the signal would have ended it, and SIGPIPE and SIGXFSZ are
/// ignored, so a closed pipe or a file size limit fails the write (EPIPE, EFBIG) instead of
/// ending the process. For programs (the command line); a library leaves a host's signals alone.
void removeTemporariesOnSignal();

/// Calls `write` with a temporary path in the target's folder that keeps the target's extension
/// (so writers that choose the format by extension, like OpenImageIO, still work), then renames
/// it to `target`. A `target` that is itself a temporary of OutputFiles is written directly (its
/// OutputFiles renames it). If `write` throws, the temporary file is removed and the exception
/// propagates, except that a writer's failure (any std::runtime_error but InputError and
/// FormatError: a full disk, an I/O error) becomes a WriteError naming the file the user gave.
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
    /// `target` is a folder, was added already, is one of the command's inputs (recordInputFiles
    /// in common/input_file.h), or its folder does not exist or refuses a new file.
    std::filesystem::path add(const std::filesystem::path& target, const std::string& shownAs);

    /// Renames every temporary file over its target, in the order they were added, once every
    /// target has been checked again as add() checks it (an input read since, a folder made
    /// since: InputError, nothing renamed). Throws std::filesystem::filesystem_error if a rename
    /// still fails (the temporaries not yet renamed are then removed).
    void commit();

  private:
    struct File {
        std::filesystem::path temporary;
        std::filesystem::path target;
        std::string shownAs;
        int signalSlot;  ///< its entry among the temporaries a signal removes (-1: none)
    };
    /// No longer shows writes into file.temporary as writes of its target (writeAtomically).
    static void forget(const File& file);
    /// Files not yet renamed.
    std::vector<File> files_;
};

}  // namespace distile
