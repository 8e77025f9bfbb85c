#include "vdb/level_set.h"

#include <cmath>
#include <string>

#include "common/atomic_file.h"
#include "common/error.h"
#include "vdb/detail/openvdb_module.h"

namespace distile {

LevelSet::LevelSet(detail::LevelSetParts parts)
    : parts_(std::make_unique<detail::LevelSetParts>(std::move(parts))) {}
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
        throw InputError("level set: half band width " + numberText(halfBandTexels) +
                         " texels is not accepted; it must be in [1, 1024]");
    }
    return LevelSet({detail::openVdb().levelSetFromDistanceRows(
                         rowDistance, tile, halfBandTexels, source, params, progress, fillMargins),
                     tile, source, params});
}

void LevelSet::checkRepeat(const Size3& tile, float halfBandTexels, int repeatX, int repeatY) {
    const int margin = int(std::ceil(halfBandTexels));
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
}

LevelSet LevelSet::repeated(int repeatX, int repeatY) const {
    const Size3& tile = parts_->tile;
    checkRepeat(tile, parts_->grid->halfBandTexels(), repeatX, repeatY);
    return LevelSet({parts_->grid->repeated(tile, repeatX, repeatY, parts_->source, parts_->params),
                     {tile.width * repeatX, tile.height * repeatY, tile.depth},
                     parts_->source,
                     parts_->params});
}

LevelSet LevelSet::load(const std::filesystem::path& file) {
    detail::requireVdbInput(file);
    return LevelSet(detail::openVdb().loadLevelSet(file));
}

void LevelSet::save(const std::filesystem::path& file) const {
    writeAtomically(
        file, [&](const std::filesystem::path& temporary) { parts_->grid->write(temporary); });
}

const Size3& LevelSet::tileSize() const {
    return parts_->tile;
}
float LevelSet::halfBandTexels() const {
    return parts_->grid->halfBandTexels();
}
const std::string& LevelSet::source() const {
    return parts_->source;
}
const std::string& LevelSet::params() const {
    return parts_->params;
}
std::size_t LevelSet::activeVoxelCount() const {
    return parts_->grid->activeVoxelCount();
}
float LevelSet::voxelDistanceTexels(int i, int j, int k) const {
    return parts_->grid->voxelDistanceTexels(i, j, k);
}
void LevelSet::copyTileVoxels(std::span<float> texels) const {
    parts_->grid->copyTileVoxels(parts_->tile, texels);
}

}  // namespace distile
