#include "vdb/level_set.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <sstream>
#include <vector>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/input_file.h"
#include "vdb/detail/openvdb_setup.h"
#include "vdb/detail/vdb_header_check.h"

namespace distile {

namespace {

constexpr const char* kGridName = "surface";
constexpr const char* kSizeKey = "distile:size";
constexpr const char* kSourceKey = "distile:source";
constexpr const char* kParamsKey = "distile:params";

using detail::initializeOpenVdb;
using detail::texelTransform;

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

}  // namespace

struct LevelSet::Impl {
    openvdb::FloatGrid::Ptr grid;
    Size3 tile;
    std::string source;
    std::string params;
};

namespace {

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

}  // namespace

LevelSet::LevelSet(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
LevelSet::LevelSet(LevelSet&&) noexcept = default;
LevelSet& LevelSet::operator=(LevelSet&&) noexcept = default;
LevelSet::~LevelSet() = default;

LevelSet LevelSet::fromDistance(const DistanceFunction& distance, const Size3& tile,
                                float halfBandTexels, const std::string& source,
                                const std::string& params, const ProgressCallback& progress) {
    return fromDistanceRows(
        [&distance](int j, int k, std::span<double> row) {
            for (std::size_t i = 0; i < row.size(); ++i)
                row[i] = distance(glm::dvec3(double(i) + 0.5, j + 0.5, k + 0.5));
        },
        tile, halfBandTexels, source, params, progress);
}

LevelSet LevelSet::fromDistanceRows(const RowDistanceFunction& rowDistance, const Size3& tile,
                                    float halfBandTexels, const std::string& source,
                                    const std::string& params, const ProgressCallback& progress,
                                    bool fillMargins) {
    validateTileSize(tile, "level set");
    if (!(halfBandTexels >= 1.0f && halfBandTexels <= 1024.0f)) {
        throw InputError("level set: half band width " + std::to_string(halfBandTexels) +
                         " texels is not accepted; it must be in [1, 1024]");
    }
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

    auto impl = std::make_unique<Impl>();
    impl->grid = sparseGrid(dense, halfBandTexels, tile, source, params);
    impl->tile = tile;
    impl->source = source;
    impl->params = params;
    return LevelSet(std::move(impl));
}

LevelSet LevelSet::repeated(int repeatX, int repeatY) const {
    const Size3& tile = impl_->tile;
    const float halfBand = impl_->grid->background();
    const int margin = int(std::ceil(halfBand));
    const std::size_t voxels = std::size_t(tile.width) * std::size_t(std::max(repeatX, 1)) *
                               std::size_t(tile.height) * std::size_t(std::max(repeatY, 1)) *
                               std::size_t(tile.depth + 2 * margin);
    if (repeatX < 1 || repeatX > 64 || repeatY < 1 || repeatY > 64 ||
        voxels > (std::size_t(1) << 28)) {  // 1 GiB of float voxels
        throw InputError::inField("repeatX, repeatY", std::to_string(repeatX) + "x" +
                                                          std::to_string(repeatY) +
                                                          " is not accepted; each count must be "
                                                          "in [1, 64] and the repeated level "
                                                          "set at most 2^28 voxels (1 GiB)");
    }
    const openvdb::CoordBBox source(
        openvdb::Coord(0, 0, -margin),
        openvdb::Coord(tile.width - 1, tile.height - 1, tile.depth - 1 + margin));
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> one(source);
    openvdb::tools::copyToDense(*impl_->grid, one);
    const Size3 repeatedTile{tile.width * repeatX, tile.height * repeatY, tile.depth};
    const openvdb::CoordBBox box(
        openvdb::Coord(0, 0, -margin),
        openvdb::Coord(repeatedTile.width - 1, repeatedTile.height - 1, tile.depth - 1 + margin));
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(box);
    const float* from = one.data();
    float* to = dense.data();
    const std::size_t rows = std::size_t(tile.height) * std::size_t(tile.depth + 2 * margin);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t row = range.begin(); row != range.end(); ++row) {
                              const std::size_t j = row % std::size_t(tile.height);
                              const std::size_t k = row / std::size_t(tile.height);
                              const float* sourceRow = from + row * std::size_t(tile.width);
                              for (int n = 0; n < repeatY; ++n) {
                                  float* targetRow = to + (k * std::size_t(repeatedTile.height) +
                                                           std::size_t(n) * tile.height + j) *
                                                              std::size_t(repeatedTile.width);
                                  for (int m = 0; m < repeatX; ++m)
                                      std::copy_n(sourceRow, tile.width,
                                                  targetRow + std::size_t(m) * tile.width);
                              }
                          }
                      });
    auto impl = std::make_unique<Impl>();
    impl->grid = sparseGrid(dense, halfBand, repeatedTile, impl_->source, impl_->params);
    impl->tile = repeatedTile;
    impl->source = impl_->source;
    impl->params = impl_->params;
    return LevelSet(std::move(impl));
}

LevelSet LevelSet::load(const std::filesystem::path& file) {
    detail::checkVdbHeader(file, requireRegularFile(file, "an OpenVDB .vdb file"));
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
        if (chosen) grid = openvdb::gridPtrCast<openvdb::FloatGrid>(vdbFile.readGrid(chosen->getName()));
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
    auto impl = std::make_unique<Impl>();
    impl->tile = parseSize(sizeText, file.string());
    impl->source = stringMeta(*grid, kSourceKey);
    impl->params = stringMeta(*grid, kParamsKey);
    impl->grid = grid;
    return LevelSet(std::move(impl));
}

void LevelSet::save(const std::filesystem::path& file) const {
    writeAtomically(file, [&](const std::filesystem::path& temporary) {
        openvdb::io::File vdbFile(temporary.string());
        vdbFile.write({impl_->grid});
        vdbFile.close();
    });
}

const Size3& LevelSet::tileSize() const {
    return impl_->tile;
}
float LevelSet::halfBandTexels() const {
    return impl_->grid->background();
}
const std::string& LevelSet::source() const {
    return impl_->source;
}
const std::string& LevelSet::params() const {
    return impl_->params;
}
std::size_t LevelSet::activeVoxelCount() const {
    return impl_->grid->activeVoxelCount();
}

float LevelSet::voxelDistanceTexels(int i, int j, int k) const {
    return impl_->grid->tree().getValue(openvdb::Coord(i, j, k));
}

void LevelSet::copyTileVoxels(std::span<float> texels) const {
    const Size3& tile = impl_->tile;
    assert(texels.size() == tile.texelCount());
    const openvdb::CoordBBox box(openvdb::Coord(0, 0, 0),
                                 openvdb::Coord(tile.width - 1, tile.height - 1, tile.depth - 1));
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(box, texels.data());
    openvdb::tools::copyToDense(*impl_->grid, dense);
}

}  // namespace distile
