/// @file
/// Little-endian fields read from a binary file at a position, each checked against the file's
/// size before it is read: the one way the header walks (.vdb, OpenEXR) read the files they check
/// before their libraries do.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace distile {

/// Reads fields of `file` (`fileBytes` long) from byte 0 on. Every refusal is a FormatError
/// "FILE: not a readable KIND (its WHAT at byte N PROBLEM)", KIND e.g. ".vdb file".
class FieldReader {
  public:
    /// @throws InputError `file` cannot be opened.
    FieldReader(const std::filesystem::path& file, std::uint64_t fileBytes, std::string kind);

    std::uint64_t offset() const { return offset_; }
    std::uint64_t remaining() const { return fileBytes_ - offset_; }
    std::uint64_t fileBytes() const { return fileBytes_; }

    /// Moves to byte `offset` (at most the file's size).
    void seek(std::uint64_t offset, const char* what);
    /// An unsigned little-endian field of `bytes` (1 to 8) bytes.
    std::uint64_t unsignedField(int bytes, const char* what);
    /// A signed little-endian 32-bit field.
    std::int64_t int32Field(const char* what);
    /// `bytes` bytes into `to`.
    void readBytes(void* to, std::uint64_t bytes, const char* what);
    void skip(std::uint64_t bytes, const char* what);
    /// `count` items of at least `leastBytes` each must fit in the rest of the file.
    void requireCount(std::uint64_t count, std::uint64_t leastBytes, const char* what);

    /// Refuses the field read last, which `problem`s (e.g. "is 7; accepted: 0 to 6").
    [[noreturn]] void refuse(const char* what, const std::string& problem) const;
    /// Refuses the field read last as running past the end of the file.
    [[noreturn]] void fail(const char* what, const std::string& problem) const;

  private:
    void require(std::uint64_t bytes, const char* what);

    std::ifstream in_;
    std::filesystem::path file_;
    std::uint64_t fileBytes_;
    std::string kind_;
    std::uint64_t offset_ = 0;
    std::uint64_t fieldOffset_ = 0;  ///< where the last field read starts (for messages)
};

}  // namespace distile
