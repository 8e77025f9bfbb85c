#include "common/atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <span>
#include <string_view>
#include <system_error>

#include "common/error.h"
#include "common/fnv1a.h"
#include "common/input_file.h"

namespace distile {

namespace fs = std::filesystem;

const std::string& detail::temporaryScope() {
    static const std::string scope = [] {
        std::string identity;
        std::ifstream bootId("/proc/sys/kernel/random/boot_id");
        std::getline(bootId, identity);
        std::error_code error;
        identity += " " + fs::read_symlink("/proc/self/ns/pid", error).string();
        Fnv1a64 hash;
        hash.update(std::as_bytes(std::span(identity.data(), identity.size())));
        return hexDigits(hash.value()).substr(0, kScopeDigits);
    }();
    return scope;
}

namespace {

fs::path folderOf(const fs::path& target) {
    return target.has_parent_path() ? target.parent_path() : fs::path(".");
}

/// The stem that names the temporaries of `target` (".STEM.partial-SCOPE-PID-N.EXT"): its own,
/// or where such a name would not fit in a file name (255 bytes), its start (whole UTF-8
/// characters), "~" and the FNV-1a 64 of the whole stem.
std::string temporaryStem(const fs::path& target) {
    constexpr std::size_t kNameMax = 255;
    constexpr std::size_t kHashed = 1 + 16;  // "~" and the hash
    // ".", ".partial-", SCOPE, "-", PID, "-", N
    constexpr std::size_t kAround = 1 + 9 + detail::kScopeDigits + 1 + 10 + 1 + 10;
    const std::string stem = target.stem().string();
    const std::size_t extension = target.extension().string().size();
    if (kAround + extension + stem.size() <= kNameMax) return stem;
    std::size_t keep =
        kNameMax > kAround + extension + kHashed ? kNameMax - kAround - extension - kHashed : 0;
    while (keep > 0 && (static_cast<unsigned char>(stem[keep]) & 0xC0) == 0x80) --keep;
    Fnv1a64 hash;
    hash.update(std::as_bytes(std::span(stem.data(), stem.size())));
    return stem.substr(0, keep) + "~" + hexDigits(hash.value());
}

/// A name beside `target` no other write of this process or another uses, with its extension.
fs::path temporaryBeside(const fs::path& target) {
    static std::atomic<int> counter{0};
    return folderOf(target) / ("." + temporaryStem(target) + ".partial-" +
                               detail::temporaryScope() + "-" + std::to_string(::getpid()) + "-" +
                               std::to_string(counter++) + target.extension().string());
}

/// How old a temporary of another scope (another machine or PID namespace sharing the folder)
/// must be before a write of its target removes it: its process cannot be asked whether it is
/// alive, and a command reserves its outputs when it starts, so a live one may be hours old.
constexpr auto kForeignTemporaryAge = std::chrono::hours(24 * 7);

/// Removes the temporaries of `target` that killed runs left behind:
/// ".STEM.partial-SCOPE-PID-N.EXT" files of this scope whose process PID no longer exists (a live
/// run's temporaries, ours included, stay), and those of another scope unchanged for
/// kForeignTemporaryAge. A killed run cannot clean up after itself, so the next write of the same
/// target does.
void removeStaleTemporaries(const fs::path& target) {
    const std::string prefix = "." + temporaryStem(target) + ".partial-";
    const std::string extension = target.extension().string();
    const auto digits = [](std::string_view text) {
        return !text.empty() && text.size() <= 9 &&
               text.find_first_not_of("0123456789") == std::string::npos;
    };
    const std::string& scope = detail::temporaryScope();
    std::error_code status;
    for (auto entry = fs::directory_iterator(folderOf(target), status);
         !status && entry != fs::directory_iterator(); entry.increment(status)) {
        const std::string name = entry->path().filename().string();
        if (name.size() <= prefix.size() + extension.size() || !name.starts_with(prefix) ||
            !name.ends_with(extension))
            continue;
        // SCOPE-PID-N
        const std::string_view middle = std::string_view(name).substr(
            prefix.size(), name.size() - prefix.size() - extension.size());
        const std::size_t first = middle.find('-');
        const std::size_t second =
            first == std::string_view::npos ? first : middle.find('-', first + 1);
        if (second == std::string_view::npos || first != detail::kScopeDigits ||
            middle.substr(0, first).find_first_not_of("0123456789abcdef") !=
                std::string_view::npos ||
            !digits(middle.substr(first + 1, second - first - 1)) ||
            !digits(middle.substr(second + 1)))
            continue;
        if (middle.substr(0, first) == scope) {
            const auto pid = ::pid_t(std::stol(std::string(middle.substr(first + 1))));
            if (pid <= 0 || pid == ::getpid() || ::kill(pid, 0) == 0 || errno != ESRCH) continue;
        } else {
            std::error_code timeError;
            const auto written = fs::last_write_time(entry->path(), timeError);
            if (timeError || fs::file_time_type::clock::now() - written < kForeignTemporaryAge)
                continue;
        }
        std::error_code ignored;
        fs::remove(entry->path(), ignored);
    }
}

/// The temporary files a signal removes (removeTemporariesOnSignal): fixed slots, so the handler
/// reads them without allocating or locking. A slot is free (0), being filled (1) or holds the
/// absolute path of a temporary (2).
struct TemporarySlot {
    std::atomic<int> state{0};
    char path[4096];
};
constexpr int kTemporarySlots = 64;
TemporarySlot temporarySlots[kTemporarySlots];
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler reads the slots");

/// Takes a slot for `temporary`; -1 when none is free or the path does not fit (the file is then
/// left as a killed run's would be).
int registerTemporary(const fs::path& temporary) {
    std::error_code error;
    const std::string path = fs::absolute(temporary, error).string();
    if (error || path.size() >= sizeof(TemporarySlot::path)) return -1;
    for (int slot = 0; slot < kTemporarySlots; ++slot) {
        int free = 0;
        if (!temporarySlots[slot].state.compare_exchange_strong(free, 1)) continue;
        std::memcpy(temporarySlots[slot].path, path.c_str(), path.size() + 1);
        temporarySlots[slot].state.store(2, std::memory_order_release);
        return slot;
    }
    return -1;
}

/// Frees `slot` (after its temporary was renamed or removed).
void releaseTemporary(int slot) {
    if (slot >= 0) temporarySlots[slot].state.store(0, std::memory_order_release);
}

extern "C" void removeTemporariesThenDie(int signal) {
    for (TemporarySlot& slot : temporarySlots) {
        if (slot.state.load(std::memory_order_acquire) == 2) ::unlink(slot.path);
    }
    // The handler was installed with SA_RESETHAND: the signal, raised again, ends the process as
    // it would have without the handler once the handler returns.
    ::raise(signal);
}

/// The targets of OutputFiles' temporaries, by the temporary's absolute path: what a write into
/// one is shown as.
std::mutex outputTargetsMutex;
std::map<fs::path, fs::path> outputTargets;

fs::path absoluteNormal(const fs::path& path) {
    std::error_code ignored;
    return fs::absolute(path, ignored).lexically_normal();
}

/// The target of `file` when it is a temporary of OutputFiles; nothing otherwise.
std::optional<fs::path> outputTargetOf(const fs::path& file) {
    const std::lock_guard lock(outputTargetsMutex);
    const auto found = outputTargets.find(absoluteNormal(file));
    if (found == outputTargets.end()) return std::nullopt;
    return found->second;
}

/// `error`, thrown by a writer of `temporary`, as the WriteError of `target`: every mention of
/// the temporary's name (it lies in the target's folder) reads as the target's.
WriteError writeErrorOf(const std::exception& error, const fs::path& temporary,
                        const fs::path& target) {
    std::string message = error.what();
    const auto replaceAll = [&](const std::string& from, const std::string& to) {
        for (std::size_t at = message.find(from); !from.empty() && at != std::string::npos;
             at = message.find(from, at + to.size()))
            message.replace(at, from.size(), to);
    };
    replaceAll(temporary.string(), target.string());
    replaceAll(temporary.filename().string(), target.filename().string());
    if (message.find(target.filename().string()) == std::string::npos)
        message = target.string() + ": " + message;
    return WriteError(message);
}

/// InputError unless `target` may be written: not a folder, its folder exists, not an input.
void requireWritableTarget(const fs::path& target, const std::string& shownAs) {
    const std::string name = shownAs + ": '" + target.string() + "'";
    std::error_code status;
    if (fs::is_directory(target, status)) {
        throw InputError(name + " is a folder; give a file name to write");
    }
    const fs::path folder = folderOf(target);
    if (!fs::is_directory(folder, status)) {
        throw InputError(name + " cannot be written: folder '" + folder.string() +
                         "' does not exist");
    }
    if (const std::string kind = recordedInputKind(target); !kind.empty()) {
        throw InputError(name + " is also an input of this command (read as " + kind +
                         "); give the output another name");
    }
}

}  // namespace

void removeTemporariesOnSignal() {
    static std::once_flag installed;
    std::call_once(installed, [] {
        for (const int signal :
             {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGALRM, SIGUSR1, SIGUSR2, SIGXCPU}) {
            struct sigaction previous {};
            if (::sigaction(signal, nullptr, &previous) != 0 || previous.sa_handler == SIG_IGN)
                continue;  // e.g. nohup: stay immune
            struct sigaction action {};
            action.sa_handler = removeTemporariesThenDie;
            sigemptyset(&action.sa_mask);
            action.sa_flags = SA_RESETHAND;
            ::sigaction(signal, &action, nullptr);
        }
        ::signal(SIGPIPE, SIG_IGN);
        ::signal(SIGXFSZ, SIG_IGN);
    });
}

void writeAtomically(const fs::path& target, const std::function<void(const fs::path&)>& write) {
    const fs::path folder = folderOf(target);
    if (!fs::is_directory(folder)) {
        throw InputError(target.string() + ": folder '" + folder.string() + "' does not exist");
    }
    // Already a temporary, renamed by its OutputFiles: written as it is.
    if (const std::optional<fs::path> shownAs = outputTargetOf(target)) {
        try {
            write(target);
        } catch (const InputError&) {
            throw;
        } catch (const FormatError&) {
            throw;
        } catch (const std::runtime_error& error) {
            throw writeErrorOf(error, target, *shownAs);
        }
        return;
    }
    removeStaleTemporaries(target);
    const fs::path temporary = temporaryBeside(target);
    const int slot = registerTemporary(temporary);
    const auto removeTemporary = [&] {
        std::error_code ignored;
        fs::remove(temporary, ignored);
        releaseTemporary(slot);
    };
    try {
        write(temporary);
        fs::rename(temporary, target);
    } catch (const InputError&) {
        removeTemporary();
        throw;
    } catch (const FormatError&) {
        removeTemporary();
        throw;
    } catch (const std::runtime_error& error) {
        removeTemporary();
        throw writeErrorOf(error, temporary, target);
    } catch (...) {
        removeTemporary();
        throw;
    }
    releaseTemporary(slot);
}

OutputFiles::~OutputFiles() {
    for (const File& file : files_) {
        std::error_code ignored;
        fs::remove(file.temporary, ignored);
        releaseTemporary(file.signalSlot);
        forget(file);
    }
}

void OutputFiles::forget(const File& file) {
    const std::lock_guard lock(outputTargetsMutex);
    outputTargets.erase(absoluteNormal(file.temporary));
}

fs::path OutputFiles::add(const fs::path& target, const std::string& shownAs) {
    requireWritableTarget(target, shownAs);
    const std::string name = shownAs + ": '" + target.string() + "'";
    for (const File& added : files_) {
        if (fs::absolute(added.target).lexically_normal() ==
            fs::absolute(target).lexically_normal())
            throw InputError(name + " is also another output of this command; give each its own");
    }
    removeStaleTemporaries(target);
    const fs::path temporary = temporaryBeside(target);
    const int slot = registerTemporary(temporary);
    const int descriptor = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0666);
    if (descriptor < 0) {
        const int openError = errno;
        releaseTemporary(slot);
        throw InputError(name + " cannot be written: folder '" + folderOf(target).string() +
                         "' refuses a new file (" + std::strerror(openError) + ")");
    }
    ::close(descriptor);
    files_.push_back({temporary, target, shownAs, slot});
    const std::lock_guard lock(outputTargetsMutex);
    outputTargets[absoluteNormal(temporary)] = target;
    return temporary;
}

void OutputFiles::commit() {
    // All or none: every target is checked before the first rename, and a target that exists is
    // linked to a backup beside it before it is replaced, so that should a later rename fail (a
    // file another user owns in a sticky folder, an immutable one), the targets replaced so far
    // get their old files back and the new ones go.
    for (const File& file : files_) requireWritableTarget(file.target, file.shownAs);
    struct Replaced {
        fs::path target;
        bool existed = false;  ///< the target was there before
        fs::path backup;       ///< empty: none (the target was new, or cannot be linked)
        int backupSlot = -1;
    };
    std::vector<Replaced> replaced;
    const auto dropBackup = [](const Replaced& entry) {
        std::error_code ignored;
        if (!entry.backup.empty()) fs::remove(entry.backup, ignored);
        releaseTemporary(entry.backupSlot);
    };
    for (const File& file : files_) {
        Replaced entry;
        entry.target = file.target;
        std::error_code status;
        entry.existed = fs::exists(fs::symlink_status(file.target, status));
        if (entry.existed) {
            const fs::path backup = temporaryBeside(file.target);
            entry.backupSlot = registerTemporary(backup);
            if (::link(file.target.c_str(), backup.c_str()) == 0) entry.backup = backup;
        }
        if (::rename(file.temporary.c_str(), file.target.c_str()) != 0) {
            const int renameError = errno;
            // Undone: a new target removed, a replaced one put back from its backup; one that
            // was replaced without a backup (a file system without hard links, a file another
            // user owns) keeps its new content.
            std::string kept;
            for (auto undo = replaced.rbegin(); undo != replaced.rend(); ++undo) {
                std::error_code ignored;
                if (!undo->backup.empty())
                    fs::rename(undo->backup, undo->target, ignored);
                else if (!undo->existed)
                    fs::remove(undo->target, ignored);
                else
                    kept += (kept.empty() ? "" : ", ") + undo->target.string();
                dropBackup(*undo);
            }
            dropBackup(entry);
            throw WriteError(file.shownAs + ": '" + file.target.string() +
                             "' cannot be replaced (" + std::strerror(renameError) + "); " +
                             (kept.empty() ? std::string("nothing was written")
                                           : "already replaced, and not put back: " + kept));
        }
        replaced.push_back(entry);
    }
    for (const Replaced& entry : replaced) dropBackup(entry);
    for (const File& file : files_) {
        releaseTemporary(file.signalSlot);
        forget(file);
    }
    files_.clear();
}

}  // namespace distile
