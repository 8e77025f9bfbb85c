#include "vdb/vdb_volume.h"

#include <cmath>

#include "common/detail/module_loader.h"
#include "common/error.h"
#include "common/input_file.h"
#include "vdb/detail/openvdb_module.h"

namespace distile {

VdbVolume::VdbVolume(detail::ReadVolume volume)
    : volume_(std::make_unique<detail::ReadVolume>(std::move(volume))) {}
VdbVolume::VdbVolume(VdbVolume&&) noexcept = default;
VdbVolume& VdbVolume::operator=(VdbVolume&&) noexcept = default;
VdbVolume::~VdbVolume() = default;

VdbVolume VdbVolume::read(const std::filesystem::path& file, const std::string& gridName,
                          std::optional<double> iso) {
    detail::requireVdbInput(file);
    return VdbVolume(detail::openVdb().readVolume(file, gridName, iso));
}

std::vector<VdbGridInfo> listVdbGrids(const std::filesystem::path& file) {
    detail::requireVdbInput(file);
    return detail::openVdb().listVdbGrids(file);
}

const std::string& VdbVolume::gridName() const {
    return volume_->name;
}
bool VdbVolume::isLevelSet() const {
    return volume_->levelSet;
}
double VdbVolume::iso() const {
    return volume_->iso;
}
glm::dvec3 VdbVolume::voxelSizeWorld() const {
    return volume_->grid->voxelSizeWorld();
}
Bounds3 VdbVolume::activeBoundsWorld() const {
    return volume_->activeBounds;
}
Bounds3 VdbVolume::surfaceBoundsWorld() const {
    return volume_->surfaceBounds;
}
const TriangleSoup& VdbVolume::surfaceWorld() const {
    return volume_->surface;
}
TriangleSoup VdbVolume::refinedSurfaceWorld(double maxEdgeWorld, const Bounds3& regionWorld) const {
    return volume_->grid->refinedSurfaceWorld(volume_->surface, volume_->iso, maxEdgeWorld,
                                              regionWorld);
}

VdbSourceSampler::VdbSourceSampler(const VdbVolume& volume, const TexelPlacement& placement) {
    if (!(std::isfinite(placement.scale) && placement.scale > 0.0)) {
        throw InputError::inField("placement.scale",
                                  numberText(placement.scale) +
                                      " is not accepted; it must be a finite number > 0 (texels "
                                      "per world unit)");
    }
    if (!(std::isfinite(placement.offsetTexels.x) && std::isfinite(placement.offsetTexels.y) &&
          std::isfinite(placement.offsetTexels.z))) {
        throw InputError::inField("placement.offsetTexels",
                                  "must be three finite numbers (texels)");
    }
    const detail::ReadVolume& source = *volume.volume_;
    sampler_ = source.grid->sampler(source.levelSet, source.iso, placement);
    levelSet_ = source.levelSet;
}
VdbSourceSampler::VdbSourceSampler(VdbSourceSampler&&) noexcept = default;
VdbSourceSampler::~VdbSourceSampler() = default;

bool VdbSourceSampler::isLevelSet() const {
    return levelSet_;
}
double VdbSourceSampler::bandTexels() const {
    return sampler_->bandTexels();
}
VdbSourceSampler::Sample VdbSourceSampler::sample(const glm::dvec3& texelPosition) const {
    return sampler_->sample(texelPosition);
}

void writeSphereVolumes(const std::filesystem::path& file,
                        const std::vector<SphereVolumeOptions>& spheres) {
    detail::openVdb().writeSphereVolumes(file, spheres);
}

namespace detail {

void requireVdbInput(const std::filesystem::path& file) {
    requireRegularFile(file, "an OpenVDB .vdb file");
}

const OpenVdbFunctions& openVdb() {
    static const OpenVdbFunctions& functions = *static_cast<const OpenVdbFunctions*>(
        loadModule({DISTILE_OPENVDB_MODULE_NAME, DISTILE_OPENVDB_MODULE_DIR, kOpenVdbModuleEntry,
                    "distile_vdb_openvdb"}));
    return functions;
}

}  // namespace detail

}  // namespace distile
