/// @file
/// What every fuzz target does: write libFuzzer's bytes to a file with the reader's extension
/// (distile's readers take paths, as users give them) and read it. distile's refusals of bad input
/// (InputError, FormatError) are the expected outcome; anything else (a crash, a sanitizer
/// report, another exception, a hang, more than the memory limit) is a finding.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

#include "common/error.h"

namespace distile::fuzz {

/// A file of this process in the temporary folder, removed when the process exits normally (a
/// campaign's workers and CI's replays would otherwise leave one behind each).
class ProcessTempFile {
  public:
    explicit ProcessTempFile(const std::string& name)
        : path_(std::filesystem::temp_directory_path() /
                ("distile_fuzz_" + std::to_string(::getpid()) + "_" + name)) {}
    ~ProcessTempFile() {
        std::error_code ignored;
        std::filesystem::remove(path_, ignored);
    }
    ProcessTempFile(const ProcessTempFile&) = delete;
    ProcessTempFile& operator=(const ProcessTempFile&) = delete;
    const std::filesystem::path& path() const { return path_; }

  private:
    std::filesystem::path path_;
};

/// Writes `data` to one file per process named `name` (extension included) in the temporary
/// folder, then calls `read(path)`.
template <class Read>
int readAsFile(const std::uint8_t* data, std::size_t size, const std::string& name, Read read) {
    static const ProcessTempFile temp(name);
    const std::filesystem::path& file = temp.path();
    {
        std::ofstream out(file, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    }
    try {
        read(file);
    } catch (const InputError&) {
    } catch (const FormatError&) {
    }
    return 0;
}

}  // namespace distile::fuzz
