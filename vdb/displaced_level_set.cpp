#include "vdb/displaced_level_set.h"

#include "vdb/detail/openvdb_module.h"

namespace distile {

DisplacedMesh buildDisplacedMesh(const DetailDistanceFunction& detail, const Size3& tile,
                                 const DisplacementShell& shell,
                                 const DisplacedMeshOptions& options) {
    return detail::openVdb().buildDisplacedMesh(detail, tile, shell, options);
}

DisplacedLevelSet::DisplacedLevelSet(detail::BuiltDisplacedLevelSet built)
    : built_(std::make_unique<detail::BuiltDisplacedLevelSet>(std::move(built))) {}
DisplacedLevelSet::DisplacedLevelSet(DisplacedLevelSet&&) noexcept = default;
DisplacedLevelSet& DisplacedLevelSet::operator=(DisplacedLevelSet&&) noexcept = default;
DisplacedLevelSet::~DisplacedLevelSet() = default;

const DisplacedLevelSetStats& DisplacedLevelSet::stats() const {
    return built_->stats;
}

DisplacedLevelSet DisplacedLevelSet::build(const DistanceFunction& detail, const Size3& tile,
                                           const DisplacementShell& shell,
                                           const DisplacedLevelSetOptions& options) {
    detail::validateDisplacedLevelSetOptions(options);
    return build(buildDisplacedMesh(detail, tile, shell, options.mesh), options);
}

DisplacedLevelSet DisplacedLevelSet::build(const DisplacedMesh& mesh,
                                           const DisplacedLevelSetOptions& options) {
    return DisplacedLevelSet(detail::openVdb().buildDisplacedLevelSet(mesh, options));
}

bool DisplacedLevelSet::intersect(const glm::dvec3& origin, const glm::dvec3& unitDirection,
                                  double maxDistanceWorld, double& distanceWorld,
                                  glm::dvec3& normalWorld) const {
    return built_->grid->intersect(origin, unitDirection, maxDistanceWorld, distanceWorld,
                                   normalWorld);
}

}  // namespace distile
