#include "common/input_file.h"

#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <fstream>
#include <limits>
#include <mutex>
#include <vector>

#include "common/error.h"

namespace distile {

namespace fs = std::filesystem;

namespace {

constexpr std::uint64_t kSaturated = std::numeric_limits<std::uint64_t>::max();

std::string mebibytes(std::uint64_t bytes) {
    return bytes == kSaturated ? std::string("more than 2^64 bytes")
                               : std::to_string(bytes >> 20) + " MiB";
}

/// The files requireRegularFile accepted since recordInputFiles().
struct RecordedInputs {
    struct File {
        dev_t device;
        ino_t inode;
        std::string kind;
    };
    std::atomic<bool> recording{false};
    std::mutex mutex;
    std::vector<File> files;
};

RecordedInputs& recordedInputs() {
    static RecordedInputs inputs;
    return inputs;
}

}  // namespace

void recordInputFiles() {
    RecordedInputs& inputs = recordedInputs();
    const std::lock_guard<std::mutex> lock(inputs.mutex);
    inputs.files.clear();
    inputs.recording = true;
}

std::string recordedInputKind(const fs::path& file) {
    RecordedInputs& inputs = recordedInputs();
    struct stat identity {};
    if (!inputs.recording || ::stat(file.c_str(), &identity) != 0) return {};
    const std::lock_guard<std::mutex> lock(inputs.mutex);
    for (const RecordedInputs::File& input : inputs.files) {
        if (input.device == identity.st_dev && input.inode == identity.st_ino) return input.kind;
    }
    return {};
}

std::string lowerExtension(const fs::path& file) {
    std::string extension = file.extension().string();
    for (char& c : extension) c = char(std::tolower(static_cast<unsigned char>(c)));
    return extension;
}

std::uint64_t requireRegularFile(const fs::path& file, std::string_view expected) {
    std::error_code error;
    const fs::file_status status = fs::status(file, error);
    if (!fs::exists(status)) throw InputError(file.string() + ": no such file");
    if (fs::is_directory(status)) {
        throw InputError(file.string() + ": is a folder; " + std::string(expected) +
                         " is expected");
    }
    if (!fs::is_regular_file(status)) {
        throw InputError(file.string() + ": is not a regular file (a device, pipe or socket); " +
                         std::string(expected) + " is expected");
    }
    const std::uintmax_t size = fs::file_size(file, error);
    if (error) throw InputError(file.string() + ": cannot read its size (" + error.message() + ")");
    if (RecordedInputs& inputs = recordedInputs(); inputs.recording) {
        struct stat identity {};
        if (::stat(file.c_str(), &identity) == 0) {
            const std::lock_guard<std::mutex> lock(inputs.mutex);
            inputs.files.push_back({identity.st_dev, identity.st_ino, std::string(expected)});
        }
    }
    return std::uint64_t(size);
}

std::uint64_t saturatingProduct(std::uint64_t a, std::uint64_t b) {
    std::uint64_t product = 0;
    return __builtin_mul_overflow(a, b, &product) ? kSaturated : product;
}

std::uint64_t saturatingSum(std::uint64_t a, std::uint64_t b) {
    std::uint64_t sum = 0;
    return __builtin_add_overflow(a, b, &sum) ? kSaturated : sum;
}

void requireDeclaredCount(const fs::path& file, std::string_view what, std::uint64_t count,
                          std::uint64_t fileBytesEach, std::uint64_t fileBytes,
                          std::uint64_t memoryBytesEach) {
    const std::uint64_t needed = saturatingProduct(count, fileBytesEach);
    if (needed > fileBytes) {
        throw FormatError(file.string() + ": " + std::string(what) + " declares " +
                          std::to_string(count) + " items, at least " +
                          (needed == kSaturated ? std::string("2^64") : std::to_string(needed)) +
                          " bytes, but only " + std::to_string(fileBytes) +
                          " are there; the file is truncated or corrupted");
    }
    requireWithinMemoryBudget(file, std::string(what) + " of " + std::to_string(count) + " items",
                              saturatingProduct(count, memoryBytesEach));
}

void requireWithinMemoryBudget(const fs::path& file, std::string_view what, std::uint64_t bytes) {
    if (bytes > kInputMemoryBudgetBytes) {
        throw FormatError(file.string() + ": " + std::string(what) + " would take " +
                          mebibytes(bytes) + " of memory; at most " +
                          mebibytes(kInputMemoryBudgetBytes) + " per input file is accepted");
    }
}

namespace {

/// CRC-32 (ISO 3309, as PNG uses it) of `bytes`, continuing from `crc`.
std::uint32_t crc32(std::uint32_t crc, const unsigned char* bytes, std::size_t count) {
    static const std::array<std::uint32_t, 256> table = [] {
        std::array<std::uint32_t, 256> entries{};
        for (std::uint32_t n = 0; n < 256; ++n) {
            std::uint32_t c = n;
            for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
            entries[n] = c;
        }
        return entries;
    }();
    crc = ~crc;
    for (std::size_t i = 0; i < count; ++i) crc = table[(crc ^ bytes[i]) & 0xffu] ^ (crc >> 8);
    return ~crc;
}

}  // namespace

bool startsAsPng(const fs::path& file) {
    constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    std::ifstream in(file, std::ios::binary);
    unsigned char header[8] = {};
    in.read(reinterpret_cast<char*>(header), 8);
    return in.gcount() == 8 && std::equal(header, header + 8, kSignature);
}

void checkPngChunks(const fs::path& file) {
    if (!startsAsPng(file)) return;
    std::ifstream in(file, std::ios::binary);
    in.seekg(8);
    const std::uint64_t fileBytes = fs::file_size(file);
    const std::string name = file.string();
    std::uint64_t offset = 8;
    std::vector<unsigned char> buffer;
    bool imageData = false;
    for (;;) {
        unsigned char lengthAndType[8] = {};
        in.read(reinterpret_cast<char*>(lengthAndType), 8);
        if (in.gcount() != 8) {
            throw FormatError(name + ": broken PNG (it ends at byte " + std::to_string(offset) +
                              " without an IEND chunk; the file is truncated)");
        }
        const std::uint64_t length = std::uint64_t(lengthAndType[0]) << 24 |
                                     std::uint64_t(lengthAndType[1]) << 16 |
                                     std::uint64_t(lengthAndType[2]) << 8 | lengthAndType[3];
        const std::string type(reinterpret_cast<const char*>(lengthAndType + 4), 4);
        const bool letters = std::all_of(type.begin(), type.end(), [](char c) {
            return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z');
        });
        if (!letters) {
            throw FormatError(name + ": broken PNG (chunk type '" + quotedInput(type) +
                              "' at byte " + std::to_string(offset) +
                              " is not four letters; the file is corrupted)");
        }
        if (length + 12 > fileBytes - offset) {
            throw FormatError(name + ": broken PNG (chunk " + type + " at byte " +
                              std::to_string(offset) + " needs " + std::to_string(length) +
                              " bytes, past the end of the file; the file is truncated)");
        }
        // The CRC covers the type and the data, read in blocks (a chunk may be large).
        std::uint32_t crc = crc32(0, lengthAndType + 4, 4);
        for (std::uint64_t left = length; left > 0;) {
            const std::size_t block = std::size_t(std::min<std::uint64_t>(left, 1 << 16));
            buffer.resize(block);
            in.read(reinterpret_cast<char*>(buffer.data()), std::streamsize(block));
            crc = crc32(crc, buffer.data(), block);
            left -= block;
        }
        unsigned char stored[4] = {};
        in.read(reinterpret_cast<char*>(stored), 4);
        const std::uint32_t storedCrc = std::uint32_t(stored[0]) << 24 |
                                        std::uint32_t(stored[1]) << 16 |
                                        std::uint32_t(stored[2]) << 8 | stored[3];
        if (!in || crc != storedCrc) {
            throw FormatError(name + ": broken PNG (chunk " + type + " at byte " +
                              std::to_string(offset) +
                              " fails its CRC check; the file is corrupted)");
        }
        if (offset == 8 && type != "IHDR") {
            throw FormatError(name + ": broken PNG (its first chunk is " + type +
                              ", not IHDR; the file is corrupted)");
        }
        offset += length + 12;
        imageData = imageData || type == "IDAT";
        if (type == "IEND") {
            if (!imageData) throw FormatError(name + ": broken PNG (it has no IDAT chunk)");
            return;
        }
    }
}

std::string quotedInput(std::string_view bytes, std::size_t maxCharacters) {
    std::string quoted;
    for (std::size_t i = 0; i < bytes.size() && i < maxCharacters; ++i) {
        const unsigned char c = static_cast<unsigned char>(bytes[i]);
        quoted += c >= 0x20 && c < 0x7f ? char(c) : '?';
    }
    if (bytes.size() > maxCharacters) quoted += "...";
    return quoted;
}

}  // namespace distile
