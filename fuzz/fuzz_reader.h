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

#include "common/error.h"

namespace distile::fuzz {

/// Writes `data` to one file per process named `name` (extension included) in the temporary
/// folder, then calls `read(path)`.
template <class Read>
int readAsFile(const std::uint8_t* data, std::size_t size, const std::string& name, Read read) {
    static const std::filesystem::path file =
        std::filesystem::temp_directory_path() /
        ("distile_fuzz_" + std::to_string(::getpid()) + "_" + name);
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
