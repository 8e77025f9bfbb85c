#include "vdb/openvdb/vdb_header_check.h"

#include <algorithm>
#include <array>
#include <bit>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/field_reader.h"
#include "common/input_file.h"

namespace distile::detail {

namespace {

// OpenVDB's file format (openvdb/io/Archive, GridDescriptor, MetaMap, math/Transform, the tree
// nodes' readTopology/readBuffers and io/Compression.h): little-endian fields, strings as a
// 32-bit length and that many bytes.
constexpr std::int64_t kVdbMagic = 0x56444220;
constexpr std::uint32_t kVersionNodeMaskCompression = 222;  ///< oldest version walked
constexpr std::uint32_t kVersionNewest = 224;               ///< newest version OpenVDB 10 reads
constexpr std::uint32_t kVersionGridInstancing = 216;       ///< descriptors name an instance parent

// Compression flags of a grid (io::COMPRESS_*) and the per-node flag that says which inactive
// values follow (io::NO_MASK_AND_ONE_INACTIVE_VAL ...).
constexpr std::uint64_t kCompressZip = 0x1;
constexpr std::uint64_t kCompressActiveMask = 0x2;
constexpr std::uint64_t kCompressBlosc = 0x4;
constexpr std::uint64_t kNoMaskAndAllValues = 6;

/// A float tree of OpenVDB's standard configuration, the only grids distile reads voxels of:
/// root -> internal nodes of 32^3 -> internal nodes of 16^3 -> leaves of 8^3.
constexpr const char* kFloatTreeType = "Tree_float_5_4_3";
constexpr const char* kHalfSuffix = "_HalfFloat";  ///< values stored as 16-bit halves
constexpr int kLeafLog2 = 3;
constexpr std::uint64_t kFloatBytes = 4;
constexpr std::uint64_t kHalfBytes = 2;
/// What one node takes in memory once read (values, masks, child pointers), bytes, at least.
constexpr std::uint64_t kLeafMemoryBytes = (std::uint64_t(1) << 9) * kFloatBytes + 2 * 64;
constexpr std::uint64_t kInternalMemoryBytes[] = {
    0, 0, 0, 0, (std::uint64_t(1) << 12) * 8 + 2 * 512, (std::uint64_t(1) << 15) * 8 + 2 * 4096};

/// A node mask of 2^(3 log2) bits, as 64-bit words.
using LeafMask = std::array<std::uint64_t, 8>;

/// A string: a 32-bit length and that many bytes.
std::string vdbString(FieldReader& reader, const char* what) {
    const std::uint64_t length = reader.unsignedField(4, what);
    reader.requireCount(length, 1, what);  // before the string is allocated
    std::string text(length, '\0');
    reader.readBytes(text.data(), text.size(), what);
    return text;
}

/// Bytes of the metadata value types OpenVDB registers whose reader takes a fixed size whatever
/// the value's declared size says (TypedMetadata<T>); 0 for the others, which read what the size
/// says (strings, unknown types) or walk their own contents (__delayedload).
std::uint64_t fixedMetadataBytes(const std::string& type) {
    struct Fixed {
        const char* type;
        std::uint64_t bytes;
    };
    static constexpr Fixed kFixed[] = {{"bool", 1},   {"int32", 4},  {"int64", 8},  {"float", 4},
                                       {"double", 8}, {"vec2i", 8},  {"vec2s", 8},  {"vec2d", 16},
                                       {"vec3i", 12}, {"vec3s", 12}, {"vec3d", 24}, {"vec4i", 16},
                                       {"vec4s", 16}, {"vec4d", 32}, {"mat4s", 64}, {"mat4d", 128}};
    for (const Fixed& fixed : kFixed)
        if (type == fixed.type) return fixed.bytes;
    return 0;
}

/// The two sizes a blosc buffer's 16-byte header declares. Blosc trusts them: it writes
/// `uncompressedBytes` and reads `compressedBytes` whatever the buffer holds.
struct BloscSizes {
    std::uint64_t uncompressedBytes = 0;
    std::uint64_t compressedBytes = 0;
};

BloscSizes readBloscHeader(FieldReader& reader, const char* what) {
    std::uint8_t header[16];
    reader.readBytes(header, 16, what);
    const auto field = [&](int at) {
        return std::uint64_t(header[at]) | std::uint64_t(header[at + 1]) << 8 |
               std::uint64_t(header[at + 2]) << 16 | std::uint64_t(header[at + 3]) << 24;
    };
    return {field(4), field(12)};
}

/// OpenVDB's delayed-load metadata: a leaf count, then a byte per leaf and (unless the size
/// says none) 8 bytes per leaf, each part either raw or as a blosc buffer of a 32-bit size.
/// OpenVDB sizes its arrays by the count and by the blosc header, not by the value's size.
void checkDelayedLoadMetadata(FieldReader& reader, std::uint64_t valueBytes) {
    if (valueBytes == 0) return;
    const std::uint64_t end = reader.offset() + valueBytes;
    const auto left = [&] { return end - std::min(end, reader.offset()); };
    const std::uint64_t leaves = reader.unsignedField(4, "delayed-load leaf count");
    // Each leaf takes a mask byte and an 8-byte size in memory.
    if (saturatingProduct(leaves, 9) > kInputMemoryBudgetBytes)
        reader.refuse("delayed-load leaf count",
                      "is " + std::to_string(leaves) + ", more leaves than fit in memory");
    for (const std::uint64_t bytesEach : {std::uint64_t(1), std::uint64_t(8)}) {
        const std::uint64_t stored = reader.unsignedField(4, "delayed-load buffer size");
        if (bytesEach == 8 && stored == 0xffffffffu) break;  // no compressed sizes stored
        const std::uint64_t expected = leaves * bytesEach;
        if (stored == 0) {
            if (expected > left())
                reader.refuse("delayed-load buffer size",
                              "is " + std::to_string(expected) + " bytes, past the metadata value");
            reader.skip(expected, "delayed-load buffer");
            continue;
        }
        if (stored < 16 || stored > left())
            reader.refuse("delayed-load buffer size", "is " + std::to_string(stored) +
                                                          " bytes, not a blosc buffer within the "
                                                          "metadata value");
        const BloscSizes sizes = readBloscHeader(reader, "delayed-load blosc header");
        // OpenVDB pads short buffers to 128 bytes before compressing them, and reserves what the
        // header says.
        const std::uint64_t most = std::max<std::uint64_t>(expected, 128);
        if (sizes.uncompressedBytes < expected || sizes.uncompressedBytes > most ||
            sizes.compressedBytes > stored)
            reader.refuse("delayed-load blosc header",
                          "says " + std::to_string(sizes.uncompressedBytes) + " bytes from " +
                              std::to_string(sizes.compressedBytes) + "; accepted: " +
                              std::to_string(expected) + " to " + std::to_string(most) +
                              " (the leaf count's) from at most " + std::to_string(stored));
        reader.skip(stored - 16, "delayed-load buffer");
    }
    if (reader.offset() > end)
        reader.refuse("delayed-load metadata", "runs past its declared size");
    reader.seek(end, "delayed-load metadata");
}

/// A metadata map: a count, then per entry a name, a type name and a sized value.
void checkMetadata(FieldReader& reader) {
    const std::uint64_t count = reader.unsignedField(4, "metadata count");
    reader.requireCount(count, 12, "metadata count");
    for (std::uint64_t entry = 0; entry < count; ++entry) {
        reader.skip(reader.unsignedField(4, "metadata name"), "metadata name");
        const std::string type = vdbString(reader, "metadata type name");
        const std::uint64_t valueBytes = reader.unsignedField(4, "metadata value size");
        const std::uint64_t fixedBytes = fixedMetadataBytes(type);
        if (fixedBytes != 0 && valueBytes != fixedBytes) {
            reader.refuse("metadata value size", "is " + std::to_string(valueBytes) +
                                                     " for a value of type " + quotedInput(type) +
                                                     "; accepted: " + std::to_string(fixedBytes));
        }
        if (type == "__delayedload") {
            reader.requireCount(valueBytes, 1, "metadata value size");
            checkDelayedLoadMetadata(reader, valueBytes);
        } else {
            reader.skip(valueBytes, "metadata value");
        }
    }
}

/// A transform: a map type name and the map's values (math/Maps.h: each map reads a fixed
/// number of doubles; a frustum also reads a second map).
void checkTransform(FieldReader& reader, int depth = 0) {
    const std::string type = vdbString(reader, "transform map type");
    struct MapBytes {
        const char* type;
        std::uint64_t bytes;
    };
    static constexpr MapBytes kMaps[] = {{"AffineMap", 128},
                                         {"UnitaryMap", 128},
                                         {"ScaleMap", 5 * 24},
                                         {"UniformScaleMap", 5 * 24},
                                         {"TranslationMap", 24},
                                         {"ScaleTranslateMap", 6 * 24},
                                         {"UniformScaleTranslateMap", 6 * 24}};
    for (const MapBytes& map : kMaps) {
        if (type == map.type) {
            reader.skip(map.bytes, "transform");
            return;
        }
    }
    if (type == "NonlinearFrustumMap" && depth == 0) {
        reader.skip(48 + 16, "frustum transform");  // box, taper, depth
        checkTransform(reader, depth + 1);
        return;
    }
    reader.refuse("transform map type", "is " + quotedInput(type) +
                                            "; accepted: the maps OpenVDB defines (AffineMap, "
                                            "ScaleMap, ...)");
}

/// Walks one float tree (topology, then the leaves' values) of a grid stored with
/// `compression`, counting what it will take in memory.
class FloatTreeWalk {
  public:
    /// `memoryBytes`: what the file's trees walked so far take, added to as this one is walked.
    FloatTreeWalk(const std::filesystem::path& file, FieldReader& reader, std::uint64_t compression,
                  bool half, std::uint64_t& memoryBytes)
        : file_(file),
          reader_(reader),
          compression_(compression),
          half_(half),
          memoryBytes_(memoryBytes) {}

    void topology() {
        reader_.skip(4, "tree buffer count");
        reader_.skip(kFloatBytes, "background value");
        const std::uint64_t tiles = reader_.unsignedField(4, "root tile count");
        const std::uint64_t children = reader_.unsignedField(4, "root child count");
        if (tiles == 0 && children == 0) return;
        reader_.requireCount(tiles, 12 + kFloatBytes + 1, "root tile count");
        reader_.skip(tiles * (12 + kFloatBytes + 1), "root tiles");
        reader_.requireCount(children, 12 + 2 * 4096 + 1, "root child count");
        for (std::uint64_t child = 0; child < children; ++child) {
            reader_.skip(12, "root child origin");
            internalTopology(5);
        }
    }

    void buffers() {
        for (const LeafMask& topologyMask : leafMasks_) {
            LeafMask mask{};
            reader_.readBytes(mask.data(), sizeof mask, "leaf value mask");
            if (mask != topologyMask)
                reader_.refuse("leaf value mask", "differs from the one in the tree's topology");
            compressedValues(std::uint64_t(1) << (3 * kLeafLog2), activeCount(mask), 64);
        }
    }

  private:
    void internalTopology(int log2) {
        addMemory(kInternalMemoryBytes[log2]);
        const std::uint64_t words = (std::uint64_t(1) << (3 * log2)) / 64;
        std::vector<std::uint64_t> childMask(words), valueMask(words);
        reader_.readBytes(childMask.data(), words * 8, "node child mask");
        reader_.readBytes(valueMask.data(), words * 8, "node value mask");
        std::uint64_t active = 0;
        for (const std::uint64_t word : valueMask) active += std::uint64_t(std::popcount(word));
        compressedValues(words * 64, active, words * 8);
        for (std::uint64_t word = 0; word < words; ++word) {
            for (int bit = 0; bit < 64; ++bit) {
                if (!((childMask[word] >> bit) & 1)) continue;
                if (log2 == 5) {
                    internalTopology(4);
                } else {
                    addMemory(kLeafMemoryBytes);
                    LeafMask mask{};
                    reader_.readBytes(mask.data(), sizeof mask, "leaf value mask");
                    leafMasks_.push_back(mask);
                }
            }
        }
    }

    static std::uint64_t activeCount(const LeafMask& mask) {
        std::uint64_t active = 0;
        for (const std::uint64_t word : mask) active += std::uint64_t(std::popcount(word));
        return active;
    }

    /// io::readCompressedValues: a flag, the inactive values and selection mask it announces,
    /// then the values (all, or only the active ones under mask compression).
    void compressedValues(std::uint64_t count, std::uint64_t active, std::uint64_t maskBytes) {
        const std::uint64_t flag = reader_.unsignedField(1, "node compression flag");
        if (flag == 2 || flag == 4 || flag == 5) reader_.skip(kFloatBytes, "inactive value");
        if (flag == 5) reader_.skip(kFloatBytes, "inactive value");
        if (flag == 3 || flag == 4 || flag == 5) reader_.skip(maskBytes, "selection mask");
        const bool onlyActive = (compression_ & kCompressActiveMask) && flag != kNoMaskAndAllValues;
        const std::uint64_t values = onlyActive ? active : count;
        if (half_ && values == 0) return;  // OpenVDB reads no chunk for no halves
        const std::uint64_t bytes = values * (half_ ? kHalfBytes : kFloatBytes);
        if (compression_ & (kCompressBlosc | kCompressZip)) {
            chunk(bytes);
        } else {
            reader_.skip(bytes, "node values");
        }
    }

    /// A blosc or zip chunk: its 64-bit size (negative: that many raw bytes follow), then the
    /// bytes. OpenVDB allocates the size it reads before reading the bytes.
    void chunk(std::uint64_t expectedBytes) {
        const auto declared = std::int64_t(reader_.unsignedField(8, "compressed chunk size"));
        if (declared <= 0) {
            const std::uint64_t rawBytes = 0 - std::uint64_t(declared);  // no overflow at INT64_MIN
            if (rawBytes != expectedBytes)
                reader_.refuse("uncompressed chunk size",
                               "is " + std::to_string(rawBytes) +
                                   " bytes; accepted: " + std::to_string(expectedBytes));
            reader_.skip(expectedBytes, "uncompressed chunk");
            return;
        }
        if (std::uint64_t(declared) > reader_.remaining())
            reader_.fail("compressed chunk size", "is " + std::to_string(declared) + " bytes");
        if (!(compression_ & kCompressBlosc)) {
            reader_.skip(std::uint64_t(declared), "compressed chunk");
            return;
        }
        // Blosc decompresses what its own header says, not the chunk size: both must agree.
        if (declared < 16)
            reader_.refuse("compressed chunk size", "is shorter than a blosc header");
        const BloscSizes sizes = readBloscHeader(reader_, "blosc header");
        if (sizes.uncompressedBytes != expectedBytes ||
            sizes.compressedBytes > std::uint64_t(declared)) {
            reader_.refuse("blosc header", "says " + std::to_string(sizes.uncompressedBytes) +
                                               " bytes from " +
                                               std::to_string(sizes.compressedBytes) +
                                               "; accepted: " + std::to_string(expectedBytes) +
                                               " bytes from at most " + std::to_string(declared));
        }
        reader_.skip(std::uint64_t(declared) - 16, "compressed chunk");
    }

    void addMemory(std::uint64_t bytes) {
        memoryBytes_ = saturatingSum(memoryBytes_, bytes);
        requireWithinMemoryBudget(file_, "its float grids' trees", memoryBytes_);
    }

    const std::filesystem::path& file_;
    FieldReader& reader_;
    std::uint64_t compression_;
    bool half_;
    std::uint64_t& memoryBytes_;
    std::vector<LeafMask> leafMasks_;
};

}  // namespace

void checkVdbHeader(const std::filesystem::path& file, std::uint64_t fileBytes) {
    FieldReader reader(file, fileBytes, ".vdb file");
    if (fileBytes < 8 || std::int64_t(reader.unsignedField(8, "magic number")) != kVdbMagic) {
        throw FormatError(file.string() +
                          ": not a readable .vdb file (it does not start with OpenVDB's magic "
                          "number)");
    }
    const std::uint64_t version = reader.unsignedField(4, "file version");
    if (version < kVersionNodeMaskCompression || version > kVersionNewest) {
        reader.refuse("file version",
                      "is " + std::to_string(version) +
                          "; accepted: " + std::to_string(kVersionNodeMaskCompression) + " to " +
                          std::to_string(kVersionNewest) + " (files of OpenVDB 2 and later)");
    }
    reader.skip(8, "library version");
    if (reader.unsignedField(1, "grid offset flag") == 0)
        reader.refuse("grid offset flag", "is 0; accepted: 1 (OpenVDB files list grid offsets)");
    reader.skip(36, "file identifier");
    checkMetadata(reader);
    const std::uint64_t grids = reader.unsignedField(4, "grid count");
    reader.requireCount(grids, 36, "grid count");
    struct GridOffsets {
        std::uint64_t grid, block, end;
        bool floatTree, half, instance;
    };
    std::vector<GridOffsets> offsets;
    for (std::uint64_t index = 0; index < grids; ++index) {
        reader.skip(reader.unsignedField(4, "grid name"), "grid name");
        const std::string type = vdbString(reader, "grid type");
        GridOffsets grid{};
        grid.half = type.ends_with(kHalfSuffix);
        grid.floatTree = type.substr(0, grid.half ? type.size() - std::string(kHalfSuffix).size()
                                                  : type.size()) == kFloatTreeType;
        // An instance shares its parent's tree: only its metadata and transform are stored.
        if (version >= kVersionGridInstancing)
            grid.instance = !vdbString(reader, "instance parent name").empty();
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
        // The grid follows its descriptor: the next descriptor starts where the grid ends.
        if (grid.end < reader.offset())
            reader.refuse("grid end offset", "is " + std::to_string(grid.end) +
                                                 ", before the grid's own descriptor ends");
        reader.seek(grid.end, "grid end offset");
    }
    std::uint64_t memoryBytes = 0;
    for (const GridOffsets& grid : offsets) {
        reader.seek(grid.grid, "grid offset");
        const std::uint64_t compression = reader.unsignedField(4, "grid compression flags");
        checkMetadata(reader);
        checkTransform(reader);
        if (reader.offset() > grid.block) {
            throw FormatError(file.string() +
                              ": not a readable .vdb file (a grid's metadata runs into its data; "
                              "the file is corrupt)");
        }
        // distile reads the voxels of float grids only; other grids' metadata is all it reads.
        if (!grid.floatTree || grid.instance) continue;
        FloatTreeWalk tree(file, reader, compression, grid.half, memoryBytes);
        tree.topology();
        if (reader.offset() != grid.block)
            reader.refuse("tree topology", "ends at byte " + std::to_string(reader.offset()) +
                                               " but the grid's data starts at byte " +
                                               std::to_string(grid.block));
        tree.buffers();
        if (reader.offset() > grid.end)
            reader.refuse("tree values", "run to byte " + std::to_string(reader.offset()) +
                                             ", past the grid's end at byte " +
                                             std::to_string(grid.end));
    }
}

}  // namespace distile::detail
