#include "common/atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <system_error>

#include "common/error.h"

namespace distile {

namespace fs = std::filesystem;

namespace {

fs::path folderOf(const fs::path& target) {
    return target.has_parent_path() ? target.parent_path() : fs::path(".");
}

/// A name beside `target` no other write of this process or another uses, with its extension.
fs::path temporaryBeside(const fs::path& target) {
    static std::atomic<int> counter{0};
    return folderOf(target) /
           ("." + target.stem().string() + ".partial-" + std::to_string(::getpid()) + "-" +
            std::to_string(counter++) + target.extension().string());
}

/// Removes the temporaries of `target` that killed runs left behind: ".STEM.partial-PID-N.EXT"
/// files whose process PID no longer exists (a live run's temporaries, ours included, stay). A
/// killed run cannot clean up after itself, so the next write of the same target does.
void removeStaleTemporaries(const fs::path& target) {
    const std::string prefix = "." + target.stem().string() + ".partial-";
    const std::string extension = target.extension().string();
    const auto digits = [](const std::string& text) {
        return !text.empty() && text.size() <= 9 &&
               text.find_first_not_of("0123456789") == std::string::npos;
    };
    std::error_code status;
    for (auto entry = fs::directory_iterator(folderOf(target), status);
         !status && entry != fs::directory_iterator(); entry.increment(status)) {
        const std::string name = entry->path().filename().string();
        if (name.size() <= prefix.size() + extension.size() || !name.starts_with(prefix) ||
            !name.ends_with(extension))
            continue;
        const std::string middle =
            name.substr(prefix.size(), name.size() - prefix.size() - extension.size());
        const std::size_t dash = middle.find('-');
        if (dash == std::string::npos || !digits(middle.substr(0, dash)) ||
            !digits(middle.substr(dash + 1)))
            continue;
        const auto pid = ::pid_t(std::stol(middle.substr(0, dash)));
        if (pid <= 0 || pid == ::getpid() || ::kill(pid, 0) == 0 || errno != ESRCH) continue;
        std::error_code ignored;
        fs::remove(entry->path(), ignored);
    }
}

}  // namespace

void writeAtomically(const fs::path& target, const std::function<void(const fs::path&)>& write) {
    const fs::path folder = folderOf(target);
    if (!fs::is_directory(folder)) {
        throw InputError(target.string() + ": folder '" + folder.string() + "' does not exist");
    }
    removeStaleTemporaries(target);
    const fs::path temporary = temporaryBeside(target);
    try {
        write(temporary);
        fs::rename(temporary, target);
    } catch (...) {
        std::error_code ignored;
        fs::remove(temporary, ignored);
        throw;
    }
}

OutputFiles::~OutputFiles() {
    for (const auto& [temporary, target] : files_) {
        std::error_code ignored;
        fs::remove(temporary, ignored);
    }
}

fs::path OutputFiles::add(const fs::path& target, const std::string& shownAs) {
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
    for (const auto& [temporary, added] : files_) {
        if (fs::absolute(added).lexically_normal() == fs::absolute(target).lexically_normal())
            throw InputError(name + " is also another output of this command; give each its own");
    }
    removeStaleTemporaries(target);
    const fs::path temporary = temporaryBeside(target);
    const int descriptor = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0666);
    if (descriptor < 0) {
        throw InputError(name + " cannot be written: folder '" + folder.string() +
                         "' refuses a new file (" + std::strerror(errno) + ")");
    }
    ::close(descriptor);
    files_.emplace_back(temporary, target);
    return temporary;
}

void OutputFiles::commit() {
    while (!files_.empty()) {
        const auto& [temporary, target] = files_.front();
        fs::rename(temporary, target);
        files_.erase(files_.begin());
    }
}

}  // namespace distile
