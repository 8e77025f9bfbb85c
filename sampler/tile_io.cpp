#include "sampler/tile_io.h"

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/openexr.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/atomic_file.h"
#include "common/detail/exr_file.h"
#include "common/error.h"
#include "common/exr_header.h"
#include "common/fnv1a.h"
#include "common/image_files.h"
#include "common/input_file.h"

namespace distile {

namespace fs = std::filesystem;

namespace {

constexpr const char* kFormatVersion = "0.1.0";
constexpr const char* kChannelName = "distance";
constexpr float kHalfMax = 65504.0f;

constexpr const char* kUnknownSource = "unknown";
constexpr const char* kNoParams = "{}";

/// Every attribute a tile file must carry, in the order they are checked on reading.
constexpr std::array<const char*, 7> kTileAttributes = {
    "distile:size",   "distile:layout",  "distile:units", "distile:source",
    "distile:params", "distile:version", "distile:hash"};

using image_files::firstLine;
using image_files::PixelType;

std::uint64_t hashDistances(const Size3& size, std::span<const float> distancesTexels) {
    Fnv1a64 hash;
    for (int extent : {size.width, size.height, size.depth}) {
        hash.updateU32LittleEndian(static_cast<std::uint32_t>(extent));
    }
    for (float distance : distancesTexels) {
        hash.updateU32LittleEndian(std::bit_cast<std::uint32_t>(distance));
    }
    return hash.value();
}

std::string layoutText(const AtlasGrid& grid) {
    const std::string cols = std::to_string(grid.cols);
    return "atlas " + cols + "x" + std::to_string(grid.rows) + " slice k at column k%" + cols +
           " row k/" + cols + ", x fastest, texel centre at i+0.5";
}

std::string texelName(const Size3& size, std::size_t index) {
    const std::size_t sliceTexels = std::size_t(size.width) * std::size_t(size.height);
    const std::size_t x = index % std::size_t(size.width);
    const std::size_t y = (index % sliceTexels) / std::size_t(size.width);
    const std::size_t z = index / sliceTexels;
    return "texel (" + std::to_string(x) + ", " + std::to_string(y) + ", " + std::to_string(z) +
           ")";
}

/// Atlas pixel count per row and per column for a tile of `size`.
struct AtlasPixels {
    AtlasGrid grid;
    int width = 0;
    int height = 0;
};

AtlasPixels atlasPixels(const Size3& size) {
    const AtlasGrid grid = atlasGrid(size.depth);
    return {grid, grid.cols * size.width, grid.rows * size.height};
}

/// Copies distances in tile order (x fastest) into a row-major atlas image, filling cells past
/// the last slice with `fill`.
template <typename Value>
std::vector<Value> toAtlas(const Size3& size, std::span<const Value> tileValues, Value fill) {
    const AtlasPixels atlas = atlasPixels(size);
    std::vector<Value> pixels(std::size_t(atlas.width) * std::size_t(atlas.height), fill);
    for (int z = 0; z < size.depth; ++z) {
        const int originX = (z % atlas.grid.cols) * size.width;
        const int originY = (z / atlas.grid.cols) * size.height;
        for (int y = 0; y < size.height; ++y) {
            const std::size_t from =
                std::size_t(size.width) * (std::size_t(y) + std::size_t(size.height) * z);
            const std::size_t to =
                std::size_t(originX) + std::size_t(atlas.width) * std::size_t(originY + y);
            std::copy_n(tileValues.begin() + from, size.width, pixels.begin() + to);
        }
    }
    return pixels;
}

/// Copies a row-major atlas image into the tile's distances, the slices side by side.
void fromAtlas(const Size3& size, std::span<const float> pixels, Tile& tile) {
    const AtlasPixels atlas = atlasPixels(size);
    tbb::parallel_for(0, size.depth, [&](int z) {
        const int originX = (z % atlas.grid.cols) * size.width;
        const int originY = (z / atlas.grid.cols) * size.height;
        for (int y = 0; y < size.height; ++y) {
            const std::size_t from =
                std::size_t(originX) + std::size_t(atlas.width) * std::size_t(originY + y);
            std::copy_n(pixels.begin() + from, size.width, &tile.at(0, y, z));
        }
    });
}

/// `source` as written in the tile `file`: relative to the tile's folder
/// when the two share a root, else absolute.
std::string recordedSourceFile(const fs::path& source, const fs::path& file) {
    const fs::path absoluteSource = fs::absolute(source).lexically_normal();
    const fs::path relative =
        absoluteSource.lexically_relative(fs::absolute(file).parent_path().lexically_normal());
    return relative.empty() ? absoluteSource.generic_string() : relative.generic_string();
}

/// The spec of an atlas of `size` in one channel named "distance", stored as `stored`, with the
/// attributes of a tile.
image_files::Spec tileSpec(const Size3& size, PixelType stored, const TileProvenance& provenance,
                           std::uint64_t hash, const fs::path& file) {
    const AtlasPixels atlas = atlasPixels(size);
    image_files::Spec spec;
    spec.width = atlas.width;
    spec.height = atlas.height;
    spec.channels = 1;
    spec.pixelType = stored;
    spec.channelNames = {kChannelName};
    spec.set("distile:size", toString(size));
    spec.set("distile:layout", layoutText(atlasGrid(size.depth)));
    spec.set("distile:units", std::string("texels"));
    // Empty provenance is spelled out: files once written through OpenImageIO, whose EXR writer
    // drops empty string attributes, read back the same way.
    spec.set("distile:source", provenance.source.empty() ? kUnknownSource : provenance.source);
    spec.set("distile:params", provenance.params.empty() ? kNoParams : provenance.params);
    spec.set("distile:version", std::string(kFormatVersion));
    spec.set("distile:hash", hexDigits(hash));
    if (provenance.halfBandTexels > 0.0)
        spec.set("distile:band_texels", float(provenance.halfBandTexels));
    if (!provenance.sourceFile.empty()) {
        spec.set("distile:source_file", recordedSourceFile(provenance.sourceFile, file));
        spec.set("distile:source_hash", provenance.sourceHash);
    }
    if (!provenance.check.empty()) spec.set("distile:check", provenance.check);
    if (!provenance.recipeHash.empty()) spec.set("distile:recipe_hash", provenance.recipeHash);
    return spec;
}

/// The distances a tile may hold, texels, and why.
struct DistanceInterval {
    double lowest = 0.0, highest = 0.0;
    std::string reason;  ///< completes "... texels, outside ..."
};

/// The one bound on a tile's distances. With a declared band (`halfBandTexels` > 0): a bake
/// clamps distances to +-band and the conservative lowering takes them at most one tile depth
/// below -band. Without one: twice the widest band a bake of `size` accepts
/// (maxHalfBandTexels), so the lowering fits and sums of distances stay far from the float range.
DistanceInterval acceptedDistances(const Size3& size, double halfBandTexels) {
    if (halfBandTexels > 0.0) {
        return {-halfBandTexels - double(size.depth), halfBandTexels,
                "outside the band the tile declares (distile:band_texels " +
                    numberText(halfBandTexels) +
                    ": at most the band, at least minus the band "
                    "minus the tile depth)"};
    }
    const double limit = 2.0 * double(maxHalfBandTexels(size));
    return {-limit, limit,
            "outside +-" + std::to_string(int(limit)) + ", the distances a " + toString(size) +
                " tile holds (twice its widest band)"};
}

/// What is wrong with the tile's distances against `accepted`, or "".
std::string distanceProblem(const Tile& tile, const DistanceInterval& accepted) {
    const auto distances = tile.distancesTexels();
    const auto outside = std::find_if(distances.begin(), distances.end(), [&](float d) {
        return double(d) > accepted.highest || double(d) < accepted.lowest;
    });
    if (outside == distances.end()) return {};
    return "distance at " + texelName(tile.size(), std::size_t(outside - distances.begin())) +
           " is " + std::to_string(*outside) + " texels, " + accepted.reason;
}

/// What is wrong with the band (distile:band_texels) a tile of `size` declares, or "": 0 declares
/// none; a declared band is positive and within the interval of a tile without one.
std::string bandValueProblem(const Size3& size, double halfBandTexels) {
    const double most = acceptedDistances(size, 0.0).highest;
    if (halfBandTexels == 0.0 || (halfBandTexels > 0.0 && halfBandTexels <= most)) return {};
    return "the declared band (distile:band_texels) " + numberText(halfBandTexels) +
           " is not a positive number of at most " + std::to_string(int(most)) + " texels";
}

/// The first error OpenEXR's core library reports on a context, kept instead of printed.
struct CoreErrors {
    std::mutex mutex;
    std::string first;
};

void keepCoreError(exr_const_context_t context, exr_result_t code, const char* message) {
    void* data = nullptr;
    if (exr_get_user_data(context, &data) != EXR_ERR_SUCCESS || !data) return;
    auto& errors = *static_cast<CoreErrors*>(data);
    const std::lock_guard lock(errors.mutex);
    if (errors.first.empty())
        errors.first = message && *message ? message : exr_get_default_error_message(code);
}

/// The one channel of a scanline file's data window, `width` x `height` pixels, as floats in
/// row-major order, its chunks decoded side by side on all threads with OpenEXR's core library
/// (InputFile::readPixels reads the chunks one after another on the calling thread and left the
/// others half idle: the demo's 4 MB tile took 15-17 ms on two cores). Each chunk writes only its
/// own rows, so the pixels are the same on any number of threads. Throws std::runtime_error with
/// OpenEXR's first message.
std::vector<float> decodeAtlasPixels(const fs::path& file, int width, int height) {
    CoreErrors errors;
    exr_context_initializer_t initializer = EXR_DEFAULT_CONTEXT_INITIALIZER;
    initializer.user_data = &errors;
    initializer.error_handler_fn = keepCoreError;
    exr_context_t context = nullptr;
    const auto fail = [&](exr_result_t code) {
        const std::lock_guard lock(errors.mutex);
        throw std::runtime_error(errors.first.empty() ? exr_get_default_error_message(code)
                                                      : errors.first);
    };
    if (const exr_result_t code = exr_start_read(&context, file.c_str(), &initializer);
        code != EXR_ERR_SUCCESS) {
        exr_finish(&context);
        fail(code);
    }
    const std::unique_ptr<exr_context_t, void (*)(exr_context_t*)> closer(
        &context, [](exr_context_t* open) { exr_finish(open); });
    exr_attr_box2i_t window{};
    int32_t chunks = 0, rowsPerChunk = 0;
    for (const exr_result_t code :
         {exr_get_data_window(context, 0, &window), exr_get_chunk_count(context, 0, &chunks),
          exr_get_scanlines_per_chunk(context, 0, &rowsPerChunk)}) {
        if (code != EXR_ERR_SUCCESS) fail(code);
    }
    if (std::int64_t(window.max.x) - window.min.x + 1 != width ||
        std::int64_t(window.max.y) - window.min.y + 1 != height || rowsPerChunk < 1)
        throw std::runtime_error("the data window is not the header's");
    std::vector<float> pixels(std::size_t(width) * std::size_t(height));
    struct Decoder {
        exr_decode_pipeline_t pipeline{};  // all zero, as EXR_DECODE_PIPELINE_INITIALIZER
        bool started = false;
    };
    // Chunk `chunk` into its rows of `pixels` with `decoder` (this thread's).
    const auto decodeChunk = [&](int chunk, Decoder& decoder) -> exr_result_t {
        exr_chunk_info_t info{};
        if (const exr_result_t code = exr_read_scanline_chunk_info(
                context, 0, window.min.y + chunk * rowsPerChunk, &info);
            code != EXR_ERR_SUCCESS)
            return code;
        const exr_result_t code =
            decoder.started ? exr_decoding_update(context, 0, &info, &decoder.pipeline)
                            : exr_decoding_initialize(context, 0, &info, &decoder.pipeline);
        if (code != EXR_ERR_SUCCESS) return code;
        decoder.started = true;
        exr_coding_channel_info_t& channel = decoder.pipeline.channels[0];
        if (decoder.pipeline.channel_count != 1 || channel.width != width ||
            channel.height != info.height || info.start_y < window.min.y ||
            std::int64_t(info.start_y) + info.height - 1 > window.max.y)
            return EXR_ERR_BAD_CHUNK_LEADER;
        channel.decode_to_ptr = reinterpret_cast<std::uint8_t*>(
            pixels.data() + std::size_t(info.start_y - window.min.y) * std::size_t(width));
        channel.user_pixel_stride = sizeof(float);
        channel.user_line_stride = int32_t(sizeof(float)) * width;
        channel.user_bytes_per_element = sizeof(float);
        channel.user_data_type = EXR_PIXEL_FLOAT;
        if (const exr_result_t chosen =
                exr_decoding_choose_default_routines(context, 0, &decoder.pipeline);
            chosen != EXR_ERR_SUCCESS)
            return chosen;
        return exr_decoding_run(context, 0, &decoder.pipeline);
    };
    tbb::enumerable_thread_specific<Decoder> decoders;
    std::atomic<exr_result_t> failure{EXR_ERR_SUCCESS};
    tbb::parallel_for(0, chunks, [&](int chunk) {
        if (failure.load(std::memory_order_relaxed) != EXR_ERR_SUCCESS) return;
        if (const exr_result_t code = decodeChunk(chunk, decoders.local());
            code != EXR_ERR_SUCCESS) {
            exr_result_t none = EXR_ERR_SUCCESS;
            failure.compare_exchange_strong(none, code);
        }
    });
    for (Decoder& decoder : decoders) {
        if (decoder.started) exr_decoding_destroy(context, &decoder.pipeline);
    }
    if (failure != EXR_ERR_SUCCESS) fail(failure);
    return pixels;
}

/// The header of an OpenEXR file as an image_files::Spec: its data window's extent, channel names
/// and the string, float and integer attributes (readers take every channel as float).
image_files::Spec specOfExr(const Imf::Header& header) {
    image_files::Spec spec;
    const Imath::Box2i window = header.dataWindow();
    spec.width =
        int(std::min<std::int64_t>(std::int64_t(window.max.x) - window.min.x + 1, INT32_MAX));
    spec.height =
        int(std::min<std::int64_t>(std::int64_t(window.max.y) - window.min.y + 1, INT32_MAX));
    spec.deep = header.hasType() && Imf::isDeepData(header.type());
    for (auto channel = header.channels().begin(); channel != header.channels().end(); ++channel)
        spec.channelNames.push_back(channel.name());
    spec.channels = int(spec.channelNames.size());
    for (auto entry = header.begin(); entry != header.end(); ++entry) {
        const Imf::Attribute& value = entry.attribute();
        if (const auto* text = dynamic_cast<const Imf::StringAttribute*>(&value))
            spec.attributes.push_back({entry.name(), text->value()});
        else if (const auto* number = dynamic_cast<const Imf::FloatAttribute*>(&value))
            spec.attributes.push_back({entry.name(), number->value()});
        else if (const auto* integer = dynamic_cast<const Imf::IntAttribute*>(&value))
            spec.attributes.push_back({entry.name(), integer->value()});
    }
    return spec;
}

void requireWritableDistances(const Tile& tile, const fs::path& file) {
    const auto distances = tile.distancesTexels();
    const auto bad =
        std::find_if(distances.begin(), distances.end(), [](float d) { return !std::isfinite(d); });
    if (bad != distances.end()) {
        throw InputError(file.string() + ": distance at " +
                         texelName(tile.size(), std::size_t(bad - distances.begin())) + " is " +
                         std::to_string(*bad) + "; only finite distances can be written");
    }
    // A tile that declares a band keeps to it; one without may hold any finite distance.
    const double band = tile.provenance.halfBandTexels;
    std::string problem = bandValueProblem(tile.size(), band);
    if (problem.empty() && band > 0.0)
        problem = distanceProblem(tile, acceptedDistances(tile.size(), band));
    if (!problem.empty())
        throw InputError(file.string() + ": " + problem + "; it cannot be written");
}

Size3 parseSize(const std::string& text, const fs::path& file) {
    Size3 size;
    try {
        size = parseSize3(text, "distile:size");
    } catch (const InputError&) {
        throw FormatError(file.string() + ": distile:size '" + text +
                          "' is not accepted; expected WxHxD such as 256x256x16");
    }
    try {
        validateTileSize(size, file.string() + ": distile:size");
    } catch (const InputError& error) {
        throw FormatError(error.what());
    }
    return size;
}

}  // namespace

AtlasGrid atlasGrid(int depthSlices) {
    if (depthSlices < 1) {
        throw InputError("atlas: depth " + std::to_string(depthSlices) +
                         " is not accepted; at least 1 slice");
    }
    int cols = static_cast<int>(std::sqrt(static_cast<double>(depthSlices)));
    while (cols * cols < depthSlices) ++cols;  // exact ceil(sqrt(D)), immune to rounding
    while ((cols - 1) * (cols - 1) >= depthSlices) --cols;
    return {cols, (depthSlices + cols - 1) / cols};
}

std::uint64_t tileHash(const Tile& tile) {
    return hashDistances(tile.size(), tile.distancesTexels());
}

std::uint16_t halfBitsAtMost(float value) {
    Imath::half rounded(value);
    if (float(rounded) > value) {
        // One step down: away from 0 below it (-0 included), toward 0 above it.
        const std::uint16_t bits = rounded.bits();
        rounded.setBits(bits & 0x8000 ? bits + 1 : bits - 1);
    }
    return rounded.bits();
}

void writeTileExr(const Tile& tile, const fs::path& file, TileStorage storage) {
    if (lowerExtension(file) != ".exr") {
        throw InputError(file.string() + ": extension '" + file.extension().string() +
                         "' is not accepted for a tile; use .exr");
    }
    requireWritableDistances(tile, file);
    const Size3& size = tile.size();
    std::span<const float> stored = tile.distancesTexels();
    std::vector<float> roundedToHalf;
    PixelType fileType = PixelType::Float;
    if (storage == TileStorage::Half16) {
        // Rounded once here, so the hash covers exactly the values a reader will get back.
        roundedToHalf.resize(stored.size());
        std::transform(stored.begin(), stored.end(), roundedToHalf.begin(), [](float value) {
            Imath::half rounded;
            rounded.setBits(halfBitsAtMost(value));
            return float(rounded);
        });
        for (std::size_t i = 0; i < stored.size(); ++i) {
            if (!(std::abs(stored[i]) <= kHalfMax)) {
                throw InputError(file.string() + ": distance " + std::to_string(stored[i]) +
                                 " at " + texelName(size, i) +
                                 " does not fit in half storage; |distance| must be at most " +
                                 std::to_string(int(kHalfMax)) + " texels, or use float storage");
            }
        }
        stored = roundedToHalf;
        fileType = PixelType::Half;
    }

    const float maxDistance = *std::max_element(stored.begin(), stored.end());
    const std::vector<float> pixels = toAtlas(size, stored, maxDistance);
    const image_files::Spec spec =
        tileSpec(size, fileType, tile.provenance, hashDistances(size, stored), file);
    // With OpenEXR itself, whatever the file's extension: reading and writing tiles needs none
    // of OpenImageIO's plugins, so a render's tiles are read while OpenImageIO is still loading.
    writeAtomically(file, [&](const fs::path& temporary) {
        const std::string problem =
            image_files::detail::writeExr(temporary, spec, PixelType::Float, pixels.data());
        if (!problem.empty()) throw std::runtime_error(file.string() + ": " + problem);
    });
}

Tile readTileExr(const fs::path& file) {
    requireRegularFile(file, "a tile .exr file");
    checkPngChunks(file);  // libpng would report a broken one on stderr itself
    checkExrHeader(file);  // OpenEXR allocates what a damaged header declares
    std::unique_ptr<Imf::InputFile> input;
    image_files::Spec spec;
    try {
        input = std::make_unique<Imf::InputFile>(file.c_str());
        spec = specOfExr(input->header());
    } catch (const std::exception& error) {
        throw FormatError(file.string() + ": not a readable OpenEXR file (" +
                          firstLine(error.what(), "unknown OpenEXR error") +
                          "); a distile tile is OpenEXR, and this file is truncated, corrupted "
                          "or another format");
    }
    for (const char* name : kTileAttributes) {
        const image_files::Attribute* attribute = spec.find(name);
        if (!attribute || !std::holds_alternative<std::string>(attribute->value)) {
            throw FormatError(file.string() + ": not a distile tile (no " + name +
                              " attribute); write tiles with `distile bake`");
        }
    }
    const Size3 size = parseSize(spec.text("distile:size"), file);
    const std::string units = spec.text("distile:units");
    if (units != "texels") {
        throw FormatError(file.string() + ": distile:units '" + units +
                          "' is not accepted; only 'texels'");
    }
    if (spec.channels != 1 || spec.channelNames.empty() || spec.channelNames[0] != kChannelName) {
        const std::string first = spec.channelNames.empty() ? "" : spec.channelNames[0];
        throw FormatError(file.string() + ": has " + std::to_string(spec.channels) +
                          " channel(s) starting with '" + first +
                          "'; a tile has exactly one channel named 'distance'");
    }
    const AtlasPixels atlas = atlasPixels(size);
    if (spec.width != atlas.width || spec.height != atlas.height || spec.deep) {
        throw FormatError(file.string() + ": image is " + std::to_string(spec.width) + "x" +
                          std::to_string(spec.height) + " pixels but distile:size " +
                          toString(size) + " needs a " + std::to_string(atlas.grid.cols) + "x" +
                          std::to_string(atlas.grid.rows) + " atlas of " +
                          std::to_string(atlas.width) + "x" + std::to_string(atlas.height));
    }

    const std::uint64_t atlasPixelCount = std::uint64_t(atlas.width) * std::uint64_t(atlas.height);
    requireWithinMemoryBudget(file, "a " + toString(size) + " tile",
                              saturatingProduct(atlasPixelCount + size.texelCount(), 4));
    std::vector<float> pixels;
    try {
        if (!input->header().hasTileDescription()) {  // scanlines, as distile writes them
            pixels = decodeAtlasPixels(file, atlas.width, atlas.height);
        } else {
            // Tiled by another tool. The slice's origin is the data window's corner, as OpenEXR
            // addresses pixels; computed as an address so that a window far from (0, 0) is not
            // pointer arithmetic out of range.
            image_files::detail::useExrThreads();
            pixels.resize(atlasPixelCount);
            const Imath::Box2i window = input->header().dataWindow();
            const std::uintptr_t origin =
                reinterpret_cast<std::uintptr_t>(pixels.data()) -
                (std::uintptr_t(std::intptr_t(window.min.x)) +
                 std::uintptr_t(std::intptr_t(window.min.y)) * std::uintptr_t(atlas.width)) *
                    sizeof(float);
            Imf::FrameBuffer frame;
            frame.insert(kChannelName,
                         Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(origin), sizeof(float),
                                    sizeof(float) * std::size_t(atlas.width)));
            input->setFrameBuffer(frame);
            input->readPixels(window.min.y, window.max.y);
        }
    } catch (const std::exception& error) {
        throw FormatError(file.string() + ": cannot read the pixels (" +
                          firstLine(error.what(), "unknown OpenEXR error") +
                          "); the file is truncated or corrupted");
    }

    Tile tile(size);
    fromAtlas(size, pixels, tile);
    const auto distances = tile.distancesTexels();
    const auto bad =
        std::find_if(distances.begin(), distances.end(), [](float d) { return !std::isfinite(d); });
    if (bad != distances.end()) {
        throw FormatError(file.string() + ": distance at " +
                          texelName(size, std::size_t(bad - distances.begin())) + " is " +
                          std::to_string(*bad) + "; a tile holds only finite distances");
    }
    if (const image_files::Attribute* band = spec.find("distile:band_texels")) {
        const float* value = std::get_if<float>(&band->value);
        if (!value) {
            throw FormatError(file.string() +
                              ": distile:band_texels is not a float attribute (the band in "
                              "texels); the file was modified or corrupted");
        }
        tile.provenance.halfBandTexels = *value;
        if (const std::string problem = bandValueProblem(size, tile.provenance.halfBandTexels);
            !problem.empty())
            throw FormatError(file.string() + ": " + problem +
                              "; the file was modified or corrupted");
    }
    if (const std::string problem =
            distanceProblem(tile, acceptedDistances(size, tile.provenance.halfBandTexels));
        !problem.empty())
        throw FormatError(file.string() + ": " + problem);
    const std::string storedHash = spec.text("distile:hash");
    const std::string actualHash = hexDigits(tileHash(tile));
    if (storedHash != actualHash) {
        throw FormatError(file.string() + ": distile:hash is " + storedHash +
                          " but the distances hash to " + actualHash +
                          "; the file was modified or corrupted");
    }
    tile.provenance.source = spec.text("distile:source");
    tile.provenance.params = spec.text("distile:params");
    // Optional: tiles baked from a file name it, relative to the tile's folder.
    const std::string sourceFile = spec.text("distile:source_file");
    if (!sourceFile.empty()) {
        tile.provenance.sourceFile =
            (fs::absolute(file).parent_path() / fs::path(sourceFile)).lexically_normal();
        tile.provenance.sourceHash = spec.text("distile:source_hash");
    }
    // Optional: the bake cache's recipe, and the verdict of the check made when the tile was
    // baked.
    tile.provenance.recipeHash = spec.text("distile:recipe_hash");
    tile.provenance.check = spec.text("distile:check");
    const std::string_view check = tile.provenance.check;
    if (!check.empty() && !check.starts_with(TileProvenance::kCheckWithin) &&
        !check.starts_with(TileProvenance::kCheckBeyond)) {
        throw FormatError(file.string() + ": distile:check '" + tile.provenance.check +
                          "' is not a check's verdict; accepted: text that starts '" +
                          std::string(TileProvenance::kCheckWithin) + "' or '" +
                          std::string(TileProvenance::kCheckBeyond) + "'");
    }
    return tile;
}

namespace {

/// The checks of every PNG export: the extension, and no distance rejected by `refused`
/// (described as `what`).
void requirePngExport(const Tile& tile, const fs::path& file, bool (*refused)(float),
                      const char* what) {
    if (lowerExtension(file) != ".png") {
        throw InputError(file.string() + ": extension '" + file.extension().string() +
                         "' is not accepted for a PNG export; use .png");
    }
    const auto distances = tile.distancesTexels();
    const auto bad = std::find_if(distances.begin(), distances.end(), refused);
    if (bad != distances.end()) {
        throw InputError(file.string() + ": distance at " +
                         texelName(tile.size(), std::size_t(bad - distances.begin())) + " is " +
                         what + "; only finite numbers can be exported");
    }
}

}  // namespace

void writeTilePng(const Tile& tile, const fs::path& file, int bitsPerChannel) {
    if (bitsPerChannel != 8 && bitsPerChannel != 16) {
        throw InputError(file.string() + ": PNG bit depth " + std::to_string(bitsPerChannel) +
                         " is not accepted; use 8 or 16");
    }
    requirePngExport(
        tile, file, [](float d) { return std::isnan(d); }, "NaN");
    const auto distances = tile.distancesTexels();
    const Size3& size = tile.size();
    const float depthTexels = float(size.depth);
    const std::uint32_t maxCode = bitsPerChannel == 8 ? 255u : 65535u;
    // GPU Gems 2 ch. 8: distance / depth, clamped to [0, 1]; -inf and +inf clamp too.
    auto toCode = [&](float distanceTexels) {
        const float unit = std::clamp(distanceTexels / depthTexels, 0.0f, 1.0f);
        return static_cast<std::uint16_t>(std::lround(unit * float(maxCode)));
    };
    std::vector<std::uint16_t> codes(distances.size());
    std::transform(distances.begin(), distances.end(), codes.begin(), toCode);
    const std::uint16_t fill = *std::max_element(codes.begin(), codes.end());
    const std::vector<std::uint16_t> pixels =
        toAtlas(size, std::span<const std::uint16_t>(codes), fill);

    image_files::Spec spec =
        tileSpec(size, bitsPerChannel == 8 ? PixelType::UInt8 : PixelType::UInt16, tile.provenance,
                 tileHash(tile), file);
    spec.set("oiio:ColorSpace", std::string("Linear"));  // data, not colour: no sRGB decoding
    spec.set("distile:units", "distance / " + std::to_string(size.depth) +
                                  " texels (tile depth), clamped to [0, 1]");
    if (bitsPerChannel == 8) {
        std::vector<std::uint8_t> bytes(pixels.begin(), pixels.end());
        writeAtomically(file, [&](const fs::path& temporary) {
            image_files::write(temporary, file, spec, PixelType::UInt8, bytes.data());
        });
    } else {
        writeAtomically(file, [&](const fs::path& temporary) {
            image_files::write(temporary, file, spec, PixelType::UInt16, pixels.data());
        });
    }
}

float signedPngRangeTexels(const Tile& tile) {
    float range = 0.0f;
    for (float distance : tile.distancesTexels()) range = std::max(range, std::abs(distance));
    return range > 0.0f ? range : 1.0f;
}

void writeSignedTilePng(const Tile& tile, const fs::path& file) {
    requirePngExport(
        tile, file, [](float d) { return !std::isfinite(d); }, "not finite");
    const Size3& size = tile.size();
    const float range = signedPngRangeTexels(tile);
    const auto distances = tile.distancesTexels();
    std::vector<std::uint16_t> codes(distances.size());
    std::transform(distances.begin(), distances.end(), codes.begin(), [&](float distance) {
        const double unit = std::clamp(0.5 + double(distance) / (2.0 * double(range)), 0.0, 1.0);
        return static_cast<std::uint16_t>(std::lround(unit * 65535.0));
    });
    const std::uint16_t fill = *std::max_element(codes.begin(), codes.end());
    const std::vector<std::uint16_t> pixels =
        toAtlas(size, std::span<const std::uint16_t>(codes), fill);
    image_files::Spec spec =
        tileSpec(size, PixelType::UInt16, tile.provenance, tileHash(tile), file);
    spec.set("oiio:ColorSpace", std::string("Linear"));  // data, not colour: no sRGB decoding
    char rangeText[32];
    std::snprintf(rangeText, sizeof rangeText, "%.9g", double(range));
    spec.set("distile:units", std::string("0.5 + distance / (2 x ") + rangeText +
                                  " texels), signed: distance = value x " +
                                  "2 R - R with R = distile:png_range_texels");
    spec.set("distile:png_range_texels", std::string(rangeText));
    writeAtomically(file, [&](const fs::path& temporary) {
        image_files::write(temporary, file, spec, PixelType::UInt16, pixels.data());
    });
}

}  // namespace distile
