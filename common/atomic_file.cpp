#include "common/atomic_file.h"

#include <unistd.h>

#include <atomic>
#include <system_error>

#include "common/error.h"

namespace distile {

namespace fs = std::filesystem;

void writeAtomically(const fs::path& target, const std::function<void(const fs::path&)>& write) {
    const fs::path folder = target.has_parent_path() ? target.parent_path() : fs::path(".");
    if (!fs::is_directory(folder)) {
        throw InputError(target.string() + ": folder '" + folder.string() + "' does not exist");
    }
    static std::atomic<int> counter{0};
    const fs::path temporary =
        folder / ("." + target.stem().string() + ".partial-" + std::to_string(::getpid()) + "-" +
                  std::to_string(counter++) + target.extension().string());
    try {
        write(temporary);
        fs::rename(temporary, target);
    } catch (...) {
        std::error_code ignored;
        fs::remove(temporary, ignored);
        throw;
    }
}

}  // namespace distile
