// Tests of the tile files (sampler/tile_io.h) and the image files (render/image.h): exact round
// trips, the atlas layout pixel by pixel, the header metadata, and every rejection path.

#include <Imath/half.h>
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "common/detail/png_file.h"
#include "common/error.h"
#include "common/image_files.h"
#include "render/image.h"
#include "sampler/tile_io.h"
#include "tests/temp_folder.h"

namespace distile {
namespace {

namespace fs = std::filesystem;

/// A fresh folder under the system temporary folder per test, removed afterwards.
class SamplerIo : public ::testing::Test {
  protected:
    fs::path path(const std::string& name) const { return folder_.path(name); }

    /// Only `expected` in the folder: no temporary files left behind.
    std::vector<std::string> folderEntries() const {
        std::vector<std::string> names;
        for (const auto& entry : fs::directory_iterator(folder_.folder())) {
            names.push_back(entry.path().filename().string());
        }
        return names;
    }

  private:
    TempFolder folder_{"distile_sampler_io"};
};

/// A tile whose distances vary smoothly and cross zero, with every texel distinct enough that a
/// layout mistake shows.
Tile patternTile(const Size3& size) {
    Tile tile(size);
    for (int z = 0; z < size.depth; ++z) {
        for (int y = 0; y < size.height; ++y) {
            for (int x = 0; x < size.width; ++x) {
                tile.at(x, y, z) = 3.0f * std::sin(0.37f * x + 0.11f * y) + 0.5f * z - 2.0f +
                                   0.001f * float(x + y * size.width);
            }
        }
    }
    tile.provenance.source = "test:pattern";
    tile.provenance.params = R"({"amplitude": 3, "label": "a \"quoted\" value"})";
    return tile;
}

/// Raw one-channel pixels and header of an image, read with OpenImageIO directly.
struct RawImage {
    OIIO::ImageSpec spec;
    std::vector<float> pixels;
    float at(int x, int y) const { return pixels[std::size_t(x) + std::size_t(spec.width) * y]; }
};

RawImage readRaw(const fs::path& file) {
    auto input = OIIO::ImageInput::open(file.string());
    if (!input) throw std::runtime_error("test: cannot open " + file.string());
    RawImage raw{input->spec(), {}};
    raw.pixels.resize(std::size_t(raw.spec.width) * raw.spec.height * raw.spec.nchannels);
    if (!input->read_image(0, 0, 0, raw.spec.nchannels, OIIO::TypeDesc::FLOAT, raw.pixels.data())) {
        throw std::runtime_error("test: cannot read " + file.string());
    }
    return raw;
}

/// Rewrites an image with OpenImageIO after `edit` changed its header or pixels (float storage).
void rewriteRaw(const fs::path& file, const std::function<void(RawImage&)>& edit) {
    RawImage raw = readRaw(file);
    edit(raw);
    raw.spec.set_format(OIIO::TypeDesc::FLOAT);
    auto output = OIIO::ImageOutput::create(file.string());
    ASSERT_TRUE(output);
    ASSERT_TRUE(output->open(file.string(), raw.spec));
    ASSERT_TRUE(output->write_image(OIIO::TypeDesc::FLOAT, raw.pixels.data()));
    ASSERT_TRUE(output->close());
}

std::string formatErrorMessage(const fs::path& file) {
    try {
        readTileExr(file);
    } catch (const FormatError& error) {
        return error.what();
    }
    return "(no FormatError)";
}

TEST(AtlasGrid, ColumnsAreCeilSqrtAndRowsFollow) {
    EXPECT_EQ(atlasGrid(16).cols, 4);
    EXPECT_EQ(atlasGrid(16).rows, 4);
    EXPECT_EQ(atlasGrid(5).cols, 3);
    EXPECT_EQ(atlasGrid(5).rows, 2);
    EXPECT_EQ(atlasGrid(2).cols, 2);
    EXPECT_EQ(atlasGrid(2).rows, 1);
    EXPECT_EQ(atlasGrid(17).cols, 5);
    EXPECT_EQ(atlasGrid(17).rows, 4);
    EXPECT_EQ(atlasGrid(1).cols, 1);
    EXPECT_EQ(atlasGrid(1).rows, 1);
}

TEST_F(SamplerIo, FloatExrRoundTripIsExact) {
    const Tile tile = patternTile({16, 12, 5});
    writeTileExr(tile, path("tile.exr"));
    const Tile read = readTileExr(path("tile.exr"));
    ASSERT_EQ(read.size(), tile.size());
    for (std::size_t i = 0; i < tile.distancesTexels().size(); ++i) {
        ASSERT_EQ(read.distancesTexels()[i], tile.distancesTexels()[i]) << "texel index " << i;
    }
    EXPECT_EQ(read.provenance.source, tile.provenance.source);
    EXPECT_EQ(read.provenance.params, tile.provenance.params);
    EXPECT_EQ(tileHash(read), tileHash(tile));
    EXPECT_EQ(folderEntries(), std::vector<std::string>{"tile.exr"});
}

TEST_F(SamplerIo, HalfExrRoundTripRoundsDownWithinHalfPrecision) {
    Tile tile = patternTile({16, 12, 5});
    // Where rounding to nearest would go up: 1.0005 (halves 1 and 1 + 2^-10 apart, nearer the
    // upper), -1.0004 (nearer -1) and -1e-9 (nearer -0); exact ones stay.
    tile.at(0, 0, 0) = 1.0005f;
    tile.at(1, 0, 0) = -1.0004f;
    tile.at(2, 0, 0) = -1e-9f;
    tile.at(3, 0, 0) = 0.5f;
    tile.at(4, 0, 0) = -0.75f;
    writeTileExr(tile, path("tile.exr"), TileStorage::Half16);
    EXPECT_EQ(readRaw(path("tile.exr")).spec.format, OIIO::TypeDesc::HALF);
    const Tile read = readTileExr(path("tile.exr"));
    EXPECT_EQ(read.at(0, 0, 0), 1.0f);
    EXPECT_EQ(read.at(1, 0, 0), -1.0f - std::ldexp(1.0f, -10));
    EXPECT_EQ(read.at(2, 0, 0), -std::ldexp(1.0f, -24));  // the negative half nearest 0
    EXPECT_EQ(read.at(3, 0, 0), 0.5f);
    EXPECT_EQ(read.at(4, 0, 0), -0.75f);
    // Half has an 11-bit significand: rounding down lands within one spacing, 2^-10 relative;
    // below the smallest normal (2^-14) the spacing is absolute, 2^-24. Never above: a
    // conservative tile stays conservative.
    int lowered = 0;
    for (std::size_t i = 0; i < tile.distancesTexels().size(); ++i) {
        const float expected = tile.distancesTexels()[i];
        const float stored = read.distancesTexels()[i];
        const float spacing =
            std::max(std::abs(expected) * std::ldexp(1.0f, -10), std::ldexp(1.0f, -24));
        ASSERT_LE(stored, expected) << "texel index " << i;
        ASSERT_GT(stored, expected - spacing) << "texel index " << i;
        lowered += stored < expected;
    }
    EXPECT_GT(lowered, 100);  // the pattern's values are mostly not halves
}

TEST_F(SamplerIo, HalfStorageRejectsDistancesBeyondHalfRange) {
    Tile tile({4, 4, 2}, 1.0f);
    tile.at(1, 2, 1) = 1.0e5f;
    EXPECT_THROW(writeTileExr(tile, path("tile.exr"), TileStorage::Half16), InputError);
    EXPECT_TRUE(folderEntries().empty());
    writeTileExr(tile, path("tile.exr"), TileStorage::Float32);  // float holds it
    // ... but no bake writes it: beyond twice the widest band (+-8 texels here), reading
    // refuses it.
    EXPECT_THROW(readTileExr(path("tile.exr")), FormatError);
}

TEST_F(SamplerIo, EmptyProvenanceIsSpelledOut) {
    writeTileExr(Tile({4, 4, 2}, 1.0f), path("tile.exr"));
    const Tile read = readTileExr(path("tile.exr"));
    EXPECT_EQ(read.provenance.source, "unknown");
    EXPECT_EQ(read.provenance.params, "{}");
}

TEST_F(SamplerIo, SourceFileIsRecordedRelativeToTheTileAndResolvedOnReading) {
    fs::create_directories(path("meshes"));
    fs::create_directories(path("tiles"));
    Tile tile = patternTile({8, 8, 2});
    tile.provenance.sourceFile = fs::absolute(path("meshes/ring.obj"));
    tile.provenance.sourceHash = "0123456789abcdef";
    writeTileExr(tile, path("tiles/tile.exr"));
    const OIIO::ImageSpec spec = readRaw(path("tiles/tile.exr")).spec;
    EXPECT_EQ(spec.get_string_attribute("distile:source_file"), "../meshes/ring.obj");
    EXPECT_EQ(spec.get_string_attribute("distile:source_hash"), "0123456789abcdef");
    // Read back as the absolute path, from wherever the tile is read.
    const Tile read = readTileExr(path("tiles/tile.exr"));
    EXPECT_EQ(read.provenance.sourceFile, fs::absolute(path("meshes/ring.obj")).lexically_normal());
    EXPECT_EQ(read.provenance.sourceHash, "0123456789abcdef");
    // A tile without a source file (procedural, or written before the keys existed) has none.
    writeTileExr(patternTile({8, 8, 2}), path("plain.exr"));
    EXPECT_FALSE(readRaw(path("plain.exr")).spec.find_attribute("distile:source_file"));
    EXPECT_TRUE(readTileExr(path("plain.exr")).provenance.sourceFile.empty());
}

TEST_F(SamplerIo, AtlasPlacesSliceKAtColumnKModColsRowKDivCols) {
    const Size3 size{16, 16, 5};
    Tile tile(size);
    // Value = slice index k, plus a distinct fraction per (x, y) so a transposed slice shows.
    for (int z = 0; z < size.depth; ++z) {
        for (int y = 0; y < size.height; ++y) {
            for (int x = 0; x < size.width; ++x) {
                tile.at(x, y, z) = float(z) + float(x + size.width * y) / 1024.0f;
            }
        }
    }
    writeTileExr(tile, path("tile.exr"));
    const RawImage raw = readRaw(path("tile.exr"));
    const int cols = 3;
    const int rows = 2;
    ASSERT_EQ(raw.spec.width, cols * size.width);
    ASSERT_EQ(raw.spec.height, rows * size.height);
    ASSERT_EQ(raw.spec.nchannels, 1);
    EXPECT_EQ(raw.spec.channelnames[0], "distance");
    for (int k = 0; k < size.depth; ++k) {
        for (int y = 0; y < size.height; ++y) {
            for (int x = 0; x < size.width; ++x) {
                ASSERT_EQ(raw.at(k % cols * size.width + x, k / cols * size.height + y),
                          tile.at(x, y, k))
                    << "texel (" << x << ", " << y << ", " << k << ")";
            }
        }
    }
    // The sixth cell (column 2, row 1) is unused: it holds the tile's largest distance.
    const float maxDistance = tile.at(size.width - 1, size.height - 1, size.depth - 1);
    EXPECT_EQ(raw.at(2 * size.width, size.height), maxDistance);
    EXPECT_EQ(raw.at(3 * size.width - 1, 2 * size.height - 1), maxDistance);
}

TEST_F(SamplerIo, DefaultTileIsA1024SquareAtlas) {
    Tile tile(Size3{}, 2.5f);
    writeTileExr(tile, path("tile.exr"));
    const RawImage raw = readRaw(path("tile.exr"));
    EXPECT_EQ(raw.spec.width, 1024);
    EXPECT_EQ(raw.spec.height, 1024);
    EXPECT_EQ(raw.spec.get_string_attribute("compression"), "zip");
}

TEST_F(SamplerIo, HeaderCarriesEveryDistileAttribute) {
    const Tile tile = patternTile({16, 16, 16});
    writeTileExr(tile, path("tile.exr"));
    const OIIO::ImageSpec spec = readRaw(path("tile.exr")).spec;
    EXPECT_EQ(spec.get_string_attribute("distile:size"), "16x16x16");
    EXPECT_EQ(spec.get_string_attribute("distile:layout"),
              "atlas 4x4 slice k at column k%4 row k/4, x fastest, texel centre at i+0.5");
    EXPECT_EQ(spec.get_string_attribute("distile:units"), "texels");
    EXPECT_EQ(spec.get_string_attribute("distile:source"), tile.provenance.source);
    EXPECT_EQ(spec.get_string_attribute("distile:params"), tile.provenance.params);
    EXPECT_EQ(spec.get_string_attribute("distile:version"), "0.1.0");
    const std::string hash = spec.get_string_attribute("distile:hash");
    ASSERT_EQ(hash.size(), 16u);
    EXPECT_EQ(std::stoull(hash, nullptr, 16), tileHash(tile));
}

TEST(TileHash, DependsOnSizeAndEveryValue) {
    Tile a({4, 4, 2}, 1.0f);
    Tile b({4, 2, 4}, 1.0f);  // same texels, other shape
    EXPECT_NE(tileHash(a), tileHash(b));
    const std::uint64_t before = tileHash(a);
    a.at(3, 3, 1) = std::nextafter(1.0f, 2.0f);  // one ulp
    EXPECT_NE(tileHash(a), before);
}

TEST_F(SamplerIo, PlainExrIsNotADistileTile) {
    Image image(8, 8, glm::vec3(0.25f));
    writeImage(image, path("plain.exr"));
    EXPECT_NE(formatErrorMessage(path("plain.exr")).find("not a distile tile"), std::string::npos);
}

TEST_F(SamplerIo, ExrAndTiffRendersCarryNoWriteTime) {
    // OpenImageIO stamps a DateTime on files unless told otherwise: the same render written a
    // second later would differ.
    Image image(8, 8, glm::vec3(0.25f));
    for (const std::string name : {"plain.exr", "plain.tif"}) {
        writeImage(image, path(name));
        auto input = OIIO::ImageInput::open(path(name).string());
        ASSERT_TRUE(input) << name;
        EXPECT_EQ(input->spec().find_attribute("DateTime"), nullptr) << name;
    }
}

TEST_F(SamplerIo, PngNamedExrIsRejected) {
    Image image(8, 8, glm::vec3(0.25f));
    writeImage(image, path("plain.png"));
    fs::rename(path("plain.png"), path("fake.exr"));
    EXPECT_THROW(readTileExr(path("fake.exr")), FormatError);
}

TEST_F(SamplerIo, MissingFileIsAnInputError) {
    try {
        readTileExr(path("absent.exr"));
        FAIL() << "no exception";
    } catch (const InputError& error) {
        EXPECT_NE(std::string(error.what()).find("no such file"), std::string::npos);
    }
}

TEST_F(SamplerIo, TruncatedFileIsAFormatError) {
    writeTileExr(patternTile({64, 64, 4}), path("tile.exr"));
    const auto bytes = fs::file_size(path("tile.exr"));
    fs::resize_file(path("tile.exr"), bytes / 2);  // OpenEXR notices when opening
    EXPECT_THROW(readTileExr(path("tile.exr")), FormatError);
    writeTileExr(patternTile({64, 64, 4}), path("tile.exr"));
    fs::resize_file(path("tile.exr"), bytes - 64);  // only the last scanlines are missing
    EXPECT_THROW(readTileExr(path("tile.exr")), FormatError);
}

TEST_F(SamplerIo, ADamagedChunkIsAFormatErrorThatNothingElsePrints) {
    // The chunks are decoded side by side with OpenEXR's core library, whose default error
    // handler prints each error on stderr: the reader keeps the first and reports it once.
    writeTileExr(patternTile({64, 64, 4}), path("tile.exr"));
    std::string bytes;
    {
        std::ifstream in(path("tile.exr"), std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    // Inside the last chunks' compressed data, after the header and the offset table.
    std::fill_n(bytes.end() - 400, 200, char(0xff));
    std::ofstream(path("tile.exr"), std::ios::binary) << bytes;
    testing::internal::CaptureStderr();
    const std::string message = formatErrorMessage(path("tile.exr"));
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
    EXPECT_NE(message.find("tile.exr: cannot read the pixels ("), std::string::npos) << message;
    EXPECT_NE(message.find("); the file is truncated or corrupted"), std::string::npos) << message;
}

TEST_F(SamplerIo, ATileSavedInTilesByAnotherToolReadsTheSame) {
    // distile writes scanlines; a tile re-saved as a tiled OpenEXR (OpenImageIO here) is read
    // through OpenEXR's tiled path and gives the same distances.
    const Tile tile = patternTile({64, 64, 4});
    writeTileExr(tile, path("tile.exr"));
    rewriteRaw(path("tile.exr"), [](RawImage& raw) {
        raw.spec.tile_width = 32;
        raw.spec.tile_height = 32;
    });
    ASSERT_GT(readRaw(path("tile.exr")).spec.tile_width, 0);
    const Tile read = readTileExr(path("tile.exr"));
    ASSERT_EQ(read.size(), tile.size());
    EXPECT_TRUE(std::equal(read.distancesTexels().begin(), read.distancesTexels().end(),
                           tile.distancesTexels().begin()));
}

TEST_F(SamplerIo, GarbageFileIsAFormatError) {
    std::ofstream(path("garbage.exr")) << "this is not an image";
    EXPECT_THROW(readTileExr(path("garbage.exr")), FormatError);
}

TEST_F(SamplerIo, EditedPixelFailsTheHashCheck) {
    writeTileExr(patternTile({16, 16, 4}), path("tile.exr"));
    rewriteRaw(path("tile.exr"), [](RawImage& raw) { raw.pixels[17] += 0.25f; });
    EXPECT_NE(formatErrorMessage(path("tile.exr")).find("distile:hash"), std::string::npos);
}

TEST_F(SamplerIo, NonFiniteDistanceInFileIsAFormatError) {
    writeTileExr(patternTile({16, 16, 4}), path("tile.exr"));
    rewriteRaw(path("tile.exr"),
               [](RawImage& raw) { raw.pixels[5] = std::numeric_limits<float>::quiet_NaN(); });
    EXPECT_NE(formatErrorMessage(path("tile.exr")).find("texel (5, 0, 0)"), std::string::npos);
}

TEST_F(SamplerIo, DeclaredBandRoundTripsAndBoundsTheDistances) {
    Tile tile = patternTile({16, 16, 4});
    float largest = 0.0f;
    for (float d : tile.distancesTexels()) largest = std::max(largest, std::abs(d));
    tile.provenance.halfBandTexels = largest;
    writeTileExr(tile, path("tile.exr"));
    EXPECT_EQ(readTileExr(path("tile.exr")).provenance.halfBandTexels, double(largest));
    // A bake clamps at +band and lowers at most a tile depth below -band; beyond that a tile is
    // neither written nor read (a finite 3e38 with a valid hash rendered NaN).
    Tile beyond = tile;
    beyond.at(3, 0, 0) = largest + 0.5f;
    EXPECT_THROW(writeTileExr(beyond, path("beyond.exr")), InputError);
    beyond.at(3, 0, 0) = -largest - 4.5f;
    EXPECT_THROW(writeTileExr(beyond, path("beyond.exr")), InputError);
    beyond.at(3, 0, 0) = -largest - 3.5f;  // within the lowering's reach: written
    writeTileExr(beyond, path("lowered.exr"));
    EXPECT_EQ(readTileExr(path("lowered.exr")).at(3, 0, 0), -largest - 3.5f);
    std::vector<std::string> written = folderEntries();
    std::sort(written.begin(), written.end());
    EXPECT_EQ(written, (std::vector<std::string>{"lowered.exr", "tile.exr"}));
    Tile huge = patternTile({16, 16, 4});
    huge.at(5, 0, 0) = 12.0f;  // no band declared: any distance a bake of its size could make
    writeTileExr(huge, path("huge.exr"));
    rewriteRaw(path("huge.exr"),
               [](RawImage& raw) { raw.spec.attribute("distile:band_texels", 4.0f); });
    EXPECT_NE(formatErrorMessage(path("huge.exr")).find("outside the band"), std::string::npos);
    rewriteRaw(path("tile.exr"),
               [](RawImage& raw) { raw.spec.attribute("distile:band_texels", -1.0f); });
    EXPECT_NE(formatErrorMessage(path("tile.exr")).find("distile:band_texels"), std::string::npos);
    // Given as text, the band read as -1: "-1 is not a positive number".
    rewriteRaw(path("tile.exr"),
               [](RawImage& raw) { raw.spec.attribute("distile:band_texels", "8"); });
    EXPECT_NE(formatErrorMessage(path("tile.exr")).find("distile:band_texels is not a float"),
              std::string::npos);
    // One bound: the declared band replaces the bound by size (+-16 texels here), and may not
    // exceed it.
    rewriteRaw(path("huge.exr"),
               [](RawImage& raw) { raw.spec.attribute("distile:band_texels", 12.0f); });
    EXPECT_EQ(readTileExr(path("huge.exr")).at(5, 0, 0), 12.0f);
    rewriteRaw(path("huge.exr"),
               [](RawImage& raw) { raw.spec.attribute("distile:band_texels", 1e30f); });
    EXPECT_NE(formatErrorMessage(path("huge.exr")).find("at most 16 texels"), std::string::npos);
}

TEST_F(SamplerIo, ACheckVerdictRoundTripsAndAnyOtherTextIsAFormatError) {
    Tile tile = patternTile({16, 16, 4});
    writeTileExr(tile, path("unchecked.exr"));
    EXPECT_EQ(readTileExr(path("unchecked.exr")).provenance.check, "");
    tile.provenance.check = "beyond tolerances: RMS 0.2 texel (allowed 0.1)";
    writeTileExr(tile, path("tile.exr"));
    EXPECT_EQ(readTileExr(path("tile.exr")).provenance.check, tile.provenance.check);
    rewriteRaw(path("tile.exr"), [](RawImage& raw) {
        raw.spec.attribute("distile:check", "within tolerances: RMS 0.01 texel");
    });
    EXPECT_EQ(readTileExr(path("tile.exr")).provenance.check, "within tolerances: RMS 0.01 texel");
    rewriteRaw(path("tile.exr"),
               [](RawImage& raw) { raw.spec.attribute("distile:check", "looks fine to me"); });
    EXPECT_NE(formatErrorMessage(path("tile.exr")).find("distile:check 'looks fine to me'"),
              std::string::npos);
}

TEST_F(SamplerIo, DistancesBeyondTwiceTheWidestBandAreAFormatError) {
    // A 16x16x4 tile's widest band is 2 x 4 = 8 texels: it holds distances within +-16. Far
    // distances near the float range, with a valid hash, made the tracer compute NaN.
    const Size3 size{16, 16, 4};
    ASSERT_EQ(maxHalfBandTexels(size), 8.0f);
    Tile edge = patternTile(size);
    edge.at(3, 0, 0) = 16.0f;
    edge.at(4, 0, 0) = -16.0f;
    writeTileExr(edge, path("edge.exr"));
    EXPECT_EQ(readTileExr(path("edge.exr")).at(4, 0, 0), -16.0f);
    for (const float far : {16.01f, -3.4e38f}) {
        Tile tile = patternTile(size);
        tile.at(3, 0, 0) = far;
        writeTileExr(tile, path("far.exr"));
        const std::string message = formatErrorMessage(path("far.exr"));
        EXPECT_NE(message.find("texel (3, 0, 0)"), std::string::npos) << message;
        EXPECT_NE(message.find("+-16"), std::string::npos) << message;
    }
}

TEST_F(SamplerIo, SizeThatDisagreesWithTheAtlasIsAFormatError) {
    writeTileExr(patternTile({16, 16, 4}), path("tile.exr"));
    rewriteRaw(path("tile.exr"),
               [](RawImage& raw) { raw.spec.attribute("distile:size", "16x16x5"); });
    EXPECT_NE(formatErrorMessage(path("tile.exr")).find("atlas"), std::string::npos);
    rewriteRaw(path("tile.exr"),
               [](RawImage& raw) { raw.spec.attribute("distile:size", "16 by 16"); });
    EXPECT_NE(formatErrorMessage(path("tile.exr")).find("WxHxD"), std::string::npos);
}

TEST_F(SamplerIo, WrongChannelIsAFormatError) {
    writeTileExr(patternTile({16, 16, 4}), path("tile.exr"));
    rewriteRaw(path("tile.exr"), [](RawImage& raw) { raw.spec.channelnames = {"Y"}; });
    EXPECT_NE(formatErrorMessage(path("tile.exr")).find("'distance'"), std::string::npos);
}

TEST_F(SamplerIo, WritingIntoAMissingFolderLeavesNoFile) {
    const fs::path target = path("absent") / "tile.exr";
    EXPECT_THROW(writeTileExr(patternTile({4, 4, 2}), target), InputError);
    EXPECT_FALSE(fs::exists(target));
    EXPECT_TRUE(folderEntries().empty());
}

TEST_F(SamplerIo, NonFiniteTileIsNotWritten) {
    Tile tile({4, 4, 2}, 1.0f);
    tile.at(2, 1, 1) = std::numeric_limits<float>::infinity();
    EXPECT_THROW(writeTileExr(tile, path("tile.exr")), InputError);
    EXPECT_TRUE(folderEntries().empty());
}

TEST_F(SamplerIo, FailedRewriteKeepsTheGoodFile) {
    const Tile good = patternTile({8, 8, 2});
    writeTileExr(good, path("tile.exr"));
    Tile bad = good;
    bad.at(0, 0, 0) = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(writeTileExr(bad, path("tile.exr")), InputError);
    EXPECT_EQ(tileHash(readTileExr(path("tile.exr"))), tileHash(good));
    EXPECT_EQ(folderEntries(), std::vector<std::string>{"tile.exr"});
}

TEST_F(SamplerIo, PngNormalisesDistanceByTileDepth) {
    const Size3 size{8, 8, 4};
    Tile tile(size, 0.5f * float(size.depth));  // D/2 -> 0.5
    tile.at(1, 1, 0) = -3.0f;                   // inside material -> 0
    tile.at(2, 1, 0) = 10.0f * size.depth;      // far away -> 1
    tile.provenance.source = "test:constant";
    for (int bits : {8, 16}) {
        const fs::path file = path("tile" + std::to_string(bits) + ".png");
        writeTilePng(tile, file, bits);
        const RawImage raw = readRaw(file);
        EXPECT_EQ(raw.spec.format, bits == 8 ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::UINT16);
        ASSERT_EQ(raw.spec.width, 2 * size.width);
        ASSERT_EQ(raw.spec.height, 2 * size.height);
        const float step = bits == 8 ? 1.0f / 255.0f : 1.0f / 65535.0f;
        EXPECT_NEAR(raw.at(0, 0), 0.5f, step) << bits << " bits";
        EXPECT_NEAR(raw.at(size.width + 3, size.height + 5), 0.5f, step) << bits << " bits";
        EXPECT_EQ(raw.at(1, 1), 0.0f) << bits << " bits";
        EXPECT_EQ(raw.at(2, 1), 1.0f) << bits << " bits";
        // PNG keeps the attributes as text chunks.
        EXPECT_EQ(raw.spec.get_string_attribute("distile:size"), "8x8x4");
        EXPECT_EQ(raw.spec.get_string_attribute("distile:source"), tile.provenance.source);
    }
}

// The signed export keeps the inside: every distance comes back within half a code step
// (R / 65535 texels, R the largest |distance|), the largest |distance| sits on the end codes and
// 0 on the middle one.
TEST_F(SamplerIo, SignedPngRoundTripIsWithinOneStep) {
    const Size3 size{8, 8, 4};
    Tile tile(size);
    for (int z = 0; z < size.depth; ++z)
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x)
                tile.at(x, y, z) = 0.37f * float(x) - 0.61f * float(y) + 0.23f * float(z) - 0.5f;
    tile.at(3, 2, 1) = -6.5f;  // the largest |distance|: R
    tile.at(4, 2, 1) = 0.0f;
    tile.provenance.source = "test:ramp";
    const float range = signedPngRangeTexels(tile);
    EXPECT_EQ(range, 6.5f);
    writeSignedTilePng(tile, path("signed.png"));
    const RawImage raw = readRaw(path("signed.png"));
    ASSERT_EQ(raw.spec.format, OIIO::TypeDesc::UINT16);
    EXPECT_EQ(raw.spec.get_string_attribute("distile:png_range_texels"), "6.5");
    const float step = 2.0f * range / 65535.0f;
    double largestError = 0.0;
    for (int z = 0; z < size.depth; ++z) {
        const int left = (z % 2) * size.width, top = (z / 2) * size.height;  // 2 x 2 atlas
        for (int y = 0; y < size.height; ++y) {
            for (int x = 0; x < size.width; ++x) {
                const float decoded = raw.at(left + x, top + y) * 2.0f * range - range;
                largestError = std::max(largestError, double(std::abs(decoded - tile.at(x, y, z))));
            }
        }
    }
    EXPECT_LE(largestError, 0.5 * step + 1e-6);
    EXPECT_EQ(raw.at(size.width + 3, 2), 0.0f);                          // -R: code 0
    EXPECT_NEAR(raw.at(size.width + 4, 2), 32768.0f / 65535.0f, 1e-7f);  // 0: the middle code
}

TEST_F(SamplerIo, SignedPngRefusesNonFiniteDistancesAndOtherExtensions) {
    Tile tile({4, 4, 2});
    EXPECT_THROW(writeSignedTilePng(tile, path("tile.exr")), InputError);
    tile.at(1, 1, 1) = std::numeric_limits<float>::infinity();
    EXPECT_THROW(writeSignedTilePng(tile, path("tile.png")), InputError);
    EXPECT_TRUE(folderEntries().empty());
}

TEST_F(SamplerIo, PngBitDepthOtherThan8Or16IsAnInputError) {
    EXPECT_THROW(writeTilePng(Tile({4, 4, 2}), path("tile.png"), 12), InputError);
    EXPECT_TRUE(folderEntries().empty());
}

TEST(Srgb, TransferFunctionKnownValues) {
    EXPECT_FLOAT_EQ(srgbFromLinear(0.0f), 0.0f);
    EXPECT_FLOAT_EQ(srgbFromLinear(1.0f), 1.0f);
    EXPECT_NEAR(srgbFromLinear(0.5f), 0.735357f, 1e-5f);
    EXPECT_NEAR(srgbFromLinear(0.001f), 0.01292f, 1e-6f);  // linear segment
    for (float linear = 0.0f; linear <= 1.0f; linear += 0.01f) {
        EXPECT_NEAR(linearFromSrgb(srgbFromLinear(linear)), linear, 1e-5f);
    }
}

Image gradientImage() {
    Image image(37, 19);
    for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
            image.at(x, y) = glm::vec3(float(x) / (image.width - 1), float(y) / (image.height - 1),
                                       0.5f * float(x + y) / (image.width + image.height));
        }
    }
    return image;
}

TEST_F(SamplerIo, ImagePngRoundTripIsWithinSrgbQuantisation) {
    const Image image = gradientImage();
    writeImage(image, path("image.png"));
    const Image read = readImage(path("image.png"));
    ASSERT_EQ(read.width, image.width);
    ASSERT_EQ(read.height, image.height);
    // 8-bit codes round the sRGB-encoded value: at most half a code apart in encoded space.
    const float tolerance = 0.5f / 255.0f + 1e-5f;
    for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
            for (int c = 0; c < 3; ++c) {
                ASSERT_NEAR(srgbFromLinear(read.at(x, y)[c]), srgbFromLinear(image.at(x, y)[c]),
                            tolerance)
                    << "pixel (" << x << ", " << y << ") channel " << c;
            }
        }
    }
    // Row 0 is the top: the first row of the file is the first row of the image.
    EXPECT_EQ(readRaw(path("image.png")).spec.nchannels, 3);
}

TEST_F(SamplerIo, ImageExrAndTiffRoundTrips) {
    Image image = gradientImage();
    image.at(3, 4) = glm::vec3(7.5f, -0.25f, 100.0f);  // EXR keeps HDR and negative values
    writeImage(image, path("image.exr"));
    const Image exr = readImage(path("image.exr"));
    ASSERT_EQ(exr.rgbLinear.size(), image.rgbLinear.size());
    for (std::size_t i = 0; i < image.rgbLinear.size(); ++i) {
        ASSERT_EQ(exr.rgbLinear[i], image.rgbLinear[i]) << "pixel index " << i;
    }
    const Image clamped = gradientImage();
    writeImage(clamped, path("image.tif"));
    const Image tiff = readImage(path("image.tif"));
    for (std::size_t i = 0; i < clamped.rgbLinear.size(); ++i) {
        for (int c = 0; c < 3; ++c) {
            ASSERT_NEAR(srgbFromLinear(tiff.rgbLinear[i][c]),
                        srgbFromLinear(clamped.rgbLinear[i][c]), 0.5f / 65535.0f + 1e-5f);
        }
    }
}

TEST_F(SamplerIo, UnknownImageExtensionIsAnInputErrorAndWritesNothing) {
    try {
        writeImage(gradientImage(), path("image.bmpx"));
        FAIL() << "no exception";
    } catch (const InputError& error) {
        EXPECT_NE(std::string(error.what()).find(".png"), std::string::npos);
    }
    EXPECT_TRUE(folderEntries().empty());
}

TEST_F(SamplerIo, NonFinitePixelIsReportedAndWritesNothing) {
    Image image = gradientImage();
    image.at(5, 2).g = std::numeric_limits<float>::quiet_NaN();
    try {
        writeImage(image, path("image.png"));
        FAIL() << "no exception";
    } catch (const InternalError& error) {  // a renderer bug, not the caller's input
        EXPECT_NE(std::string(error.what()).find("pixel (5, 2)"), std::string::npos);
    }
    EXPECT_TRUE(folderEntries().empty());
}

TEST_F(SamplerIo, ReadImageErrors) {
    EXPECT_THROW(readImage(path("absent.png")), InputError);
    std::ofstream(path("garbage.png")) << "not a png";
    EXPECT_THROW(readImage(path("garbage.png")), FormatError);
    EXPECT_THROW(Image(0, 5), InputError);
}

image_files::Spec imageSpec(int width, int height, int channels, image_files::PixelType stored) {
    image_files::Spec spec;
    spec.width = width;
    spec.height = height;
    spec.channels = channels;
    spec.pixelType = stored;
    return spec;
}

TEST_F(SamplerIo, PngsAreWrittenWithLibpngAndReadBackByOpenImageIo) {
    // 8-bit RGB from floats: clamped and rounded to the nearest code, NaN to 0; the sRGB colour
    // space and string attributes come back, the writer's integer controls are not stored.
    image_files::Spec rgb = imageSpec(3, 2, 3, image_files::PixelType::UInt8);
    rgb.set("oiio:ColorSpace", std::string("sRGB"));
    rgb.set("distile:note", std::string("a note"));
    rgb.set("png:compressionLevel", 1);
    const std::vector<float> floats = {0.0f, 1.0f,  0.5f,  -1.0f,  2.0f,   std::nanf(""),
                                       0.1f, 0.25f, 0.75f, 0.998f, 0.002f, 1.0f / 255.0f,
                                       0.3f, 0.6f,  0.9f,  0.4f,   0.7f,   0.2f};
    const fs::path rgbFile = path("rgb.png");
    image_files::write(rgbFile, rgbFile, rgb, image_files::PixelType::Float, floats.data());
    const RawImage rgbRead = readRaw(rgbFile);
    ASSERT_EQ(rgbRead.spec.format, OIIO::TypeDesc::UINT8);
    ASSERT_EQ(rgbRead.spec.nchannels, 3);
    EXPECT_EQ(rgbRead.spec.get_string_attribute("oiio:ColorSpace"), "sRGB");
    EXPECT_EQ(rgbRead.spec.get_string_attribute("distile:note"), "a note");
    EXPECT_EQ(rgbRead.spec.find_attribute("png:compressionLevel"), nullptr);
    const int expected[18] = {0,   255, 128, 0,  255, 0,   26,  64,  191,
                              254, 1,   1,   77, 153, 230, 102, 179, 51};
    for (int i = 0; i < 18; ++i)
        EXPECT_EQ(std::lround(rgbRead.pixels[std::size_t(i)] * 255.0f), expected[i]) << i;

    // 16-bit grey codes as given (most significant byte first in the file), Linear.
    image_files::Spec grey = imageSpec(4, 1, 1, image_files::PixelType::UInt16);
    grey.set("oiio:ColorSpace", std::string("Linear"));
    const std::vector<std::uint16_t> codes = {0, 1, 0x1234, 65535};
    const fs::path greyFile = path("grey.png");
    image_files::write(greyFile, greyFile, grey, image_files::PixelType::UInt16, codes.data());
    const RawImage greyRead = readRaw(greyFile);
    ASSERT_EQ(greyRead.spec.format, OIIO::TypeDesc::UINT16);
    EXPECT_EQ(greyRead.spec.get_string_attribute("oiio:ColorSpace"), "Linear");
    for (int i = 0; i < 4; ++i)
        EXPECT_EQ(std::lround(greyRead.pixels[std::size_t(i)] * 65535.0f), codes[std::size_t(i)]);
    EXPECT_TRUE(image_files::writesWithoutModule("a/B.PNG"));
    EXPECT_FALSE(image_files::writesWithoutModule("a/b.tif"));
}

TEST_F(SamplerIo, ExrsAreWrittenWithOpenExrAndReadBackByOpenImageIo) {
    // RGB floats stored as float (exactly) and as half (rounded as OpenEXR's half does), with
    // the compression named as OpenImageIO names it; string, integer and float attributes come
    // back, OpenImageIO's "oiio:" hints are not stored. What OpenEXR cannot store is refused.
    EXPECT_TRUE(image_files::writesWithoutModule("a/b.EXR"));
    const std::vector<float> floats = {0.0f, 1.0f, -2.5f,  1e-3f, 65504.0f, 3.1415926f,
                                       0.1f, 7.0f, 1e-30f, -0.0f, 123.456f, 0.5f};
    for (const auto& [stored, compression] : {std::pair{image_files::PixelType::Float, "zip"},
                                              std::pair{image_files::PixelType::Half, "piz"}}) {
        image_files::Spec rgb = imageSpec(2, 2, 3, stored);
        rgb.set("oiio:ColorSpace", std::string("Linear"));
        rgb.set("compression", std::string(compression));
        rgb.set("distile:note", std::string("a note"));
        rgb.set("distile:count", 7);
        rgb.set("distile:scale", 0.25f);
        const fs::path file = path(std::string("rgb_") + compression + ".exr");
        image_files::write(file, file, rgb, image_files::PixelType::Float, floats.data());
        const RawImage read = readRaw(file);
        ASSERT_EQ(read.spec.nchannels, 3);
        EXPECT_EQ(read.spec.channelnames, (std::vector<std::string>{"R", "G", "B"}));
        EXPECT_EQ(read.spec.format, stored == image_files::PixelType::Half ? OIIO::TypeDesc::HALF
                                                                           : OIIO::TypeDesc::FLOAT);
        EXPECT_EQ(read.spec.get_string_attribute("compression"), compression);
        EXPECT_EQ(read.spec.get_string_attribute("distile:note"), "a note");
        EXPECT_EQ(read.spec.get_int_attribute("distile:count"), 7);
        EXPECT_EQ(read.spec.get_float_attribute("distile:scale"), 0.25f);
        for (std::size_t i = 0; i < floats.size(); ++i) {
            const float expected =
                stored == image_files::PixelType::Half ? float(Imath::half(floats[i])) : floats[i];
            EXPECT_EQ(read.pixels[i], expected) << i;
        }
    }
    image_files::Spec grey = imageSpec(2, 2, 1, image_files::PixelType::Float);
    const fs::path greyFile = path("grey.exr");
    image_files::write(greyFile, greyFile, grey, image_files::PixelType::Float, floats.data());
    EXPECT_EQ(readRaw(greyFile).spec.channelnames, std::vector<std::string>{"Y"});

    const auto refusal = [&](image_files::Spec spec, image_files::PixelType given) {
        const fs::path file = path("refused.exr");
        try {
            image_files::write(file, path("named.exr"), spec, given, floats.data());
        } catch (const std::runtime_error& error) {
            return std::string(error.what());
        }
        return std::string("written");
    };
    image_files::Spec unknown = imageSpec(2, 2, 3, image_files::PixelType::Float);
    unknown.set("compression", std::string("jpeg"));
    EXPECT_EQ(refusal(unknown, image_files::PixelType::Float),
              path("named.exr").string() + ": compression 'jpeg' is not one OpenEXR has");
    EXPECT_NE(
        refusal(imageSpec(2, 2, 3, image_files::PixelType::UInt8), image_files::PixelType::Float)
            .find("from floats, stored as half or float"),
        std::string::npos);
    EXPECT_NE(
        refusal(imageSpec(1, 2, 2, image_files::PixelType::Float), image_files::PixelType::Float)
            .find("2 channels without a name each"),
        std::string::npos);
}

TEST_F(SamplerIo, PngsWithoutRowFiltersAreDeflatedInBandsTheSameOnAnyThreadCount) {
    // 16-bit RGB, 301 x 97 (four bands of 32 rows, the last short), codes from a hash: every
    // value comes back, and the file's bytes do not depend on the thread count.
    image_files::Spec spec = imageSpec(301, 97, 3, image_files::PixelType::UInt16);
    spec.set("png:filter", 8);  // PNG_FILTER_NONE
    spec.set("png:compressionLevel", 1);
    std::vector<std::uint16_t> codes(std::size_t(301 * 97 * 3));
    std::uint32_t state = 12345;
    for (std::size_t i = 0; i < codes.size(); ++i) {
        state = state * 1664525u + 1013904223u;
        codes[i] = i % 7 == 0 ? std::uint16_t(i / 1000) : std::uint16_t(state >> 16);
    }
    const auto write = [&](const fs::path& file, int threads) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        image_files::write(file, file, spec, image_files::PixelType::UInt16, codes.data());
    };
    write(path("two.png"), 2);
    write(path("one.png"), 1);
    const RawImage read = readRaw(path("two.png"));
    ASSERT_EQ(read.spec.width, 301);
    ASSERT_EQ(read.spec.height, 97);
    ASSERT_EQ(read.spec.nchannels, 3);
    for (std::size_t i = 0; i < codes.size(); ++i)
        ASSERT_EQ(std::lround(read.pixels[i] * 65535.0f), codes[i]) << i;
    std::ifstream one(path("one.png"), std::ios::binary), two(path("two.png"), std::ios::binary);
    const std::string oneBytes((std::istreambuf_iterator<char>(one)), {});
    const std::string twoBytes((std::istreambuf_iterator<char>(two)), {});
    EXPECT_EQ(oneBytes, twoBytes);
}

TEST_F(SamplerIo, PngWriteFailuresAreReportedNotCrashes) {
    image_files::Spec spec = imageSpec(256, 256, 3, image_files::PixelType::UInt8);
    spec.set("png:compressionLevel", 0);  // stored: 196 KB, more than stdio buffers
    const std::vector<std::uint8_t> pixels(256 * 256 * 3, 7);
    // A full disk: libpng's error jumps back out of its write, and the message says so.
    if (fs::exists("/dev/full")) {
        EXPECT_EQ(image_files::detail::writePng("/dev/full", spec, image_files::PixelType::UInt8,
                                                pixels.data()),
                  "writing failed (libpng: Write Error)");
    }
    EXPECT_EQ(image_files::detail::writePng(path("missing/x.png"), spec,
                                            image_files::PixelType::UInt8, pixels.data()),
              "cannot create it (No such file or directory)");
    spec.channels = 5;
    EXPECT_EQ(image_files::detail::writePng(path("five.png"), spec, image_files::PixelType::UInt8,
                                            pixels.data()),
              "a PNG holds 1 to 4 channels, not 5");
    spec.channels = 3;
    spec.pixelType = image_files::PixelType::Half;
    EXPECT_EQ(image_files::detail::writePng(path("half.png"), spec, image_files::PixelType::Half,
                                            pixels.data()),
              "a PNG stores 8- or 16-bit codes, not half or float values");
    EXPECT_FALSE(fs::exists(path("five.png")));
    EXPECT_FALSE(fs::exists(path("half.png")));
}

}  // namespace
}  // namespace distile
