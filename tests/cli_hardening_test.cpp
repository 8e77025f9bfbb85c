// Bad input from a fuzz campaign against the `distile` command: every run must end within its
// limits (10 s, 2 GB of address space here) with exit status 2 and one line naming the file,
// field or value, and leave no output behind. Also the exit statuses of the program's frame
// (cli/app.h).

#include <gtest/gtest.h>
#include <unistd.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <new>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/app.h"
#include "cli_fixture.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "common/input_file.h"
#include "render/image.h"
#include "sampler/tile_io.h"

namespace distile {
namespace {

/// 2 GB of address space: the budget the tests hold every run to.
constexpr long long kTwoGigabytesKiB = 2'000'000;

class Hardening : public Cli {
  protected:
    void SetUp() override {
        Cli::SetUp();
        limitRuns({10, kTwoGigabytesKiB});
    }

    /// A small chain mail tile and its level set in work(): two rings a row, their wires 2.1
    /// texels thick, so the tile passes its check and warns of nothing when a scene loads it.
    void bakeChainmail() const {
        const RunResult bake =
            run({"bake", "chainmail", "-o", "tile.exr", "--size", "64x64x16", "--rings-per-row",
                 "2", "--rows", "2", "--tilt", "5", "--vdb", "level.vdb"});
        ASSERT_EQ(bake.status, 0) << bake.err;
        ASSERT_EQ(bake.err, "");
    }
};

/// A plane without detail: renders in no time.
constexpr const char* kBareScene =
    R"({"objects": [{"mesh": "plane", "material": {"color": [0.8, 0.8, 0.8]}}]})";

std::string sourceFile(const std::string& relative) {
    return (fs::path(DISTILE_SOURCE_DIR) / relative).string();
}

// ---------------------------------------------------------------------------------------------
// Non-regular files: a device never ends, so every reader refuses it before reading.

TEST_F(Hardening, EveryReaderRefusesADevice) {
    const std::string device = "/dev/zero";
    const std::string refused = "not a regular file";
    EXPECT_EQ(expectInputError({"check", device}, "none", {device, refused}).status,
              cli::kExitInput);
    EXPECT_EQ(
        expectInputError({"compare", device, device, "-o", "d.png"}, "d.png", {device, refused})
            .status,
        cli::kExitInput);
    EXPECT_EQ(
        expectInputError({"bake", "heightmap", device, "-o", "t.exr"}, "t.exr", {device, refused})
            .status,
        cli::kExitInput);
    EXPECT_EQ(expectInputError({"bake", "mesh", device, "-o", "t.exr"}, "t.exr", {device, refused})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(
        expectInputError({"bake", "vdb", device, "-o", "t.exr"}, "t.exr", {device, refused}).status,
        cli::kExitInput);
    EXPECT_EQ(
        expectInputError({"render", device, "-o", "r.png"}, "r.png", {device, refused}).status,
        cli::kExitInput);
    // A scene's tile and colour texture.
    writeText(path("tile.json"),
              R"({"objects": [{"mesh": "plane", "material": {"tile": "/dev/zero"}}]})");
    EXPECT_EQ(
        expectInputError({"render", "tile.json", "-o", "r.png"}, "r.png", {device, refused}).status,
        cli::kExitInput);
    writeText(path("color.json"),
              R"({"objects": [{"mesh": "plane", "material": {"color": "/dev/urandom"}}]})");
    EXPECT_EQ(expectInputError({"render", "color.json", "-o", "r.png"}, "r.png",
                               {"/dev/urandom", refused})
                  .status,
              cli::kExitInput);
}

// ---------------------------------------------------------------------------------------------
// Declared counts against the file's size and the memory budget, before anything is allocated.

TEST_F(Hardening, PlyCountsThatOverflowThePreCheckAreRefused) {
    // 12 V + 13 F wraps around 2^64 to 0: an unchecked sum of the promised bytes passes any size.
    const unsigned long long vertices = 400'000'000ull;
    const unsigned long long faces = 1'418'980'312'993'042'432ull;
    ASSERT_EQ(12ull * vertices + 13ull * faces, 0ull);
    std::string ply =
        "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(vertices) +
        "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
        std::to_string(faces) + "\nproperty list uchar int vertex_indices\nend_header\n";
    ply.resize(251, '\0');
    writeText(path("overflow.ply"), ply);
    EXPECT_EQ(expectInputError({"bake", "mesh", "overflow.ply", "-o", "t.exr"}, "t.exr",
                               {"overflow.ply", "element 'vertex'", "400000000"})
                  .status,
              cli::kExitInput);
}

TEST_F(Hardening, OffHeaderCountsAreCheckedAgainstTheFileSize) {
    writeText(path("big.off"), "OFF\n3 1000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_EQ(expectInputError({"bake", "mesh", "big.off", "-o", "t.exr"}, "t.exr",
                               {"big.off", "OFF face count", "1000000000"})
                  .status,
              cli::kExitInput);
}

TEST_F(Hardening, MeshNumbersBeyondAFloatAreRefusedBeforeOpenMeshReadsThem) {
    const std::string header =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    writeText(path("huge.ply"), header + "-1e308 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_EQ(expectInputError({"bake", "mesh", "huge.ply", "-o", "t.exr"}, "t.exr",
                               {"huge.ply", "vertex 0", "-1e308", "float"})
                  .status,
              cli::kExitInput);
    writeText(path("huge.off"), "OFF\n3 1 0\n0 0 1e39\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_EQ(
        expectInputError({"bake", "mesh", "huge.off", "-o", "t.exr"}, "t.exr", {"huge.off", "1e39"})
            .status,
        cli::kExitInput);
}

TEST_F(Hardening, AFlippedVdbHeaderByteIsRefusedBeforeOpenVdbAllocates) {
    bakeChainmail();
    // The file's metadata count is bytes 57-60 (after the magic number, version, library
    // version, grid offset flag and UUID: 8 + 4 + 8 + 1 + 36); byte 59 flipped promises 2^23
    // entries, more than the file could hold.
    std::string bytes = readText(path("level.vdb"));
    ASSERT_GT(bytes.size(), 60u);
    bytes[59] = char(bytes[59] ^ 0x80);
    writeText(path("flipped.vdb"), bytes);
    EXPECT_EQ(expectInputError({"bake", "vdb", "flipped.vdb", "-o", "t2.exr"}, "t2.exr",
                               {"flipped.vdb", "metadata count at byte 57", "8388608"})
                  .status,
              cli::kExitInput);
    // Byte 123 is the top byte of the grid's end offset (bytes 116-123 of its descriptor):
    // flipped, it points far past the end of the file, where OpenVDB sought and waited.
    bytes = readText(path("level.vdb"));
    bytes[123] = char(bytes[123] ^ 0x80);
    writeText(path("offset.vdb"), bytes);
    EXPECT_EQ(expectInputError({"bake", "vdb", "offset.vdb", "-o", "t2.exr"}, "t2.exr",
                               {"offset.vdb", "grid 0"})
                  .status,
              cli::kExitInput);
}

/// The little-endian 64-bit field at `at` of `bytes`.
std::uint64_t field64(const std::string& bytes, std::size_t at) {
    std::uint64_t value = 0;
    for (int k = 7; k >= 0; --k) value = value << 8 | static_cast<unsigned char>(bytes[at + k]);
    return value;
}

void setField64(std::string& bytes, std::size_t at, std::uint64_t value) {
    for (int k = 0; k < 8; ++k) bytes[at + k] = char((value >> (8 * k)) & 0xff);
}

TEST_F(Hardening, AVdbChunkSizeBeyondTheFileIsRefusedBeforeOpenVdbAllocatesIt) {
    bakeChainmail();
    // The grid's data (its leaves) starts at the offset in bytes 108-115 of the descriptor. The
    // first leaf: its 64-byte value mask, a compression flag (0 for distile's level sets: no
    // inactive values follow), then the blosc chunk's 64-bit size, which OpenVDB allocates.
    std::string bytes = readText(path("level.vdb"));
    const std::uint64_t data = field64(bytes, 108);
    ASSERT_LT(data + 73, bytes.size());
    ASSERT_EQ(bytes[data + 64], 0);
    const std::uint64_t chunkSize = field64(bytes, data + 65);
    ASSERT_GT(chunkSize, 0u);
    ASSERT_LT(chunkSize, bytes.size());
    setField64(bytes, data + 65, std::uint64_t(1) << 40);
    writeText(path("chunk.vdb"), bytes);
    const std::string chunkAt = "compressed chunk size at byte " + std::to_string(data + 65);
    EXPECT_EQ(expectInputError({"bake", "vdb", "chunk.vdb", "-o", "t2.exr"}, "t2.exr",
                               {"chunk.vdb", chunkAt, "1099511627776"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"check", "tile.exr", "--against", "chunk.vdb"}, "none",
                               {"chunk.vdb", chunkAt})
                  .status,
              cli::kExitInput);
    // The blosc header inside the chunk says how many bytes it decompresses to (bytes 4-7): the
    // leaf's active values as floats (4 bytes each, 64 bits of the mask per 8 bytes); another
    // count is refused.
    bytes = readText(path("level.vdb"));
    std::uint64_t active = 0;
    for (int word = 0; word < 8; ++word) active += std::popcount(field64(bytes, data + 8 * word));
    ASSERT_EQ(field64(bytes, data + 73 + 4) & 0xffffffffu, 4 * active);
    bytes[data + 73 + 5] = char(bytes[data + 73 + 5] ^ 0x40);
    writeText(path("blosc.vdb"), bytes);
    EXPECT_EQ(expectInputError({"bake", "vdb", "blosc.vdb", "-o", "t2.exr"}, "t2.exr",
                               {"blosc.vdb", "blosc header",
                                "accepted: " + std::to_string(4 * active) + " bytes"})
                  .status,
              cli::kExitInput);
    // Found by fuzzing (fuzz/corpus/level_set_vdb/delayed_load_blosc_past_buffer.vdb): the
    // grid's delayed-load metadata (a leaf count, then its mask as a blosc buffer of a 32-bit
    // size) whose blosc header claims one byte more than the buffer holds; blosc read past
    // OpenVDB's copy of it.
    bytes = readText(path("level.vdb"));
    const std::size_t delayed = bytes.find("__delayedload");
    ASSERT_NE(delayed, std::string::npos);
    const std::size_t maskBuffer = delayed + 13 + 4 + 4;  // type name, value size, leaf count
    const std::uint64_t stored = field64(bytes, maskBuffer) & 0xffffffffu;
    ASSERT_GE(stored, 16u);
    ASSERT_EQ(field64(bytes, maskBuffer + 4 + 12) & 0xffffffffu, stored);  // blosc's cbytes
    bytes[maskBuffer + 4 + 12] = char(bytes[maskBuffer + 4 + 12] + 1);
    writeText(path("delayed.vdb"), bytes);
    EXPECT_EQ(expectInputError({"bake", "vdb", "delayed.vdb", "-o", "t2.exr"}, "t2.exr",
                               {"delayed.vdb", "delayed-load blosc header",
                                "from at most " + std::to_string(stored)})
                  .status,
              cli::kExitInput);
}

/// The offset of the 32-bit size of EXR attribute `name` in `bytes` (after its name and type).
std::size_t exrAttributeSize(const std::string& bytes, const std::string& name) {
    const std::size_t at = bytes.find(name + '\0');
    EXPECT_NE(at, std::string::npos) << name;
    return bytes.find('\0', at + name.size() + 1) + 1;
}

TEST_F(Hardening, ATileExrHeaderIsWalkedBeforeOpenExrAllocates) {
    bakeChainmail();
    const std::string tile = readText(path("tile.exr"));
    // An attribute size far past the end of the file: OpenEXR took 2.2 GB on it.
    std::string bytes = tile;
    const std::size_t size = exrAttributeSize(bytes, "distile:units");
    bytes[size + 3] = 0x7f;
    writeText(path("attribute.exr"), bytes);
    EXPECT_EQ(expectInputError({"check", "attribute.exr"}, "none",
                               {"attribute.exr", "attribute size at byte " + std::to_string(size),
                                "'distile:units'", "bytes of the file follow"})
                  .status,
              cli::kExitInput);
    // A data window of 65536 x 65536 pixels: 16 GiB as floats.
    bytes = tile;
    const std::size_t window = exrAttributeSize(bytes, "dataWindow") + 4;
    for (const std::size_t corner : {window + 8, window + 12}) {
        bytes[corner] = char(0xff);
        bytes[corner + 1] = char(0xff);
        bytes[corner + 2] = 0;
        bytes[corner + 3] = 0;
    }
    writeText(path("window.exr"), bytes);
    EXPECT_EQ(expectInputError({"check", "window.exr"}, "none",
                               {"window.exr", "65536x65536 image", "memory"})
                  .status,
              cli::kExitInput);
    // The version field's multi-part flag (bit 12): distile writes single-part files only.
    bytes = tile;
    bytes[5] = char(bytes[5] | 0x10);
    writeText(path("parts.exr"), bytes);
    EXPECT_EQ(expectInputError({"check", "parts.exr"}, "none",
                               {"parts.exr", "version field", "multi-part", "single-part"})
                  .status,
              cli::kExitInput);
    // The file cut short: the offset table points past its end.
    writeText(path("cut.exr"), tile.substr(0, tile.size() - 100));
    EXPECT_EQ(
        expectInputError({"check", "cut.exr"}, "none", {"cut.exr", "chunk", "truncated"}).status,
        cli::kExitInput);
}

TEST_F(Hardening, ImagesLargerThanTheMemoryBudgetAreRefused) {
    // A PNG header of 16000 x 16000 RGB pixels (and no pixel data): within the sizes the
    // readers accept, but 3 GB as float pixels.
    const unsigned char png[] = {0x89, 'P', 'N',  'G',  '\r', '\n', 0x1a, '\n', 0,    0,
                                 0,    13,  'I',  'H',  'D',  'R',  0,    0,    0x3e, 0x80,
                                 0,    0,   0x3e, 0x80, 8,    2,    0,    0,    0};
    std::string bytes(reinterpret_cast<const char*>(png), sizeof png);
    // Its CRC, so that only the size is wrong.
    std::uint32_t crc = 0xffffffffu;
    for (std::size_t i = 12; i < bytes.size(); ++i) {
        crc ^= static_cast<unsigned char>(bytes[i]);
        for (int k = 0; k < 8; ++k) crc = (crc & 1) ? 0xedb88320u ^ (crc >> 1) : crc >> 1;
    }
    crc = ~crc;
    for (int k = 3; k >= 0; --k) bytes += char((crc >> (8 * k)) & 0xff);
    // An empty IDAT and the IEND, each with its CRC.
    const unsigned char idat[] = {0, 0, 0, 0, 'I', 'D', 'A', 'T', 0x35, 0xaf, 0x06, 0x1e};
    bytes.append(reinterpret_cast<const char*>(idat), sizeof idat);
    const unsigned char iend[] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82};
    bytes.append(reinterpret_cast<const char*>(iend), sizeof iend);
    writeText(path("wide.png"), bytes);
    EXPECT_EQ(expectInputError({"bake", "heightmap", "wide.png", "-o", "t.exr"}, "t.exr",
                               {"wide.png", "memory"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"compare", "wide.png", "wide.png", "-o", "d.png"}, "d.png",
                               {"wide.png", "memory"})
                  .status,
              cli::kExitInput);
}

// ---------------------------------------------------------------------------------------------
// Options whose cost grows with their value have an upper bound.

TEST_F(Hardening, BenchRefusesAnOutputThatIsNoFolder) {
    // -o "" wrote its scenes into the working folder; a file gave a raw filesystem error.
    writeText(path("results.txt"), "x");
    EXPECT_EQ(expectInputError({"bench", "--quick", "-o", ""}, "scenes", {"-o", "is empty"}).status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"bench", "--quick", "-o", "results.txt"}, "scenes",
                               {"-o", "'results.txt' is a file"})
                  .status,
              cli::kExitInput);
}

TEST_F(Hardening, AnOptionErrorPointsToItsCommandsHelp) {
    // A bad value of a command's option sent the user to `distile --help`, which does not list
    // the command's options.
    EXPECT_EQ(expectInputError(
                  {"render", "--no-skip", "adaptive-budget"}, "none",
                  {"--no-skip", "adaptive-budget", "empty-space", "(see distile render --help)"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"check", "--samples", "x", "t.exr"}, "none",
                               {"--samples", "(see distile check --help)"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(
        expectInputError({"--threads", "0"}, "none", {"--threads", "(see distile --help)"}).status,
        cli::kExitInput);
}

TEST_F(Hardening, AWordThatIsNoCommandIsNamedWithTheCommands) {
    // CLI11 said "A subcommand is required" for a misspelt command, without naming the word.
    EXPECT_EQ(expectInputError({"rendr", "-o", "x.png"}, "none",
                               {"'rendr' is not a command", "bake, render, check", "--help"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"--threads", "2", "--frob"}, "none",
                               {"'--frob' is not an option", "render"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({}, "none", {"a command is required", "bake, render"}).status,
              cli::kExitInput);
}

TEST_F(Hardening, ABadThreadCountPointsToTheHelpThatListsIt) {
    // --threads is distile's own option and may follow a command; the help of that command
    // does not list it, so the hint names distile --help, while a command's option names its own.
    for (const std::vector<std::string>& args :
         {std::vector<std::string>{"--threads", "0", "render", "-o", "out.png"},
          std::vector<std::string>{"render", "--threads", "0", "-o", "out.png"}}) {
        EXPECT_EQ(
            expectInputError(args, "out.png", {"--threads", "'0'", "(see distile --help)"}).status,
            cli::kExitInput);
    }
    EXPECT_EQ(expectInputError({"render", "--width", "0", "-o", "out.png"}, "out.png",
                               {"--width", "(see distile render --help)"})
                  .status,
              cli::kExitInput);
}

TEST_F(Hardening, AValueThatIsNotANumberNamesItsOptionAndWhatItTakes) {
    // Options without a range of their own were refused in CLI11's words ("Could not convert:
    // --epsilon = abc"): now the option, the value and the kind of number, as every other error.
    EXPECT_EQ(expectInputError({"render", "--epsilon", "abc", "-o", "out.png"}, "out.png",
                               {"--epsilon: 'abc' is not accepted; give a number",
                                "(see distile render --help)"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(
        expectInputError(
            {"bake", "chainmail", "--rings-per-row", "x", "-o", "out.exr"}, "out.exr",
            {"--rings-per-row: 'x' is not accepted; give an integer", "(see distile bake --help)"})
            .status,
        cli::kExitInput);
    EXPECT_EQ(
        expectInputError({"bake", "mesh", "m.obj", "--offset", "a", "b", "c", "-o", "out.exr"},
                         "out.exr", {"--offset: 'a,b,c' is not accepted; give numbers"})
            .status,
        cli::kExitInput);
}

TEST_F(Hardening, CheckSeedsAreUnsigned64BitIntegers) {
    // CLI11 took -1 as 2^64 - 1 and clamped 2^64: the run then checked other points than asked.
    bakeChainmail();
    for (const std::string seed : {"-1", "18446744073709551616", "1.5"}) {
        EXPECT_EQ(expectInputError({"check", "tile.exr", "--seed", seed}, "none",
                                   {"--seed", seed, "[0, 2^64 - 1]"})
                      .status,
                  cli::kExitInput);
    }
}

TEST_F(Hardening, AScenesTrianglesHaveAnUpperBound) {
    // 1000 built-in spheres of 9030 triangles: each object alone is small, all of them would take
    // about 4.4 GB to render (and 20 000 of them grew past 10 GB). The loader stops at the object
    // that passes 2^23 triangles, within this test's 2 GB.
    std::string scene = R"({"image": {"width": 32, "height": 24}, "objects": [)";
    for (int i = 0; i < 1000; ++i)
        scene += std::string(i ? "," : "") + R"({"mesh": "sphere", "transform": {"scale": 0.01}})";
    scene += "]}";
    writeText(path("scene.json"), scene);
    EXPECT_EQ(expectInputError({"render", "scene.json", "-o", "out.png"}, "out.png",
                               {"scene.json: objects[929].mesh", "8392320", "8388608"})
                  .status,
              cli::kExitInput);
}

TEST_F(Hardening, CostlyOptionsHaveUpperBounds) {
    // The widest band of a 64x64x8 tile is 16 texels.
    EXPECT_EQ(expectInputError(
                  {"bake", "chainmail", "--size", "64x64x8", "--band", "1024", "-o", "t.exr"},
                  "t.exr", {"--band", "1024", "16"})
                  .status,
              cli::kExitInput);
    const std::string ring = sourceFile("data/meshes/ring.obj");
    EXPECT_EQ(expectInputError(
                  {"bake", "mesh", ring, "--size", "64x64x8", "--scale", "1000", "-o", "t.exr"},
                  "t.exr", {"detail mesh", "footprints"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"bake", "mesh", ring, "--size", "64x64x8", "--scale", "1e-300",
                                "--offset", "32,32,4", "--unsigned", "-o", "t.exr"},
                               "t.exr", {"detail mesh", "less than one texel"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"bake", "mesh", ring, "--size", "64x64x8", "--scale", "8",
                                "--offset", "1e6,-1e6,1e6", "-o", "t.exr"},
                               "t.exr", {"detail mesh", "outside the tile"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"check", "t.exr", "--samples", "100000000"}, "none", {"--samples"})
                  .status,
              cli::kExitInput);
    writeText(path("bare.json"), kBareScene);
    // An image past 2^24 pixels is refused for its size, whatever the sample count; within it,
    // the samples per pixel are what pass the bound.
    EXPECT_EQ(expectInputError(
                  {"render", "bare.json", "-o", "r.png", "--width", "16384", "--height", "16384"},
                  "r.png", {"--width", "16384x16384", "2^24 pixels"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"render", "bare.json", "-o", "r.png", "--width", "4096", "--height",
                                "4096", "--spp", "2"},
                               "r.png", {"--spp", "2^24"})
                  .status,
              cli::kExitInput);
    // A count that is no integer is told so, not that it is out of range.
    EXPECT_EQ(expectInputError({"render", "bare.json", "-o", "r.png", "--width", "8.5"}, "r.png",
                               {"--width", "'8.5'", "an integer in [1, 16384]"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError({"render", "bare.json", "-o", "r.png", "--spp", "0"}, "r.png",
                               {"--spp", "'0'", "an integer in [1, 256]"})
                  .status,
              cli::kExitInput);
    const std::string sheet = sourceFile("data/scenes/sheet.json");
    EXPECT_EQ(expectInputError({"render", sheet, "-o", "r.png", "--reference", "world-levelset",
                                "--reference-voxels", "1e-30"},
                               "r.png", {"--reference-voxels"})
                  .status,
              cli::kExitInput);
}

TEST_F(Hardening, FlagsARenderWouldIgnoreAreRefused) {
    // The tile renderer's flags beside a world reference, the level set's voxels beside any
    // other reference: each once ignored without a word.
    const std::string sheet = sourceFile("data/scenes/sheet.json");
    for (const char* flag : {"--iterations=8", "--shadows=none", "--no-shadows", "--spp=4",
                             "--shell=planar", "--no-skip=empty-space"}) {
        const std::string name = std::string(flag).substr(0, std::string(flag).find('='));
        EXPECT_EQ(expectInputError({"render", sheet, "-o", "r.png", "--reference", "world", flag},
                                   "r.png", {name + ": does not apply to --reference world"})
                      .status,
                  cli::kExitInput);
    }
    for (const char* reference : {"--reference=analytic", "--reference=world"}) {
        EXPECT_EQ(
            expectInputError({"render", sheet, "-o", "r.png", reference, "--reference-voxels", "2"},
                             "r.png",
                             {"--reference-voxels: applies to --reference "
                              "world-levelset only"})
                .status,
            cli::kExitInput);
    }
}

TEST_F(Hardening, AWorldLevelSetBeyondTheMemoryBudgetIsRefusedNotAborted) {
    limitRuns({60, kTwoGigabytesKiB});  // building the world mesh takes a few seconds
    EXPECT_EQ(expectInputError({"render", sourceFile("data/scenes/sheet.json"), "--width", "64",
                                "--height", "48", "--reference", "world-levelset",
                                "--reference-voxels", "16", "-o", "r.png"},
                               "r.png", {"voxels per texel", "16", "GB"})
                  .status,
              cli::kExitInput);
}

// ---------------------------------------------------------------------------------------------
// No partial output: every output is checked before the work and written together after it.

TEST_F(Hardening, AnOutputThatCannotBeWrittenLeavesNoOtherOutput) {
    const std::vector<std::string> bake = {"bake", "chainmail", "--size", "64x64x8", "-o", "o.exr"};
    auto with = [&](std::initializer_list<std::string> more) {
        std::vector<std::string> arguments = bake;
        arguments.insert(arguments.end(), more);
        return arguments;
    };
    EXPECT_EQ(
        expectInputError(with({"--vdb", "/proc/o.vdb"}), "o.exr", {"--vdb", "/proc/o.vdb"}).status,
        cli::kExitInput);
    EXPECT_EQ(expectInputError(with({"--png8", "/proc/o.png"}), "o.exr", {"--png8", "/proc/o.png"})
                  .status,
              cli::kExitInput);
    fs::create_directories(path("folder.vdb"));
    EXPECT_EQ(
        expectInputError(with({"--vdb", "folder.vdb"}), "o.exr", {"--vdb", "folder.vdb", "folder"})
            .status,
        cli::kExitInput);
    EXPECT_EQ(expectInputError(with({"--vdb", "same.vdb", "--png8", "o.png", "--png16", "o.png"}),
                               "o.exr", {"--png16", "o.png"})
                  .status,
              cli::kExitInput);
    // A render's image and AOVs.
    writeText(path("bare.json"), kBareScene);
    EXPECT_EQ(expectInputError(
                  {"render", "bare.json", "-o", "/proc/r.png", "--width", "8", "--height", "8"},
                  "r.png", {"-o", "/proc/r.png"})
                  .status,
              cli::kExitInput);
    // Before the scene is read (its tiles baked, for minutes maybe): the output is what the
    // message names, not the scene's missing tile.
    writeText(path("missing_tile.json"),
              R"({"objects": [{"mesh": "plane", "material": {"tile": "missing.exr"}}]})");
    EXPECT_EQ(expectInputError({"render", "missing_tile.json", "-o", "/proc/r.png"}, "r.png",
                               {"-o", "/proc/r.png"})
                  .status,
              cli::kExitInput);
    fs::create_directories(path("image_folder.png"));
    EXPECT_EQ(expectInputError(
                  {"render", "missing_tile.json", "-o", "image_folder.png", "--reference", "world"},
                  "r.png", {"-o", "image_folder.png", "is a folder"})
                  .status,
              cli::kExitInput);
}

TEST_F(Hardening, AWriteTheSystemRefusesIsRefusedOutputNamingTheFile) {
    // Files of at most 32 KiB (ulimit -f 64): a longer write fails with EFBIG, as a full disk's
    // with ENOSPC. Each such write was an "internal failure" (exit 3) naming a temporary file;
    // and OpenVDB, which never checks its stream, left a truncated .vdb reported as written.
    limitRuns({10, kTwoGigabytesKiB, 64});
    const std::vector<std::string> grating = {
        "bake", "grating",      "--size", "32x32x8",       "--bars", "2",           "--bar-width",
        "6",    "--bar-height", "2",      "--edge-radius", "0.5",    "--layer-gap", "0.5"};
    auto bake = [&](std::initializer_list<std::string> outputs) {
        std::vector<std::string> arguments = grating;
        arguments.insert(arguments.end(), outputs);
        return arguments;
    };
    // The tile (5 KB) fits and its level set (48 KB) does not: neither is written.
    EXPECT_EQ(expectInputError(bake({"-o", "g.exr", "--vdb", "g.vdb"}), "g.exr",
                               {"g.vdb: writing failed", "File too large"})
                  .status,
              cli::kExitInput);
    // A plane under a noise texture: its render does not compress into 32 KiB either.
    Image noise(64, 64);
    std::mt19937 random(5);
    std::uniform_real_distribution<float> shade(0.1f, 0.9f);
    for (glm::vec3& texel : noise.rgbLinear) texel = glm::vec3(shade(random), shade(random), 0.5f);
    writeImage(noise, path("noise.png"));
    writeText(path("noise.json"), R"({"objects": [{"mesh": "plane", "material": {
                                     "color": "noise.png", "uv_scale": [4, 4]}}]})");
    for (const std::string image : {"r.png", "r.exr", "r.tif"}) {
        EXPECT_EQ(expectInputError(
                      {"render", "noise.json", "-o", image, "--width", "320", "--height", "256"},
                      image, {image + ": writing failed"})
                      .status,
                  cli::kExitInput);
    }
    limitRuns({10, kTwoGigabytesKiB});
    const RunResult fits = run(bake({"-o", "g.exr", "--vdb", "g.vdb"}));
    EXPECT_EQ(fits.status, 0) << fits.err;
    EXPECT_EQ(workEntries(), (std::set<std::string>{"noise.png", "noise.json", "g.exr", "g.vdb"}));
}

TEST_F(Hardening, ModulesAreLoadedBesideTheProgramNotBesideItsName) {
    // distile found its modules from argv[0]: run through $PATH, a symlink or `exec -a`, that
    // names the program relative to some other folder, and a file planted at ../lib from there
    // was loaded and run. A symlink bin/distile in the work folder, and beside it a lib/ of
    // planted modules that are not libraries at all.
    fs::create_directories(path("bin"));
    fs::create_directories(path("lib"));
    fs::create_symlink(DISTILE_BINARY, path("bin") / "distile");
    for (const char* module : {"libdistile_image_files_oiio.so", "libdistile_vdb_openvdb.so"})
        writeText(path("lib") / module, "not a library");
    const RunResult rendered =
        run({"render", "--width", "16", "--height", "12", "-o", "demo.tif"}, "bin/distile");
    EXPECT_EQ(rendered.status, 0) << rendered.err;
    EXPECT_TRUE(fs::is_regular_file(path("demo.tif")));
    const RunResult baked = run(
        {"bake", "grating", "--size", "32x32x8", "--bars", "2", "--bar-width", "6", "--bar-height",
         "2", "--edge-radius", "0.5", "--layer-gap", "0.5", "-o", "g.exr", "--vdb", "g.vdb"},
        "bin/distile");
    EXPECT_EQ(baked.status, 0) << baked.err;
    EXPECT_TRUE(fs::is_regular_file(path("g.vdb")));
}

TEST_F(Hardening, AnOutputThatCannotBeReplacedPutsBackTheOutputsReplacedBeforeIt) {
    // The targets are checked before the first rename, but a rename can still fail: a file
    // another user owns in a sticky folder, an immutable file (made here with chattr, which needs
    // root and a file system that keeps the flag). The tile was replaced and the run then failed
    // naming the temporary in a raw file system message.
    writeText(path("t.exr"), "the old tile");
    writeText(path("t.vdb"), "the old level set");
    const std::string immutable =
        "chattr +i " + shellQuote(path("t.vdb").string()) + " 2>/dev/null";
    if (std::system(immutable.c_str()) != 0) GTEST_SKIP() << "chattr +i is not available here";
    const RunResult run = expectInputError(
        {"bake", "grating", "--size", "32x32x8", "--bars", "2", "--bar-width", "6", "--bar-height",
         "2", "--edge-radius", "0.5", "--layer-gap", "0.5", "-o", "t.exr", "--vdb", "t.vdb"},
        "never.exr", {"--vdb: '", "t.vdb' cannot be replaced (", "nothing was written"});
    std::system(("chattr -i " + shellQuote(path("t.vdb").string())).c_str());
    EXPECT_EQ(run.status, cli::kExitInput);
    EXPECT_EQ(readText(path("t.exr")), "the old tile");
    EXPECT_EQ(readText(path("t.vdb")), "the old level set");
}

TEST_F(Hardening, AnOutputNameNearTheLongestAFileMayHaveIsWritten) {
    // A temporary ".NAME.partial-SCOPE-PID-N.EXT" is about 40 bytes longer than its target: names
    // of 226 to 255 bytes were refused ("refuses a new file (File name too long)"), though the
    // system takes them. Such a temporary now shortens the name and adds its hash.
    for (const std::size_t length : {250u, 255u}) {
        const std::string name = std::string(length - 4, 'a') + ".exr";
        const RunResult run = this->run({"bake", "grating", "--size", "32x32x8", "--bars", "2",
                                         "--bar-width", "6", "--bar-height", "2", "--edge-radius",
                                         "0.5", "--layer-gap", "0.5", "-o", name});
        EXPECT_EQ(run.status, 0) << run.err;
        EXPECT_EQ(workEntries(), std::set<std::string>{name});
        fs::remove(path(name));
    }
}

TEST_F(Hardening, AClosedPipeDoesNotEndARunHalfway) {
    // stdout and stderr a pipe whose reader has gone: the first line written raised SIGPIPE,
    // which ended the run with its temporaries left. Now the lines are lost and the run ends
    // with its outputs written.
    const std::string command =
        "cd " + shellQuote(work().string()) + " && (" + shellQuote(DISTILE_BINARY) +
        " render --width 16 --height 12 -o demo.png --aovs; echo $? > status.txt) 2>&1 | true";
    ASSERT_EQ(std::system(command.c_str()), 0);
    EXPECT_EQ(readText(path("status.txt")), "0\n");
    const std::set<std::string> entries = workEntries();
    EXPECT_TRUE(entries.count("demo.png"));
    for (const std::string& entry : entries) EXPECT_EQ(entry.find("partial"), std::string::npos);
}

TEST_F(Hardening, AKilledRunsReservedOutputsAreRemovedByTheNextRun) {
    // A killed run leaves its reservations ".NAME.partial-SCOPE-PID-N.EXT". PIDs above 2^22
    // (Linux's largest pid_max) belong to no process; this process is alive. The next write of
    // o.exr removes the dead run's reservation only, and leaves other targets' alone.
    const std::string scope = detail::temporaryScope();
    const std::string dead = ".o.partial-" + scope + "-4194399-0.exr";
    const std::string alive = ".o.partial-" + scope + "-" + std::to_string(::getpid()) + "-7.exr";
    const std::string other = ".p.partial-" + scope + "-4194399-0.exr";
    for (const std::string& name : {dead, alive, other}) writeText(path(name), "x");
    const RunResult bake = run({"bake", "chainmail", "--size", "64x64x8", "-o", "o.exr"});
    ASSERT_EQ(bake.status, 0) << bake.err;
    EXPECT_FALSE(fs::exists(path(dead)));
    EXPECT_TRUE(fs::exists(path(alive)));
    EXPECT_TRUE(fs::exists(path(other)));
    EXPECT_TRUE(fs::exists(path("o.exr")));
}

TEST_F(Hardening, AnotherContainersTemporaryIsLeftUntilAWeekOld) {
    // Two containers sharing a folder each have their own process 7. A temporary of another
    // scope (machine boot and PID namespace) with a PID that is dead here was removed as stale
    // while its run was still writing it; now it stays until unchanged for a week. The
    // reservation this run makes names its own scope.
    const std::string scope = detail::temporaryScope();
    ASSERT_EQ(scope.size(), detail::kScopeDigits);
    const std::string foreignScope = scope == "00000000" ? "00000001" : "00000000";
    const std::string live = ".o.partial-" + foreignScope + "-4194399-0.exr";
    const std::string weekOld = ".o.partial-" + foreignScope + "-4194399-1.exr";
    for (const std::string& name : {live, weekOld}) writeText(path(name), "x");
    fs::last_write_time(path(weekOld),
                        fs::file_time_type::clock::now() - std::chrono::hours(24 * 7 + 1));
    {
        OutputFiles outputs;
        const std::string reserved = outputs.add(path("q.exr"), "-o").filename().string();
        const std::string ours = ".q.partial-" + scope + "-" + std::to_string(::getpid()) + "-";
        EXPECT_EQ(reserved.substr(0, ours.size()), ours);
    }
    const RunResult bake = run({"bake", "chainmail", "--size", "64x64x8", "-o", "o.exr"});
    ASSERT_EQ(bake.status, 0) << bake.err;
    EXPECT_TRUE(fs::exists(path(live)));
    EXPECT_FALSE(fs::exists(path(weekOld)));
    EXPECT_TRUE(fs::exists(path("o.exr")));
}

TEST_F(Hardening, NoOutputReplacesOneOfTheCommandsInputs) {
    // Each command reads a file and is asked to write over it, under its own name or a link's.
    writeText(path("bare.json"), kBareScene);
    const std::vector<std::string> small = {"--width", "16", "--height", "12", "--aovs"};
    auto render = [&](const std::string& output, std::vector<std::string> more) {
        std::vector<std::string> arguments = {"render", "bare.json", "-o", output};
        arguments.insert(arguments.end(), small.begin(), small.end());
        arguments.insert(arguments.end(), more.begin(), more.end());
        return run(arguments);
    };
    ASSERT_EQ(render("a.png", {}).status, 0);
    ASSERT_EQ(render("b.png", {"--reference"}).status, 0);
    bakeChainmail();
    writeText(
        path("tiled.json"),
        R"({"objects": [{"mesh": "plane", "material": {"tile": "tile.exr", "depth": 0.1}}]})");
    fs::create_symlink("a.png", path("link.png"));
    fs::create_symlink("level.vdb", path("level_link.vdb"));

    struct Case {
        std::vector<std::string> arguments;
        std::string input;    ///< the file that must stay as it was
        std::string shownAs;  ///< the flag the message names
    };
    const std::vector<Case> cases = {
        {{"compare", "a.png", "b.png", "-o", "a.png"}, "a.png", "-o"},
        {{"compare", "a.png", "b.png", "-o", "d.png", "--heatmap", "b.depth.exr"},
         "b.depth.exr",
         "--heatmap"},
        {{"compare", "a.png", "b.png", "-o", "link.png"}, "a.png", "-o"},
        {{"render", "tiled.json", "-o", "tile.exr", "--width", "8", "--height", "8"},
         "tile.exr",
         "-o"},
        {{"bake", "heightmap", "a.normal.png", "-o", "h.exr", "--png8", "a.normal.png", "--size",
          "16x16x8"},
         "a.normal.png",
         "--png8"},
        // OpenVDB's reader lives in a module of its own: its reads are recorded all the same.
        {{"bake", "vdb", "level.vdb", "-o", "v.exr", "--vdb", "level.vdb", "--size", "32x32x8"},
         "level.vdb",
         "--vdb"},
        {{"bake", "vdb", "level_link.vdb", "-o", "v.exr", "--vdb", "./level.vdb", "--size",
          "32x32x8"},
         "level.vdb",
         "--vdb"},
    };
    for (const Case& bad : cases) {
        const std::string before = readText(path(bad.input));
        EXPECT_EQ(expectInputError(bad.arguments, "none",
                                   {bad.shownAs, "is also an input of this command"})
                      .status,
                  cli::kExitInput);
        EXPECT_EQ(readText(path(bad.input)), before) << bad.input << " was replaced";
    }
}

TEST_F(Hardening, CompareNamesTheFilesWhoseSizesDisagree) {
    writeText(path("bare.json"), kBareScene);
    for (const std::string width : {"16", "24"}) {
        ASSERT_EQ(run({"render", "bare.json", "-o", "w" + width + ".png", "--width", width,
                       "--height", "12", "--aovs"})
                      .status,
                  0);
    }
    EXPECT_EQ(expectInputError({"compare", "w16.png", "w24.png", "-o", "d.png"}, "d.png",
                               {"A (w16.png) is 16x12 but B (w24.png) is 24x12"})
                  .status,
              cli::kExitInput);
    fs::copy_file(path("w24.depth.exr"), path("w16.depth.exr"),
                  fs::copy_options::overwrite_existing);
    EXPECT_EQ(expectInputError({"compare", "w16.png", "w16.png", "-o", "d.png"}, "d.png",
                               {"A: w16.depth.exr is 24x12 but its image w16.png is 16x12"})
                  .status,
              cli::kExitInput);
}

TEST_F(Hardening, OutputsAreCheckedAgainBeforeTheFirstIsRenamed) {
    // All or none: a target that became a folder, or a file read since it was added, stops the
    // commit before anything is renamed, and the temporaries go with the OutputFiles.
    for (const bool folder : {true, false}) {
        SCOPED_TRACE(folder ? "a folder made since" : "an input read since");
        const fs::path first = path("first.txt"), second = path("second.txt");
        fs::remove_all(second);
        recordInputFiles();
        {
            OutputFiles outputs;
            writeText(outputs.add(first, "--first"), "1");
            writeText(outputs.add(second, "--second"), "2");
            if (folder) {
                fs::create_directory(second);
            } else {
                writeText(second, "read");
                requireRegularFile(second, "a text file");
            }
            EXPECT_THROW(outputs.commit(), InputError);
        }
        EXPECT_FALSE(fs::exists(first));
        EXPECT_EQ(workEntries(), std::set<std::string>{"second.txt"});
    }
}

TEST_F(Hardening, ATerminatedRunLeavesNoPartialFile) {
    // SIGTERM once the render has reserved its outputs (the temporaries exist): the run ends as
    // the signal ends it (status 128 + 15), and its temporaries are gone with it. (SIGTERM, not
    // SIGINT: a shell's background job ignores SIGINT.)
    const std::string command =
        "cd " + shellQuote(work().string()) + " && { " + shellQuote(DISTILE_BINARY) +
        " render -o x.png --width 2048 --height 2048 --aovs >/dev/null 2>&1 & pid=$!; "
        "for i in $(seq 200); do ls -a | grep -q partial && break; sleep 0.05; done; "
        "kill -TERM $pid; wait $pid; } 2>/dev/null";
    const int wait = std::system(command.c_str());
    ASSERT_TRUE(WIFEXITED(wait));
    EXPECT_EQ(WEXITSTATUS(wait), 128 + 15);
    EXPECT_TRUE(workEntries().empty()) << *workEntries().begin();
}

// ---------------------------------------------------------------------------------------------
// One line: no libpng line of its own, no raw bytes of the file quoted.

TEST_F(Hardening, ABrokenPngIsOneLineWithoutLibpngsOwn) {
    const std::string checker = readText(sourceFile("data/textures/checker.png"));
    writeText(path("truncated.png"), checker.substr(0, 300));
    EXPECT_EQ(expectInputError({"compare", "truncated.png", "truncated.png", "-o", "d.png"},
                               "d.png", {"truncated.png", "truncated"})
                  .status,
              cli::kExitInput);
    std::string flipped = checker;
    flipped[60] = char(flipped[60] ^ 0xff);
    writeText(path("flipped.png"), flipped);
    EXPECT_EQ(expectInputError({"bake", "heightmap", "flipped.png", "-o", "t.exr"}, "t.exr",
                               {"flipped.png"})
                  .status,
              cli::kExitInput);
}

TEST_F(Hardening, MeshErrorsQuoteOnlyPrintableBytes) {
    writeText(path("escape.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \x1b[31mX\r\n");
    EXPECT_EQ(expectInputError({"bake", "mesh", "escape.obj", "-o", "t.exr"}, "t.exr",
                               {"escape.obj", "?[31mX"})
                  .status,
              cli::kExitInput);
    const RunResult result = run({"bake", "mesh", "escape.obj", "-o", "t.exr"});
    for (char c : result.err.substr(0, result.err.size() - 1))
        EXPECT_TRUE(c >= 0x20 && c < 0x7f) << "byte " << int(c) << " in: " << result.err;
}

// ---------------------------------------------------------------------------------------------
// Options the documentation names that were silently ignored or took another syntax.

TEST_F(Hardening, SmallRingOptionsAreRefusedForTheEuropeanWeave) {
    EXPECT_EQ(expectInputError({"bake", "chainmail", "--small-ring-radius", "0.2", "--size",
                                "64x64x8", "-o", "t.exr"},
                               "t.exr", {"--small-ring-radius", "japanese4in1"})
                  .status,
              cli::kExitInput);
    expectSceneError(R"({"objects": [{"mesh": "plane", "material": {"tile":
        {"bake": "chainmail", "size": "64x64x8", "small_wire_radius": 0.03}}}]})",
                     {"objects[0].material.tile.small_wire_radius", "japanese4in1"});
}

TEST_F(Hardening, AnOptionOfAnotherDetailIsRefusedNotIgnored) {
    // Each bake took every detail's options and ignored those of the others.
    writeText(path("tet.obj"),
              "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n"
              "f 2 3 4\n");
    const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
        {{"heightmap", "tet.obj", "--scale", "5"}, "--scale: only for bake mesh and bake vdb"},
        {{"chainmail", "--bars", "2"}, "--bars: only for bake grating"},
        {{"grating", "--rings-per-row", "3"}, "--rings-per-row: only for bake chainmail"},
        {{"mesh", "tet.obj", "--iso", "0.5"}, "--iso: only for bake vdb"},
        {{"vdb", "tet.obj", "--height-texels", "3"}, "--height-texels: only for bake heightmap"},
        {{"grating", "--thickness", "2"}, "--thickness: only for bake mesh"},
    };
    for (const auto& [arguments, message] : cases) {
        std::vector<std::string> command = {"bake"};
        command.insert(command.end(), arguments.begin(), arguments.end());
        command.insert(command.end(), {"--size", "16x16x8", "-o", "t.exr"});
        EXPECT_EQ(expectInputError(command, "t.exr", {message}).status, cli::kExitInput);
    }
}

TEST_F(Hardening, AMeshPlacementErrorNamesTheMeshAndWhatToChange) {
    // They read "detail mesh: ..." under no flag, or under the recipe's "file".
    writeText(path("tall.obj"),
              "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 3\nf 1 3 2\nf 1 2 4\nf 1 4 3\n"
              "f 2 3 4\n");
    const std::vector<std::string> bake = {"bake", "mesh", "tall.obj", "-o", "t.exr", "--size"};
    auto with = [&](std::initializer_list<std::string> more) {
        std::vector<std::string> arguments = bake;
        arguments.insert(arguments.end(), more);
        return arguments;
    };
    EXPECT_EQ(expectInputError(with({"16x16x8"}), "t.exr",
                               {"--size: tall.obj: detail mesh: fitted", "48 texels tall"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError(with({"16x16x8", "--scale", "1e-9"}), "t.exr",
                               {"--scale: tall.obj", "less than one texel"})
                  .status,
              cli::kExitInput);
    EXPECT_EQ(expectInputError(with({"16x16x8", "--scale", "1", "--offset", "1e5,0,0"}), "t.exr",
                               {"--offset: tall.obj", "outside the tile"})
                  .status,
              cli::kExitInput);
    expectSceneError(R"({"objects": [{"mesh": "plane", "material": {"tile": {"bake": "mesh",
                         "file": "tall.obj", "size": "16x16x8", "scale": 1e-12}}}]})",
                     {"objects[0].material.tile.scale", "less than one texel"});
}

TEST_F(Hardening, AnEmptyFileNameIsRefusedNamingItsField) {
    // It named the scene's folder: "./: is a folder; a mesh file is expected".
    const std::vector<std::pair<std::string, std::string>> cases = {
        {R"({"mesh": ""})", "objects[0].mesh: is empty"},
        {R"({"mesh": "plane", "material": {"tile": ""}})", "objects[0].material.tile: is empty"},
        {R"({"mesh": "plane", "material": {"color": ""}})", "objects[0].material.color: is empty"},
        {R"({"mesh": "plane", "material": {"tile": {"bake": "mesh", "file": ""}}})",
         "objects[0].material.tile.file: is empty"},
    };
    for (const auto& [object, message] : cases)
        ASSERT_NO_FATAL_FAILURE(expectSceneError(R"({"objects": [)" + object + "]}", {message}));
}

TEST_F(Hardening, AKeyGivenTwiceInOneObjectIsRefused) {
    // The parser kept the last of the two silently: which was meant is unknown.
    ASSERT_NO_FATAL_FAILURE(
        expectSceneError(R"({"objects": [{"mesh": "plane", "mesh": "sphere"}]})",
                         {"objects[0]: key 'mesh' is given twice"}));
    ASSERT_NO_FATAL_FAILURE(expectSceneError(
        R"({"objects": [{"mesh": "plane"}, {"mesh": "plane", "material": {"uv_scale": [1, 1],
             "depth": 0.1, "uv_scale": [2, 2]}}]})",
        {"objects[1].material: key 'uv_scale' is given twice"}));
    ASSERT_NO_FATAL_FAILURE(expectSceneError(R"({"objects": [{"mesh": "plane"}], "objects": []})",
                                             {"top level: key 'objects' is given twice"}));
    // Not JSON: the parser's quote of the bytes it last read shows no raw byte.
    ASSERT_NO_FATAL_FAILURE(expectSceneError("{\"objects\": [{\"mesh\": \"pl\xff",
                                             {"not valid JSON", "last read: '\"pl?'"}));
}

TEST_F(Hardening, ASceneWithANulCharacterIsRefused) {
    // The JSON parser stopped at a NUL byte, a path ended at one ("chain.exr\u0000x" opened
    // chain.exr), and a message quoting one was cut short there.
    using namespace std::string_literals;
    ASSERT_NO_FATAL_FAILURE(
        expectSceneError(R"({"objects": [{"mesh": "plane"}]})"s + '\0' + "garbage",
                         {"scene.json: byte 32 is a NUL byte"}));
    writeText(path("bare.json"), kBareScene);
    ASSERT_NO_FATAL_FAILURE(expectSceneError(
        R"({"objects": [{"mesh": "plane", "material": {"tile": "bare.json\u0000x"}}]})",
        {"objects[0].material.tile: the text holds a NUL character"}));
    ASSERT_NO_FATAL_FAILURE(
        expectSceneError(R"({"objects": [{"mesh": "plane", "material\u0000": {}}]})",
                         {"objects[0]: a key holds a NUL character"}));
}

TEST_F(Hardening, ARefusedWeaveOrGratingValueNamesTheFlagOrKeyThatGaveIt) {
    EXPECT_EQ(
        expectInputError({"bake", "chainmail", "--rows", "3", "--size", "64x64x8", "-o", "t.exr"},
                         "t.exr", {"--rows: 3 is not accepted", "even"})
            .status,
        cli::kExitInput);
    EXPECT_EQ(expectInputError(
                  {"bake", "grating", "--bar-width", "100", "--size", "64x64x8", "-o", "t.exr"},
                  "t.exr", {"--bar-width: 100 is not accepted"})
                  .status,
              cli::kExitInput);
    // Under the key the scene gave, the older alias included.
    for (const char* key : {"rows", "rows_per_tile"}) {
        ASSERT_NO_FATAL_FAILURE(expectSceneError(
            R"({"objects": [{"mesh": "plane", "material": {"tile":
            {"bake": "chainmail", "size": "64x64x8", ")" +
                std::string(key) + R"(": 3}}}]})",
            {"objects[0].material.tile." + std::string(key) + ": 3 is not accepted", "even"}));
    }
    ASSERT_NO_FATAL_FAILURE(expectSceneError(R"({"objects": [{"mesh": "plane", "material": {"tile":
        {"bake": "grating", "size": "64x64x16", "bars": 4, "layer_gap": 0}}}]})",
                                             {"objects[0].material.tile.layer_gap: 0 is not"}));
    // A default the recipe did not override, under its key.
    ASSERT_NO_FATAL_FAILURE(expectSceneError(R"({"objects": [{"mesh": "plane", "material": {"tile":
        {"bake": "grating", "size": "64x64x16"}}}]})",
                                             {"objects[0].material.tile: bar_width (not given, "
                                              "its default): 8 is not accepted"}));
}

TEST_F(Hardening, AMeshRecipeWithFitFalseNeedsScaleOrOffset) {
    fs::copy_file(sourceFile("data/meshes/ring.obj"), path("ring.obj"));
    ASSERT_NO_FATAL_FAILURE(expectSceneError(R"({"objects": [{"mesh": "plane", "material": {"tile":
        {"bake": "mesh", "file": "ring.obj", "size": "32x32x8", "fit": false}}}]})",
                                             {"objects[0].material.tile.fit", "scale", "offset"}));
}

TEST_F(Hardening, CheckOffsetTakesCommasAsBakeMeshDoes) {
    fs::copy_file(sourceFile("data/meshes/ring.obj"), path("ring.obj"));
    const RunResult bake = run({"bake", "mesh", "ring.obj", "--scale", "14", "--offset", "32,32,4",
                                "--size", "64x64x8", "-o", "t.exr"});
    ASSERT_EQ(bake.status, 0) << bake.err;
    const RunResult check = run({"check", "t.exr", "--against", "ring.obj", "--scale", "14",
                                 "--offset", "32,32,4", "--samples", "2000"});
    EXPECT_EQ(check.status, 0) << check.err;
    EXPECT_NE(check.out.find("explicit placement"), std::string::npos) << check.out;
}

TEST_F(Hardening, CheckPlacesTheRecordedSourceOfAVdbTileEvenWhenDistileWroteIt) {
    // pipeline.md: `check T.exr` compares a `bake vdb` tile with the source it records, placed as
    // its params say; a source written by `bake --vdb` (another tile's size) was taken unplaced.
    bakeChainmail();
    const RunResult bake = run({"bake", "vdb", "level.vdb", "--scale", "1", "--offset", "0,0,0",
                                "--size", "32x32x8", "-o", "v.exr"});
    ASSERT_EQ(bake.status, 0) << bake.err;
    // A 32x32 cut of a 64x64 period does not repeat: the seam raises the RMS, not overestimates.
    const RunResult check = run({"check", "v.exr", "--samples", "5000", "--max-rms", "0.5"});
    EXPECT_EQ(check.status, 0) << check.err;
    EXPECT_NE(check.out.find("as placed by the bake"), std::string::npos) << check.out;
}

TEST_F(Hardening, AnImageTooLargeIsNamedWhereItsSizeCameFrom) {
    // No --width was given: the scene's image.width is what to change, not a flag.
    expectSceneError(R"({"image": {"width": 16384, "height": 1025},
        "objects": [{"mesh": "plane", "material": {"color": [0.8, 0.8, 0.8]}}]})",
                     {"scene.json: image.width", "16384x1025", "2^24 pixels"});
    expectSceneError(R"({"image": {"width": 4096, "height": 4096, "spp": 2},
        "objects": [{"mesh": "plane", "material": {"color": [0.8, 0.8, 0.8]}}]})",
                     {"scene.json: image.spp", "2^24"});
    // A flag that was given is named as the flag.
    const RunResult flagged = expectInputError(
        {"render", "scene.json", "-o", "out.png", "--spp", "3"}, "out.png", {"--spp", "2^24"});
    EXPECT_EQ(flagged.status, cli::kExitInput);
}

TEST_F(Hardening, CompareHelpEndsWithTheExitStatuses) {
    const RunResult help = run({"compare", "--help"});
    EXPECT_EQ(help.status, 0) << help.err;
    EXPECT_NE(help.out.find("Figures: hit error"), std::string::npos) << help.out;
    EXPECT_NE(help.out.find("Exit status: 0 success"), std::string::npos) << help.out;
}

// ---------------------------------------------------------------------------------------------
// Exit statuses (cli/app.h): 2 for refused input and memory, 3 for a bug.

int exitStatusOf(const std::function<void()>& command) {
    char program[] = "distile";
    char name[] = "run";
    char* argv[] = {program, name, nullptr};
    return cli::runCommandLine(
        2, argv, [&](CLI::App& app) { app.add_subcommand("run", "throws")->callback(command); });
}

TEST(ExitStatus, OneMeaningEach) {
    EXPECT_EQ(exitStatusOf([] {}), 0);
    EXPECT_EQ(exitStatusOf([] { throw InputError("x: bad"); }), cli::kExitInput);
    EXPECT_EQ(exitStatusOf([] { throw FormatError("f: broken"); }), cli::kExitInput);
    EXPECT_EQ(exitStatusOf([] { throw std::bad_alloc(); }), cli::kExitInput);
    EXPECT_EQ(exitStatusOf([] { throw InternalError("NaN pixel"); }), cli::kExitBug);
    EXPECT_EQ(exitStatusOf([] { throw std::runtime_error("unexpected"); }), cli::kExitBug);
    EXPECT_EQ(exitStatusOf([] { throw 42; }), cli::kExitBug);
    EXPECT_EQ(cli::kExitBug, 3);
}

template <typename Error>
[[noreturn]] void raise(const Error& error) {
    throw error;
}

/// Throws `error` out of a function that may not throw: std::terminate.
template <typename Error>
void throwThroughNoexcept(const Error& error) noexcept {
    raise(error);
}

TEST(ExitStatus, AnExceptionEscapingWhereNoneMayIsOneLineNotAnAbort) {
    EXPECT_EXIT(exitStatusOf([] { throwThroughNoexcept(std::bad_alloc()); }),
                ::testing::ExitedWithCode(cli::kExitInput), "distile: error: out of memory");
    EXPECT_EXIT(exitStatusOf([] { throwThroughNoexcept(std::runtime_error("lost")); }),
                ::testing::ExitedWithCode(cli::kExitBug),
                "distile: error: internal failure.*\\(lost\\)");
}

}  // namespace
}  // namespace distile
