#include "common/field_reader.h"

#include "common/error.h"
#include "common/input_file.h"

namespace distile {

FieldReader::FieldReader(const std::filesystem::path& file, std::uint64_t fileBytes,
                         std::string kind)
    : in_(file, std::ios::binary), file_(file), fileBytes_(fileBytes), kind_(std::move(kind)) {
    if (!in_) throw InputError(file.string() + ": cannot open for reading");
}

void FieldReader::seek(std::uint64_t offset, const char* what) {
    if (offset > fileBytes_) fail(what, "points to byte " + std::to_string(offset));
    in_.clear();
    in_.seekg(std::streamoff(offset));
    offset_ = offset;
}

std::uint64_t FieldReader::unsignedField(int bytes, const char* what) {
    unsigned char data[8] = {};
    readBytes(data, std::uint64_t(bytes), what);
    std::uint64_t value = 0;
    for (int k = 0; k < bytes; ++k) value |= std::uint64_t(data[k]) << (8 * k);
    return value;
}

std::int64_t FieldReader::int32Field(const char* what) {
    return std::int64_t(std::int32_t(std::uint32_t(unsignedField(4, what))));
}

void FieldReader::readBytes(void* to, std::uint64_t bytes, const char* what) {
    fieldOffset_ = offset_;
    require(bytes, what);
    in_.read(static_cast<char*>(to), std::streamsize(bytes));
    if (std::uint64_t(in_.gcount()) != bytes) fail(what, "cannot be read");
    offset_ += bytes;
}

void FieldReader::skip(std::uint64_t bytes, const char* what) {
    fieldOffset_ = offset_;
    require(bytes, what);
    seek(offset_ + bytes, what);
}

void FieldReader::requireCount(std::uint64_t count, std::uint64_t leastBytes, const char* what) {
    if (saturatingProduct(count, leastBytes) > remaining())
        fail(what, "is " + std::to_string(count));
}

void FieldReader::refuse(const char* what, const std::string& problem) const {
    throw FormatError(file_.string() + ": not a readable " + kind_ + " (its " + what +
                      " at byte " + std::to_string(fieldOffset_) + " " + problem + ")");
}

void FieldReader::fail(const char* what, const std::string& problem) const {
    refuse(what, problem + ", but the file has " + std::to_string(fileBytes_) +
                     " bytes; the file is truncated or corrupt");
}

void FieldReader::require(std::uint64_t bytes, const char* what) {
    if (bytes > remaining()) fail(what, "needs " + std::to_string(bytes) + " bytes");
}

}  // namespace distile
