#include "vdb/displaced_level_set.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>

#include "common/error.h"
#include "vdb/detail/openvdb_module.h"

namespace distile {

namespace {

/// Bytes OpenVDB's meshToVolume holds per voxel of the narrow band while it builds: a float
/// distance and an int32 closest-polygon index per voxel, their partitions and tree overhead,
/// with room (an estimate, not a measurement).
constexpr double kBuildBytesPerBandVoxel = 40.0;

/// The most memory building one world level set may take, bytes.
constexpr double kLevelSetBuildBudgetBytes = double(1u << 30);

/// World area of the mesh's triangles and quads, world units squared.
double surfaceAreaWorld(const DisplacedMesh& mesh) {
    const auto& p = mesh.positions;
    double area = 0.0;
    for (const glm::uvec3& t : mesh.triangles)
        area +=
            0.5 * glm::length(glm::cross(glm::dvec3(p[t.y] - p[t.x]), glm::dvec3(p[t.z] - p[t.x])));
    for (const glm::uvec4& q : mesh.quads) {
        area +=
            0.5 * glm::length(glm::cross(glm::dvec3(p[q.z] - p[q.x]), glm::dvec3(p[q.w] - p[q.y])));
    }
    return area;
}

}  // namespace

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

double DisplacedLevelSet::voxelsPerTexel(const DisplacedMesh& mesh,
                                         const DisplacedLevelSetOptions& options) {
    detail::validateDisplacedLevelSetOptions(options);
    if (mesh.triangles.empty() && mesh.quads.empty())
        throw InputError("world reference mesh: detail: the mesh is empty");
    // The band's voxels, estimated from the surface before OpenVDB allocates for them: the
    // surface's area over a voxel's, times the band's width. Per voxel per texel squared:
    const double bandVoxelsPerSquare = surfaceAreaWorld(mesh) /
                                       (mesh.stats.texelSizeWorld * mesh.stats.texelSizeWorld) *
                                       2.0 * double(options.halfBandVoxels);
    // The finest resolution the budget allows, rounded down to a hundredth.
    const double largest =
        std::floor(100.0 * std::sqrt(kLevelSetBuildBudgetBytes /
                                     (bandVoxelsPerSquare * kBuildBytesPerBandVoxel))) /
        100.0;
    const double chosen = options.voxelsPerTexel != 0.0
                              ? options.voxelsPerTexel
                              : std::min(DisplacedLevelSetOptions::kAutomaticVoxelsPerTexel,
                                         std::max(largest, detail::kMinVoxelsPerTexel));
    const double bandVoxels = bandVoxelsPerSquare * chosen * chosen;
    if (!(bandVoxels * kBuildBytesPerBandVoxel <= kLevelSetBuildBudgetBytes)) {
        char message[200];
        std::snprintf(message, sizeof message,
                      "%s needs about %.1f GB for this detail's surface; at most 1 GiB is "
                      "accepted, so use at most %.2f",
                      numberText(chosen).c_str(), bandVoxels * kBuildBytesPerBandVoxel / 1e9,
                      largest);
        throw InputError(std::string("world reference mesh: voxels per texel: ") + message);
    }
    return chosen;
}

DisplacedLevelSet DisplacedLevelSet::build(const DisplacedMesh& mesh,
                                           const DisplacedLevelSetOptions& options) {
    DisplacedLevelSetOptions resolved = options;
    resolved.voxelsPerTexel = voxelsPerTexel(mesh, options);
    return DisplacedLevelSet(detail::openVdb().buildDisplacedLevelSet(mesh, resolved));
}

bool DisplacedLevelSet::intersect(const glm::dvec3& origin, const glm::dvec3& unitDirection,
                                  double maxDistanceWorld, double& distanceWorld,
                                  glm::dvec3& normalWorld) const {
    return built_->grid->intersect(origin, unitDirection, maxDistanceWorld, distanceWorld,
                                   normalWorld);
}

}  // namespace distile
