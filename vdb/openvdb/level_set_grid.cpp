// The OpenVDB half of vdb/level_set.h, in the module (vdb/detail/openvdb_module.h).
#include <openvdb/io/Archive.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cassert>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <span>
#include <sstream>
#include <string_view>
#include <vector>

#include "common/error.h"
#include "common/fnv1a.h"
#include "common/input_file.h"
#include "vdb/openvdb/openvdb_parts.h"
#include "vdb/openvdb/openvdb_setup.h"
#include "vdb/openvdb/vdb_header_check.h"

namespace distile::detail {

namespace {

constexpr const char* kGridName = "surface";
constexpr const char* kSizeKey = "distile:size";
constexpr const char* kSourceKey = "distile:source";
constexpr const char* kParamsKey = "distile:params";

/// OpenVDB stamps every file it writes with a random UUID, so the same grid written twice gave
/// two different files. Replace it with one made of a hash of the file's other bytes: the same
/// grid gives the same file, and a changed grid still a new UUID (what readers use it for).
/// What openvdb::io::File writes (the grids with their offsets, for random access), written to a
/// stream the caller owns and checks: io::File never checks its own after writing, so a full
/// disk left a truncated file that seemed written.
class VdbFileWriter final : public openvdb::io::Archive {
  public:
    void writeTo(std::ostream& stream, const openvdb::GridCPtrVec& grids) const {
        Archive::write(stream, grids, /*seekable=*/true);
    }
};

void stampContentUuid(const std::filesystem::path& file) {
    // The header: the magic (8 bytes), the file version and the library's major and minor version
    // (4 bytes each), the grid-offsets flag (1 byte), then the UUID as 36 characters.
    constexpr std::streamoff kUuidAt = 8 + 4 + 4 + 4 + 1;
    constexpr std::size_t kUuidLength = 36;
    std::fstream stream(file, std::ios::in | std::ios::out | std::ios::binary);
    std::string header(std::size_t(kUuidAt) + kUuidLength, '\0');
    if (!stream.read(header.data(), std::streamsize(header.size())))
        throw std::runtime_error(file.string() + ": OpenVDB wrote no file header");
    const std::string_view uuid = std::string_view(header).substr(std::size_t(kUuidAt));
    for (std::size_t n = 0; n < kUuidLength; ++n) {
        const bool dash = n == 8 || n == 13 || n == 18 || n == 23;
        if (dash ? uuid[n] != '-' : !std::isxdigit(static_cast<unsigned char>(uuid[n])))
            throw std::runtime_error(file.string() +
                                     ": OpenVDB wrote no UUID where one was expected");
    }
    // FNV-1a 64 of every byte but the UUID's, twice from different offset bases. Each byte goes
    // to both hashes in turn, so that their multiplications overlap.
    Fnv1a64 first;
    Fnv1a64 second(0x84222325cbf29ce4ull);
    const auto add = [&](const char* bytes, std::size_t count) {
        for (const std::byte byte : std::as_bytes(std::span(bytes, count))) {
            first.update(byte);
            second.update(byte);
        }
    };
    add(header.data(), std::size_t(kUuidAt));
    std::vector<char> chunk(1 << 20);
    while (stream.read(chunk.data(), std::streamsize(chunk.size())) || stream.gcount() > 0)
        add(chunk.data(), std::size_t(stream.gcount()));
    char digits[40];
    std::snprintf(digits, sizeof digits, "%08llx-%04llx-%04llx-%04llx-%012llx",
                  static_cast<unsigned long long>(first.value() >> 32),
                  static_cast<unsigned long long>((first.value() >> 16) & 0xffff),
                  static_cast<unsigned long long>(first.value() & 0xffff),
                  static_cast<unsigned long long>(second.value() >> 48),
                  static_cast<unsigned long long>(second.value() & 0xffffffffffffull));
    stream.clear();
    stream.seekp(kUuidAt);
    if (!stream.write(digits, std::streamsize(kUuidLength)) || !stream.flush())
        throw std::runtime_error(file.string() + ": could not write the file's UUID (" +
                                 std::strerror(errno) + ")");
}

std::string stringMeta(const openvdb::FloatGrid& grid, const char* key) {
    auto meta = grid.getMetadata<openvdb::StringMetadata>(key);
    return meta ? meta->value() : std::string();
}

Size3 parseSize(const std::string& text, const std::string& file) {
    Size3 size{0, 0, 0};
    char x1 = 0;
    char x2 = 0;
    std::istringstream in(text);
    if (!(in >> size.width >> x1 >> size.height >> x2 >> size.depth) || x1 != 'x' || x2 != 'x') {
        throw FormatError(file + ": " + kSizeKey + " = '" + text + "' is not WxHxD");
    }
    validateTileSize(size, file + ": " + kSizeKey);
    return size;
}

/// The sparse level set of a dense block of clamped distances: voxels at -halfBand lie deep inside
/// and become inactive, like the background outside; grid class, name, transform and metadata as
/// the file note of level_set.h says.
openvdb::FloatGrid::Ptr sparseGrid(
    const openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ>& dense, float halfBandTexels,
    const Size3& tile, const std::string& source, const std::string& params) {
    auto grid = openvdb::FloatGrid::create(halfBandTexels);
    openvdb::tools::copyFromDense(dense, *grid, /*tolerance=*/0.0f);
    for (auto voxel = grid->tree().beginValueOn(); voxel; ++voxel) {
        if (*voxel <= -halfBandTexels) voxel.setActiveState(false);
    }
    grid->tree().prune();
    grid->setTransform(texelTransform());
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    grid->setName(kGridName);
    grid->insertMeta(kSizeKey, openvdb::StringMetadata(toString(tile)));
    grid->insertMeta(kSourceKey, openvdb::StringMetadata(source));
    grid->insertMeta(kParamsKey, openvdb::StringMetadata(params));
    grid->insertMeta("distile:units", openvdb::StringMetadata("texels"));
    return grid;
}

/// A level set's grid, in texel space.
class OpenVdbLevelSetGrid final : public LevelSetGrid {
  public:
    explicit OpenVdbLevelSetGrid(openvdb::FloatGrid::Ptr grid) : grid_(std::move(grid)) {}

    float halfBandTexels() const override { return grid_->background(); }
    std::size_t activeVoxelCount() const override { return grid_->activeVoxelCount(); }
    float voxelDistanceTexels(int i, int j, int k) const override {
        return grid_->tree().getValue(openvdb::Coord(i, j, k));
    }

    void copyTileVoxels(const Size3& tile, std::span<float> texels) const override {
        assert(texels.size() == tile.texelCount());
        const openvdb::CoordBBox box(
            openvdb::Coord(0, 0, 0),
            openvdb::Coord(tile.width - 1, tile.height - 1, tile.depth - 1));
        openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(box, texels.data());
        openvdb::tools::copyToDense(*grid_, dense);
    }

    std::unique_ptr<LevelSetGrid> repeated(const Size3& tile, int repeatX, int repeatY,
                                           const std::string& source,
                                           const std::string& params) const override {
        const float halfBand = grid_->background();
        const int margin = int(std::ceil(halfBand));
        const openvdb::CoordBBox one(
            openvdb::Coord(0, 0, -margin),
            openvdb::Coord(tile.width - 1, tile.height - 1, tile.depth - 1 + margin));
        openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> tileVoxels(one);
        openvdb::tools::copyToDense(*grid_, tileVoxels);
        const Size3 repeatedTile{tile.width * repeatX, tile.height * repeatY, tile.depth};
        const openvdb::CoordBBox box(openvdb::Coord(0, 0, -margin),
                                     openvdb::Coord(repeatedTile.width - 1, repeatedTile.height - 1,
                                                    tile.depth - 1 + margin));
        openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(box);
        const float* from = tileVoxels.data();
        float* to = dense.data();
        const std::size_t rows = std::size_t(tile.height) * std::size_t(tile.depth + 2 * margin);
        // Row j of slice k goes to rows n * height + j (n < repeatY) of slice k, repeatX times
        // side by side.
        const auto copyRows = [&](const tbb::blocked_range<std::size_t>& range) {
            for (std::size_t row = range.begin(); row != range.end(); ++row) {
                const std::size_t j = row % std::size_t(tile.height);
                const std::size_t k = row / std::size_t(tile.height);
                const float* sourceRow = from + row * std::size_t(tile.width);
                for (int n = 0; n < repeatY; ++n) {
                    const std::size_t targetRowIndex =
                        k * std::size_t(repeatedTile.height) + std::size_t(n) * tile.height + j;
                    float* targetRow = to + targetRowIndex * std::size_t(repeatedTile.width);
                    for (int m = 0; m < repeatX; ++m)
                        std::copy_n(sourceRow, tile.width, targetRow + std::size_t(m) * tile.width);
                }
            }
        };
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows), copyRows);
        return std::make_unique<OpenVdbLevelSetGrid>(
            sparseGrid(dense, halfBand, repeatedTile, source, params));
    }

    void write(const std::filesystem::path& file) const override {
        std::ofstream stream(file, std::ios::binary | std::ios::trunc);
        if (!stream) {
            throw std::runtime_error(file.string() + ": cannot be opened for writing (" +
                                     std::strerror(errno) + ")");
        }
        VdbFileWriter().writeTo(stream, {grid_});
        stream.close();
        if (!stream) {
            throw std::runtime_error(file.string() + ": writing failed (" + std::strerror(errno) +
                                     ")");
        }
        stampContentUuid(file);
    }

  private:
    openvdb::FloatGrid::Ptr grid_;
};

}  // namespace

std::unique_ptr<LevelSetGrid> levelSetFromDistanceRows(
    const LevelSet::RowDistanceFunction& rowDistance, const Size3& tile, float halfBandTexels,
    const std::string& source, const std::string& params, const ProgressCallback& progress,
    bool fillMargins) {
    initializeOpenVdb();
    // Fill a dense block, one z slab at a time (progress is reported between slabs, on this
    // thread), then let OpenVDB build the sparse tree from it.
    const int margin = int(std::ceil(halfBandTexels));
    const openvdb::CoordBBox box(
        openvdb::Coord(0, 0, -margin),
        openvdb::Coord(tile.width - 1, tile.height - 1, tile.depth - 1 + margin));
    const int slabs = box.dim().z();
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(box);
    float* values = dense.data();
    const std::size_t slabStride = std::size_t(tile.width) * std::size_t(tile.height);
    for (int slab = 0; slab < slabs; ++slab) {
        const int k = box.min().z() + slab;
        float* slabValues = values + std::size_t(slab) * slabStride;
        if (!fillMargins && (k < 0 || k >= tile.depth)) {
            std::fill_n(slabValues, slabStride, halfBandTexels);  // the background: inactive
            continue;
        }
        tbb::parallel_for(
            tbb::blocked_range<int>(0, tile.height), [&](const tbb::blocked_range<int>& rows) {
                std::vector<double> row(std::size_t(tile.width));
                for (int j = rows.begin(); j != rows.end(); ++j) {
                    rowDistance(j, k, row);
                    for (int i = 0; i < tile.width; ++i) {
                        slabValues[std::size_t(j) * tile.width + i] =
                            std::clamp(float(row[std::size_t(i)]), -halfBandTexels, halfBandTexels);
                    }
                }
            });
        if (progress) progress(double(slab + 1) / slabs);
    }
    return std::make_unique<OpenVdbLevelSetGrid>(
        sparseGrid(dense, halfBandTexels, tile, source, params));
}

LevelSetParts loadLevelSet(const std::filesystem::path& file) {
    checkVdbHeader(file, requireRegularFile(file, "an OpenVDB .vdb file"));
    initializeOpenVdb();
    // Only the chosen float level set's voxels are read (the header check walked float trees).
    openvdb::FloatGrid::Ptr grid;
    try {
        openvdb::io::File vdbFile(file.string());
        vdbFile.open(/*delayLoad=*/false);
        openvdb::GridBase::ConstPtr chosen;
        const openvdb::GridPtrVecPtr metadata = vdbFile.readAllGridMetadata();
        for (const auto& candidate : *metadata) {
            if (candidate->isType<openvdb::FloatGrid>() &&
                candidate->getGridClass() == openvdb::GRID_LEVEL_SET &&
                (!chosen || candidate->getName() == kGridName)) {
                chosen = candidate;
            }
        }
        if (chosen)
            grid = openvdb::gridPtrCast<openvdb::FloatGrid>(vdbFile.readGrid(chosen->getName()));
        vdbFile.close();
    } catch (const std::exception& error) {
        throw FormatError(file.string() + ": not a readable .vdb file (" + error.what() + ")");
    }
    if (!grid) throw FormatError(file.string() + ": holds no float level set grid");
    const std::string sizeText = stringMeta(*grid, kSizeKey);
    if (sizeText.empty()) {
        throw FormatError(file.string() + ": level set '" + grid->getName() +
                          "' has no distile:size metadata; write level sets with `distile bake`");
    }
    const openvdb::Vec3d voxelSize = grid->voxelSize();
    if (!grid->transform().isLinear() || std::abs(voxelSize.x() - 1.0) > 1e-6 ||
        std::abs(voxelSize.y() - 1.0) > 1e-6 || std::abs(voxelSize.z() - 1.0) > 1e-6) {
        throw FormatError(file.string() + ": voxel size is not 1 texel");
    }
    LevelSetParts loaded;
    loaded.tile = parseSize(sizeText, file.string());
    loaded.source = stringMeta(*grid, kSourceKey);
    loaded.params = stringMeta(*grid, kParamsKey);
    loaded.grid = std::make_unique<OpenVdbLevelSetGrid>(grid);
    return loaded;
}

}  // namespace distile::detail
