#include "common/exr_header.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <fstream>
#include <optional>
#include <string>

#include "common/error.h"
#include "common/field_reader.h"
#include "common/input_file.h"

namespace distile {

namespace {

// The OpenEXR file layout: a magic number, a version field (the version in the low byte, flags
// above it), the header's attributes (name and type as NUL-terminated strings, a 32-bit size,
// the value) up to an empty name, the offset table (one 64-bit file offset per chunk), then the
// chunks (scan lines: y, data size, data; tiles: tile x, tile y, level x, level y, data size,
// data). All fields little-endian.
constexpr unsigned char kExrMagic[4] = {0x76, 0x2f, 0x31, 0x01};
constexpr std::uint64_t kExrVersion = 2;
constexpr std::uint64_t kFlagTiled = 0x200;
constexpr std::uint64_t kFlagLongNames = 0x400;
constexpr std::uint64_t kFlagDeep = 0x800;
constexpr std::uint64_t kFlagMultiPart = 0x1000;
constexpr std::uint64_t kShortNameBytes = 31;
constexpr std::uint64_t kLongNameBytes = 255;
/// Scan lines per chunk of each compression (NONE, RLE, ZIPS, ZIP, PIZ, PXR24, B44, B44A, DWAA,
/// DWAB).
constexpr std::uint64_t kLinesPerChunk[] = {1, 1, 1, 16, 32, 16, 32, 32, 32, 256};
/// Bytes each channel takes in memory once read: distile reads every channel as float.
constexpr std::uint64_t kChannelMemoryBytes = 4;

/// Attribute types whose value OpenEXR reads as a fixed number of bytes whatever the attribute's
/// size says; 0 for the others.
std::uint64_t fixedValueBytes(const std::string& type) {
    struct Fixed {
        const char* type;
        std::uint64_t bytes;
    };
    static constexpr Fixed kFixed[] = {{"box2i", 16},    {"box2f", 16},   {"compression", 1},
                                       {"lineOrder", 1}, {"envmap", 1},   {"deepImageState", 1},
                                       {"int", 4},       {"float", 4},    {"double", 8},
                                       {"rational", 8},  {"timecode", 8}, {"keycode", 28},
                                       {"tiledesc", 9},  {"v2i", 8},      {"v2f", 8},
                                       {"v2d", 16},      {"v3i", 12},     {"v3f", 12},
                                       {"v3d", 24},      {"m33f", 36},    {"m33d", 72},
                                       {"m44f", 64},     {"m44d", 128},   {"chromaticities", 32}};
    for (const Fixed& fixed : kFixed)
        if (type == fixed.type) return fixed.bytes;
    return 0;
}

/// A NUL-terminated name of at most `maxBytes` printable characters (empty: the end of a list).
std::string nameField(FieldReader& reader, std::uint64_t maxBytes, const char* what) {
    const std::uint64_t start = reader.offset();
    std::string name;
    for (;;) {
        const auto byte = char(reader.unsignedField(1, what));
        if (byte == '\0') return name;
        name += byte;
        if (byte < 0x20 || byte > 0x7e || name.size() > maxBytes) {
            reader.seek(start, what);
            reader.unsignedField(1, what);  // so the message names where the name starts
            reader.refuse(what, "is " + quotedInput(name) + "...; accepted: at most " +
                                    std::to_string(maxBytes) + " printable characters");
        }
    }
}

struct Box {
    std::int64_t xMin, yMin, xMax, yMax;
};

/// Tiles across `extent` pixels at level `level`, OpenEXR's level sizes (halved, rounded down or
/// up, at least 1).
std::uint64_t tilesAcross(std::uint64_t extent, int level, bool roundUp, std::uint64_t tileSize) {
    std::uint64_t size =
        roundUp ? (extent + (std::uint64_t(1) << level) - 1) >> level : extent >> level;
    size = std::max<std::uint64_t>(size, 1);
    return (size + tileSize - 1) / tileSize;
}

/// Levels of a mip or rip map along an extent of `extent` pixels.
int levelCount(std::uint64_t extent, bool roundUp) {
    const int floorLog2 = int(std::bit_width(extent)) - 1;
    return floorLog2 + 1 + (roundUp && !std::has_single_bit(extent) ? 1 : 0);
}

}  // namespace

bool startsAsExr(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    unsigned char magic[4] = {};
    in.read(reinterpret_cast<char*>(magic), 4);
    return in.gcount() == 4 && std::equal(magic, magic + 4, kExrMagic);
}

void checkExrHeader(const std::filesystem::path& file) {
    if (!startsAsExr(file)) return;
    FieldReader reader(file, std::filesystem::file_size(file), "OpenEXR file");
    reader.skip(4, "magic number");
    const std::uint64_t versionField = reader.unsignedField(4, "version field");
    if ((versionField & 0xff) != kExrVersion)
        reader.refuse("version field",
                      "says version " + std::to_string(versionField & 0xff) + "; accepted: 2");
    const std::uint64_t flags = versionField & ~std::uint64_t(0xff);
    if (flags & (kFlagDeep | kFlagMultiPart)) {
        reader.refuse("version field", std::string("marks a ") +
                                           ((flags & kFlagMultiPart) ? "multi-part" : "deep") +
                                           " file; distile reads single-part flat images only");
    }
    if (flags & ~(kFlagTiled | kFlagLongNames))
        reader.refuse("version field", "has unknown flags " + std::to_string(flags));
    const bool tiled = flags & kFlagTiled;
    const std::uint64_t maxNameBytes = (flags & kFlagLongNames) ? kLongNameBytes : kShortNameBytes;

    std::optional<Box> dataWindow;
    std::optional<std::uint64_t> compression, chunkCount;
    std::uint64_t tileWidth = 0, tileHeight = 0, levelMode = 0;
    bool roundUp = false, hasTiles = false;
    std::uint64_t channels = 0;
    for (;;) {
        const std::string name = nameField(reader, maxNameBytes, "attribute name");
        if (name.empty()) break;
        const std::string type = nameField(reader, maxNameBytes, "attribute type");
        const std::int64_t size = reader.int32Field("attribute size");
        if (size < 0 || std::uint64_t(size) > reader.remaining()) {
            reader.refuse("attribute size",
                          "is " + std::to_string(size) + " for attribute '" + name + "', but " +
                              std::to_string(reader.remaining()) + " bytes of the file follow");
        }
        const std::uint64_t valueBytes = std::uint64_t(size);
        const std::uint64_t valueEnd = reader.offset() + valueBytes;
        if (const std::uint64_t fixed = fixedValueBytes(type); fixed != 0 && fixed != valueBytes) {
            reader.refuse("attribute size", "is " + std::to_string(valueBytes) +
                                                " for attribute '" + name + "' of type " + type +
                                                "; accepted: " + std::to_string(fixed));
        }
        if (type == "preview") {  // width, height, then 4 bytes per pixel
            const std::uint64_t width = reader.unsignedField(4, "preview width");
            const std::uint64_t height = reader.unsignedField(4, "preview height");
            const std::uint64_t bytes =
                saturatingSum(8, saturatingProduct(saturatingProduct(width, height), 4));
            if (bytes != valueBytes)
                reader.refuse("preview size",
                              "is " + std::to_string(width) + "x" + std::to_string(height) +
                                  " pixels, which needs " + std::to_string(bytes) +
                                  " bytes; the attribute has " + std::to_string(valueBytes));
        } else if (type == "stringvector") {  // strings of a 32-bit length each
            while (reader.offset() < valueEnd) {
                const std::int64_t length = reader.int32Field("string length");
                if (length < 0 ||
                    std::uint64_t(length) > valueEnd - std::min(valueEnd, reader.offset()))
                    reader.refuse("string length", "is " + std::to_string(length) +
                                                       ", past the end of attribute '" + name +
                                                       "'");
                reader.skip(std::uint64_t(length), "string");
            }
        } else if (name == "channels" && type == "chlist") {
            for (;;) {
                if (reader.offset() >= valueEnd)
                    reader.refuse("channel list", "runs past the end of its attribute");
                if (nameField(reader, maxNameBytes, "channel name").empty()) break;
                const std::uint64_t pixelType = reader.unsignedField(4, "channel pixel type");
                if (pixelType > 2)
                    reader.refuse("channel pixel type", "is " + std::to_string(pixelType) +
                                                            "; accepted: 0 (uint), 1 (half), 2 "
                                                            "(float)");
                reader.skip(4, "channel linearity");
                const std::int64_t xSampling = reader.int32Field("channel x sampling");
                const std::int64_t ySampling = reader.int32Field("channel y sampling");
                if (xSampling != 1 || ySampling != 1)
                    reader.refuse("channel y sampling",
                                  "and x sampling are " + std::to_string(ySampling) + " and " +
                                      std::to_string(xSampling) +
                                      "; accepted: 1 (distile reads no subsampled channels)");
                ++channels;
            }
        } else if (name == "dataWindow" && type == "box2i") {
            Box box{};
            box.xMin = reader.int32Field("data window");
            box.yMin = reader.int32Field("data window");
            box.xMax = reader.int32Field("data window");
            box.yMax = reader.int32Field("data window");
            dataWindow = box;
        } else if (name == "compression" && type == "compression") {
            compression = reader.unsignedField(1, "compression");
            if (*compression >= std::size(kLinesPerChunk))
                reader.refuse("compression", "is " + std::to_string(*compression) +
                                                 "; accepted: 0 to 9 (none, rle, zips, zip, piz, "
                                                 "pxr24, b44, b44a, dwaa, dwab)");
        } else if (name == "tiles" && type == "tiledesc") {
            tileWidth = reader.unsignedField(4, "tile width");
            tileHeight = reader.unsignedField(4, "tile height");
            const std::uint64_t mode = reader.unsignedField(1, "tile level mode");
            levelMode = mode & 0x0f;
            roundUp = (mode >> 4) == 1;
            if (levelMode > 2 || (mode >> 4) > 1)
                reader.refuse("tile level mode", "is " + std::to_string(mode) +
                                                     "; accepted: levels 0 to 2, rounding 0 or 1");
            hasTiles = true;
        } else if (name == "chunkCount" && type == "int") {
            const std::int64_t count = reader.int32Field("chunk count");
            chunkCount = std::uint64_t(std::max<std::int64_t>(count, 0));
        }
        if (reader.offset() > valueEnd)
            reader.refuse("attribute size", "is shorter than attribute '" + name + "' reads");
        reader.seek(valueEnd, "attribute value");
    }
    const std::uint64_t headerEnd = reader.offset();
    const auto requireAttribute = [&](bool present, const char* name) {
        if (!present)
            throw FormatError(file.string() + ": not a readable OpenEXR file (its header has no '" +
                              name + "' attribute)");
    };
    requireAttribute(dataWindow.has_value(), "dataWindow");
    requireAttribute(compression.has_value(), "compression");
    requireAttribute(channels > 0, "channels");
    if (tiled) requireAttribute(hasTiles, "tiles");

    const Box& box = *dataWindow;
    if (box.xMax < box.xMin || box.yMax < box.yMin) {
        throw FormatError(file.string() + ": not a readable OpenEXR file (its data window (" +
                          std::to_string(box.xMin) + ", " + std::to_string(box.yMin) + ") to (" +
                          std::to_string(box.xMax) + ", " + std::to_string(box.yMax) +
                          ") is empty)");
    }
    const auto width = std::uint64_t(box.xMax - box.xMin + 1);
    const auto height = std::uint64_t(box.yMax - box.yMin + 1);
    const std::string image = "a " + std::to_string(width) + "x" + std::to_string(height) +
                              " image of " + std::to_string(channels) + " channel(s)";
    requireWithinMemoryBudget(
        file, image,
        saturatingProduct(saturatingProduct(width, height), channels * kChannelMemoryBytes));

    // The chunks the offset table lists, and the least bytes each takes (its table entry and the
    // fields before its data).
    std::uint64_t chunks = 0;
    std::uint64_t chunkFieldBytes = 8;  // y, data size
    if (!tiled) {
        const std::uint64_t lines = kLinesPerChunk[*compression];
        chunks = (height + lines - 1) / lines;
    } else {
        chunkFieldBytes = 20;  // tile x, tile y, level x, level y, data size
        if (tileWidth == 0 || tileHeight == 0)
            throw FormatError(file.string() + ": not a readable OpenEXR file (its tiles are " +
                              std::to_string(tileWidth) + "x" + std::to_string(tileHeight) +
                              " pixels; accepted: at least 1x1)");
        // OpenEXR keeps a buffer of a whole tile.
        requireWithinMemoryBudget(
            file,
            "a tile of " + std::to_string(tileWidth) + "x" + std::to_string(tileHeight) + " pixels",
            saturatingProduct(saturatingProduct(tileWidth, tileHeight),
                              channels * kChannelMemoryBytes));
        const int xLevels =
            levelMode == 0 ? 1
                           : levelCount(levelMode == 1 ? std::max(width, height) : width, roundUp);
        const int yLevels =
            levelMode == 0 ? 1
                           : levelCount(levelMode == 1 ? std::max(width, height) : height, roundUp);
        if (levelMode == 2) {  // rip map: every pair of levels
            std::uint64_t across = 0, down = 0;
            for (int level = 0; level < xLevels; ++level)
                across += tilesAcross(width, level, roundUp, tileWidth);
            for (int level = 0; level < yLevels; ++level)
                down += tilesAcross(height, level, roundUp, tileHeight);
            chunks = saturatingProduct(across, down);
        } else {
            for (int level = 0; level < xLevels; ++level)
                chunks = saturatingSum(
                    chunks, saturatingProduct(tilesAcross(width, level, roundUp, tileWidth),
                                              tilesAcross(height, level, roundUp, tileHeight)));
        }
    }
    if (chunkCount && *chunkCount != chunks) {
        throw FormatError(file.string() + ": not a readable OpenEXR file (its chunkCount " +
                          std::to_string(*chunkCount) + " is not the " + std::to_string(chunks) +
                          " chunks " + image + " needs)");
    }
    requireDeclaredCount(file, "the chunks of " + image, chunks, 8 + chunkFieldBytes,
                         reader.fileBytes() - headerEnd, 8);

    // Each chunk lies after the table and its data fits in the file.
    const std::uint64_t tableEnd = headerEnd + 8 * chunks;
    for (std::uint64_t chunk = 0; chunk < chunks; ++chunk) {
        reader.seek(headerEnd + 8 * chunk, "offset table");
        const std::uint64_t offset = reader.unsignedField(8, "chunk offset");
        if (offset < tableEnd || offset > reader.fileBytes() - chunkFieldBytes)
            reader.refuse("chunk offset", "is " + std::to_string(offset) +
                                              "; accepted: " + std::to_string(tableEnd) + " to " +
                                              std::to_string(reader.fileBytes() - chunkFieldBytes) +
                                              " (the file is truncated or corrupt)");
        reader.seek(offset + chunkFieldBytes - 4, "chunk offset");
        const std::int64_t dataBytes = reader.int32Field("chunk data size");
        if (dataBytes < 0 || std::uint64_t(dataBytes) > reader.remaining())
            reader.fail("chunk data size", "is " + std::to_string(dataBytes));
    }
}

}  // namespace distile
