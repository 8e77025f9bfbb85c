#include "vdb/detail/vdb_header_check.h"

#include <fstream>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/input_file.h"

namespace distile::detail {

namespace {

// OpenVDB's file format (openvdb/io/Archive.cc, GridDescriptor.cc, MetaMap.cc): little-endian
// fields, strings as a 32-bit length and that many bytes.
constexpr std::int64_t kVdbMagic = 0x56444220;
constexpr std::uint32_t kVersionLibraryVersion = 211;   ///< library major/minor follow
constexpr std::uint32_t kVersionGridOffsets = 212;      ///< the has-grid-offsets flag follows
constexpr std::uint32_t kVersionUuidText = 220;         ///< the UUID is 36 characters, not 16 bytes
constexpr std::uint32_t kVersionGridInstancing = 216;   ///< descriptors name an instance parent
constexpr std::uint32_t kVersionMaskCompression = 222;  ///< grids start with a compression flag

/// Reads fields from a position, refusing any that would run past the end of the file.
class FieldReader {
  public:
    FieldReader(const std::filesystem::path& file, std::uint64_t fileBytes)
        : in_(file, std::ios::binary), file_(file), fileBytes_(fileBytes) {
        if (!in_) throw InputError(file.string() + ": cannot open for reading");
    }

    std::uint64_t offset() const { return offset_; }

    void seek(std::uint64_t offset, const char* what) {
        if (offset > fileBytes_) fail(what, "points to byte " + std::to_string(offset));
        in_.seekg(std::streamoff(offset));
        offset_ = offset;
    }

    std::uint64_t unsignedField(int bytes, const char* what) {
        fieldOffset_ = offset_;
        require(std::uint64_t(bytes), what);
        unsigned char data[8] = {};
        in_.read(reinterpret_cast<char*>(data), bytes);
        if (in_.gcount() != bytes) fail(what, "cannot be read");
        offset_ += std::uint64_t(bytes);
        std::uint64_t value = 0;
        for (int k = 0; k < bytes; ++k) value |= std::uint64_t(data[k]) << (8 * k);
        return value;
    }

    /// A 32-bit length and that many bytes, skipped.
    void skipString(const char* what) { skip(unsignedField(4, what), what); }

    void skip(std::uint64_t bytes, const char* what) {
        require(bytes, what);
        seek(offset_ + bytes, what);
    }

    /// `count` items of at least `leastBytes` each must fit in the rest of the file.
    void requireCount(std::uint64_t count, std::uint64_t leastBytes, const char* what) {
        if (saturatingProduct(count, leastBytes) > fileBytes_ - offset_)
            fail(what, "is " + std::to_string(count));
    }

  private:
    void require(std::uint64_t bytes, const char* what) {
        if (bytes > fileBytes_ - offset_) fail(what, "needs " + std::to_string(bytes) + " bytes");
    }

    [[noreturn]] void fail(const char* what, const std::string& problem) const {
        throw FormatError(file_.string() + ": not a readable .vdb file (its " + what + " at byte " +
                          std::to_string(fieldOffset_) + " " + problem + ", but the file has " +
                          std::to_string(fileBytes_) + " bytes; the file is truncated or corrupt)");
    }

    std::ifstream in_;
    const std::filesystem::path& file_;
    std::uint64_t fileBytes_;
    std::uint64_t offset_ = 0;
    std::uint64_t fieldOffset_ = 0;  ///< where the last field read starts (for messages)
};

/// A metadata map: a count, then per entry a name, a type name and a sized value.
void skipMetadata(FieldReader& reader) {
    const std::uint64_t count = reader.unsignedField(4, "metadata count");
    reader.requireCount(count, 12, "metadata count");
    for (std::uint64_t entry = 0; entry < count; ++entry) {
        reader.skipString("metadata name");
        reader.skipString("metadata type name");
        reader.skipString("metadata value");
    }
}

}  // namespace

void checkVdbHeader(const std::filesystem::path& file, std::uint64_t fileBytes) {
    FieldReader reader(file, fileBytes);
    if (fileBytes < 8 || std::int64_t(reader.unsignedField(8, "magic number")) != kVdbMagic) {
        throw FormatError(file.string() +
                          ": not a readable .vdb file (it does not start with OpenVDB's magic "
                          "number)");
    }
    const std::uint64_t version = reader.unsignedField(4, "file version");
    if (version >= kVersionLibraryVersion) reader.skip(8, "library version");
    bool gridOffsets = false;
    if (version >= kVersionGridOffsets)
        gridOffsets = reader.unsignedField(1, "grid offset flag") != 0;
    reader.skip(version >= kVersionUuidText ? 36 : 16, "file identifier");
    skipMetadata(reader);
    if (!gridOffsets) return;  // grids follow one after the other; OpenVDB checks them as it reads
    const std::uint64_t grids = reader.unsignedField(4, "grid count");
    reader.requireCount(grids, 36, "grid count");
    struct GridOffsets {
        std::uint64_t grid, block, end;
    };
    std::vector<GridOffsets> offsets;
    for (std::uint64_t index = 0; index < grids; ++index) {
        reader.skipString("grid name");
        reader.skipString("grid type");
        if (version >= kVersionGridInstancing) reader.skipString("instance parent name");
        GridOffsets grid{};
        grid.grid = reader.unsignedField(8, "grid offset");
        grid.block = reader.unsignedField(8, "grid data offset");
        grid.end = reader.unsignedField(8, "grid end offset");
        if (!(grid.grid <= grid.block && grid.block <= grid.end && grid.end <= fileBytes)) {
            throw FormatError(file.string() + ": not a readable .vdb file (grid " +
                              std::to_string(index) + " says it lies in bytes " +
                              std::to_string(grid.grid) + " to " + std::to_string(grid.end) +
                              ", but the file has " + std::to_string(fileBytes) +
                              " bytes; the file is truncated or corrupt)");
        }
        offsets.push_back(grid);
    }
    for (const GridOffsets& grid : offsets) {
        reader.seek(grid.grid, "grid offset");
        if (version >= kVersionMaskCompression) reader.skip(4, "grid compression flag");
        skipMetadata(reader);
        if (reader.offset() > grid.block) {
            throw FormatError(file.string() +
                              ": not a readable .vdb file (a grid's metadata runs into its data; "
                              "the file is corrupt)");
        }
    }
}

}  // namespace distile::detail
