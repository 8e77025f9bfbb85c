#include "vdb/vdb_volume.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <sstream>

#include "common/error.h"
#include "common/input_file.h"
#include "vdb/detail/openvdb_setup.h"
#include "vdb/detail/vdb_header_check.h"

namespace distile {

namespace {

using Accessor = openvdb::tree::ValueAccessor<const openvdb::FloatTree, /*IsSafe=*/false>;

using detail::initializeOpenVdb;

std::string describe(const openvdb::GridBase& grid) {
    return "'" + grid.getName() + "' (" + grid.valueType() + ", " +
           openvdb::GridBase::gridClassToString(grid.getGridClass()) + ")";
}

std::string listGrids(const openvdb::GridPtrVec& grids) {
    std::string list;
    for (const auto& grid : grids) list += (list.empty() ? "" : ", ") + describe(*grid);
    return list.empty() ? "no grids" : list;
}

/// All grids' metadata, without their voxels. OpenVDB throws on a corrupt or truncated file and a
/// flipped header can ask for a huge allocation: both become FormatError.
openvdb::GridPtrVecPtr readGridMetadata(const std::filesystem::path& file) {
    detail::checkVdbHeader(file, requireRegularFile(file, "an OpenVDB .vdb file"));
    initializeOpenVdb();
    openvdb::GridPtrVecPtr grids;
    try {
        openvdb::io::File vdbFile(file.string());
        vdbFile.open(/*delayLoad=*/false);
        grids = vdbFile.readAllGridMetadata();
        vdbFile.close();
    } catch (const std::bad_alloc&) {
        throw FormatError(file.string() +
                          ": not a readable .vdb file (its header asks for more "
                          "memory than there is; the file is corrupt)");
    } catch (const std::exception& error) {
        throw FormatError(file.string() + ": not a readable .vdb file (" + error.what() + ")");
    }
    // OpenVDB reads a file of a format version it does not know as one without grids.
    if (!grids || grids->empty()) {
        throw FormatError(file.string() +
                          ": holds no grids (an empty, corrupt or too new .vdb file)");
    }
    return grids;
}

Bounds3 worldBoundsOfIndexBox(const openvdb::math::Transform& transform, const openvdb::Vec3d& min,
                              const openvdb::Vec3d& max) {
    Bounds3 box{glm::dvec3(HUGE_VAL), glm::dvec3(-HUGE_VAL)};
    for (int corner = 0; corner < 8; ++corner) {
        const openvdb::Vec3d index((corner & 1) ? max.x() : min.x(),
                                   (corner & 2) ? max.y() : min.y(),
                                   (corner & 4) ? max.z() : min.z());
        const openvdb::Vec3d world = transform.indexToWorld(index);
        for (int axis = 0; axis < 3; ++axis) {
            box.min[axis] = std::min(box.min[axis], world[axis]);
            box.max[axis] = std::max(box.max[axis], world[axis]);
        }
    }
    return box;
}

bool isFiniteBox(const Bounds3& box) {
    for (int axis = 0; axis < 3; ++axis) {
        if (!std::isfinite(box.min[axis]) || !std::isfinite(box.max[axis])) return false;
    }
    return true;
}

}  // namespace

struct VdbVolume::Impl {
    openvdb::FloatGrid::Ptr grid;
    std::string name;
    bool levelSet = true;
    double iso = 0.0;
    Bounds3 activeBounds;
    Bounds3 surfaceBounds;
    /// The polygonised iso surface, world space.
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
};

VdbVolume::VdbVolume(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
VdbVolume::VdbVolume(VdbVolume&&) noexcept = default;
VdbVolume& VdbVolume::operator=(VdbVolume&&) noexcept = default;
VdbVolume::~VdbVolume() = default;

std::vector<VdbGridInfo> listVdbGrids(const std::filesystem::path& file) {
    std::vector<VdbGridInfo> list;
    for (const auto& grid : *readGridMetadata(file)) {
        list.push_back({grid->getName(), grid->valueType(),
                        openvdb::GridBase::gridClassToString(grid->getGridClass())});
    }
    return list;
}

VdbVolume VdbVolume::read(const std::filesystem::path& file, const std::string& gridName,
                          std::optional<double> iso) {
    const std::string name = file.string();
    if (iso && !std::isfinite(*iso)) {
        throw InputError::inField("iso", "must be a finite number");
    }
    const openvdb::GridPtrVecPtr metadata = readGridMetadata(file);
    openvdb::GridBase::ConstPtr chosen;
    if (!gridName.empty()) {
        for (const auto& grid : *metadata) {
            if (grid->getName() == gridName) {
                chosen = grid;
                break;
            }
        }
        if (!chosen) {
            throw InputError::inField("grid", "'" + gridName + "' is not in " + name +
                                                  "; its grids: " + listGrids(*metadata));
        }
        if (chosen->valueType() != openvdb::typeNameAsString<float>()) {
            throw InputError::inField("grid", describe(*chosen) + " in " + name +
                                                  " is not a float grid; accepted: float level "
                                                  "sets and fog volumes");
        }
    } else {
        std::vector<openvdb::GridBase::ConstPtr> levelSets;
        for (const auto& grid : *metadata) {
            if (grid->valueType() == openvdb::typeNameAsString<float>() &&
                grid->getGridClass() == openvdb::GRID_LEVEL_SET) {
                levelSets.push_back(grid);
            }
        }
        if (levelSets.size() != 1) {
            const bool none = levelSets.empty();
            throw InputError::inField(
                "grid", name + (none ? " holds no float level set" : " holds several level sets") +
                            " (its grids: " + listGrids(*metadata) + "); choose a grid by name" +
                            (none ? ", with an iso value if it is a fog volume" : ""));
        }
        chosen = levelSets.front();
    }
    const bool levelSet = chosen->getGridClass() == openvdb::GRID_LEVEL_SET;
    if (!levelSet && !iso) {
        throw InputError::inField(
            "iso", "grid " + describe(*chosen) + " in " + name +
                       " is not a level set; give the iso value where its surface lies (inside "
                       "where the value is above it), e.g. 0.5 for a fog volume");
    }

    // The writer's record of the grid's size in memory: a grid beyond the memory budget (or a
    // corrupt record) is refused before the voxels are read.
    if (const auto bytes =
            chosen->getMetadata<openvdb::Int64Metadata>(openvdb::GridBase::META_FILE_MEM_BYTES);
        bytes && bytes->value() < 0) {
        throw FormatError(name + ": grid '" + chosen->getName() + "' says it needs " +
                          std::to_string(bytes->value()) +
                          " bytes in memory (the file is corrupt)");
    } else if (bytes) {
        requireWithinMemoryBudget(file, "grid '" + chosen->getName() + "'",
                                  std::uint64_t(bytes->value()));
    }
    openvdb::FloatGrid::Ptr grid;
    try {
        openvdb::io::File vdbFile(name);
        vdbFile.open(/*delayLoad=*/false);
        grid = openvdb::gridPtrCast<openvdb::FloatGrid>(vdbFile.readGrid(chosen->getName()));
        vdbFile.close();
    } catch (const std::bad_alloc&) {
        throw FormatError(name + ": grid '" + chosen->getName() +
                          "' is not readable (it asks for more memory than there is; the file is "
                          "corrupt)");
    } catch (const std::exception& error) {
        throw FormatError(name + ": grid '" + chosen->getName() + "' is not readable (" +
                          error.what() + ")");
    }
    if (!grid) throw FormatError(name + ": grid '" + chosen->getName() + "' is not readable");

    const openvdb::math::Transform& transform = grid->transform();
    const openvdb::Vec3d voxelSize = transform.voxelSize();
    bool invertible = true;
    if (transform.isLinear()) {
        const openvdb::Mat4d matrix = transform.baseMap()->getAffineMap()->getMat4();
        for (int row = 0; row < 4; ++row)
            for (int column = 0; column < 4; ++column)
                invertible = invertible && std::isfinite(matrix(row, column));
        invertible = invertible && std::abs(matrix.getMat3().det()) > 0.0;
    }
    for (int axis = 0; axis < 3; ++axis) {
        invertible = invertible && std::isfinite(voxelSize[axis]) && voxelSize[axis] > 0.0;
    }
    if (!invertible) {
        std::ostringstream message;
        message << name << ": grid '" << grid->getName() << "' has a transform that is not finite "
                << "and invertible (voxel size " << voxelSize << ")";
        throw FormatError(message.str());
    }
    const openvdb::CoordBBox active = grid->evalActiveVoxelBoundingBox();
    if (grid->activeVoxelCount() == 0 || active.empty()) {
        throw FormatError(name + ": grid '" + grid->getName() + "' is empty (no active voxels)");
    }

    auto impl = std::make_unique<Impl>();
    impl->levelSet = levelSet;
    impl->iso = iso.value_or(0.0);
    impl->activeBounds =
        worldBoundsOfIndexBox(transform, active.min().asVec3d(), active.max().asVec3d());
    openvdb::tools::volumeToMesh(*grid, impl->points, impl->triangles, impl->quads, impl->iso,
                                 /*adaptivity=*/0.0);
    if (impl->points.empty() || (impl->triangles.empty() && impl->quads.empty())) {
        std::ostringstream message;
        message << name << ": grid '" << grid->getName() << "' has no surface: its values never "
                << "cross " << impl->iso;
        throw FormatError(message.str());
    }
    Bounds3 surface{glm::dvec3(HUGE_VAL), glm::dvec3(-HUGE_VAL)};
    for (const openvdb::Vec3s& point : impl->points) {
        for (int axis = 0; axis < 3; ++axis) {
            surface.min[axis] = std::min(surface.min[axis], double(point[axis]));
            surface.max[axis] = std::max(surface.max[axis], double(point[axis]));
        }
    }
    if (!isFiniteBox(surface) || !isFiniteBox(impl->activeBounds)) {
        throw FormatError(name + ": grid '" + grid->getName() +
                          "' has world positions that are not finite (check its transform)");
    }
    impl->surfaceBounds = surface;
    impl->grid = grid;
    impl->name = grid->getName();
    return VdbVolume(std::move(impl));
}

const std::string& VdbVolume::gridName() const {
    return impl_->name;
}
bool VdbVolume::isLevelSet() const {
    return impl_->levelSet;
}
double VdbVolume::iso() const {
    return impl_->iso;
}
glm::dvec3 VdbVolume::voxelSizeWorld() const {
    const openvdb::Vec3d size = impl_->grid->transform().voxelSize();
    return {size.x(), size.y(), size.z()};
}
Bounds3 VdbVolume::activeBoundsWorld() const {
    return impl_->activeBounds;
}
Bounds3 VdbVolume::surfaceBoundsWorld() const {
    return impl_->surfaceBounds;
}

struct VdbTileSampler::Impl {
    openvdb::FloatGrid::ConstPtr source;
    bool levelSet = true;
    double iso = 0.0;
    double scale = 1.0;
    glm::dvec3 offsetTexels{0.0};
    float halfBandTexels = 1.0f;
    /// Unsigned distances to the polygonised surface, texel space (voxel (i, j, k) centred at
    /// texel (i + 0.5, j + 0.5, k + 0.5)); null when the source band is wide enough.
    openvdb::FloatGrid::Ptr rebuilt;
};

VdbTileSampler::VdbTileSampler(const VdbVolume& volume, const TexelPlacement& placement,
                               const Size3& tile, float halfBandTexels)
    : impl_(std::make_unique<Impl>()) {
    validateTileSize(tile, "size");
    if (!(std::isfinite(placement.scale) && placement.scale > 0.0)) {
        throw InputError::inField("placement.scale",
                                  std::to_string(placement.scale) +
                                      " is not accepted; it must be a finite number > 0 (texels "
                                      "per world unit)");
    }
    if (!(std::isfinite(placement.offsetTexels.x) && std::isfinite(placement.offsetTexels.y) &&
          std::isfinite(placement.offsetTexels.z))) {
        throw InputError::inField("placement.offsetTexels",
                                  "must be three finite numbers (texels)");
    }
    if (!(halfBandTexels >= 1.0f && halfBandTexels <= 1024.0f)) {
        throw InputError::inField("halfBandTexels", std::to_string(halfBandTexels) +
                                                        " texels is not accepted; it must be in "
                                                        "[1, 1024]");
    }
    const VdbVolume::Impl& source = *volume.impl_;
    Impl& impl = *impl_;
    impl.source = source.grid;
    impl.levelSet = source.levelSet;
    impl.iso = source.iso;
    impl.scale = placement.scale;
    impl.offsetTexels = placement.offsetTexels;
    impl.halfBandTexels = halfBandTexels;
    // A level set's band (background minus the iso shift, world units) covers the tile's band:
    // its values are distances wherever the tile needs them.
    const double sourceBandTexels =
        (double(source.grid->background()) - std::abs(source.iso)) * placement.scale;
    if (source.levelSet && sourceBandTexels >= halfBandTexels) return;

    // Rebuild: the polygons near the tile's box, placed in texel space.
    const double reach = 2.0 * double(halfBandTexels) + 2.0;
    const glm::dvec3 boxMin(-reach),
        boxMax(tile.width + reach, tile.height + reach, tile.depth + reach);
    std::vector<openvdb::Vec3s> points(source.points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        const openvdb::Vec3s& world = source.points[i];
        for (int axis = 0; axis < 3; ++axis) {
            points[i][axis] =
                float(placement.scale * double(world[axis]) + placement.offsetTexels[axis]);
        }
    }
    auto near = [&](std::initializer_list<openvdb::Index32> corners) {
        glm::dvec3 lo(HUGE_VAL), hi(-HUGE_VAL);
        for (openvdb::Index32 corner : corners) {
            for (int axis = 0; axis < 3; ++axis) {
                lo[axis] = std::min(lo[axis], double(points[corner][axis]));
                hi[axis] = std::max(hi[axis], double(points[corner][axis]));
            }
        }
        return lo.x <= boxMax.x && lo.y <= boxMax.y && lo.z <= boxMax.z && hi.x >= boxMin.x &&
               hi.y >= boxMin.y && hi.z >= boxMin.z;
    };
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    for (const openvdb::Vec3I& t : source.triangles)
        if (near({t[0], t[1], t[2]})) triangles.push_back(t);
    for (const openvdb::Vec4I& q : source.quads)
        if (near({q[0], q[1], q[2], q[3]})) quads.push_back(q);
    const auto texels = detail::texelTransform();
    if (triangles.empty() && quads.empty()) {
        impl.rebuilt = openvdb::FloatGrid::create(halfBandTexels);
    } else {
        impl.rebuilt = openvdb::tools::meshToUnsignedDistanceField<openvdb::FloatGrid>(
            *texels, points, triangles, quads, halfBandTexels + 1.0f);
    }
}

VdbTileSampler::VdbTileSampler(VdbTileSampler&&) noexcept = default;
VdbTileSampler::~VdbTileSampler() = default;

bool VdbTileSampler::rebuilt() const {
    return impl_->rebuilt != nullptr;
}

double VdbTileSampler::distanceTexels(const glm::dvec3& texelPosition) const {
    const Impl& impl = *impl_;
    const double band = impl.halfBandTexels;
    // Texel -> the file's world -> the source's index space, where trilinear interpolation runs
    // on the voxel lattice whatever its rotation or aspect; the values are world distances.
    const glm::dvec3 world = (texelPosition - impl.offsetTexels) / impl.scale;
    const openvdb::Vec3d index =
        impl.source->transform().worldToIndex(openvdb::Vec3d(world.x, world.y, world.z));
    Accessor source(impl.source->tree());
    const double value = openvdb::tools::BoxSampler::sample(source, index) - impl.iso;
    const bool inside = impl.levelSet ? value < 0.0 : value > 0.0;
    if (!impl.rebuilt) return std::clamp(value * impl.scale, -band, band);

    if (impl.levelSet) {
        // Inside the source band (all eight voxels of the trilinear stencil active) keep the
        // source's distance.
        const openvdb::Coord base = openvdb::Coord::floor(index);
        bool inBand = true;
        for (int corner = 0; corner < 8 && inBand; ++corner) {
            inBand = source.isValueOn(base.offsetBy(corner & 1, (corner >> 1) & 1, corner >> 2));
        }
        if (inBand) return std::clamp(value * impl.scale, -band, band);
    }
    Accessor rebuilt(impl.rebuilt->tree());
    const openvdb::Vec3d texelIndex(texelPosition.x - 0.5, texelPosition.y - 0.5,
                                    texelPosition.z - 0.5);
    const double unsignedTexels =
        std::min(double(openvdb::tools::BoxSampler::sample(rebuilt, texelIndex)), band);
    return inside ? -unsignedTexels : unsignedTexels;
}

void writeSphereVolume(const std::filesystem::path& file, const SphereVolumeOptions& options) {
    initializeOpenVdb();
    const double voxel = options.voxelSizeWorld;
    const double bandWorld = double(options.halfWidthVoxels) * voxel;
    auto transform = openvdb::math::Transform::createLinearTransform(voxel);
    const double radians = options.rotationDegrees * std::numbers::pi / 180.0;
    transform->postRotate(radians, openvdb::math::X_AXIS);
    transform->postRotate(radians, openvdb::math::Y_AXIS);
    auto grid = openvdb::FloatGrid::create(options.fog ? 0.0f : float(bandWorld));
    grid->setTransform(transform);
    grid->setName(options.gridName);
    grid->setGridClass(options.fog ? openvdb::GRID_FOG_VOLUME : openvdb::GRID_LEVEL_SET);
    const glm::dvec3 centre = options.centreWorld;
    const double reach = options.radiusWorld + bandWorld + 2.0 * voxel;
    const Bounds3 indexBox = [&] {
        Bounds3 box{glm::dvec3(HUGE_VAL), glm::dvec3(-HUGE_VAL)};
        for (int corner = 0; corner < 8; ++corner) {
            const openvdb::Vec3d world(centre.x + ((corner & 1) ? reach : -reach),
                                       centre.y + ((corner & 2) ? reach : -reach),
                                       centre.z + ((corner & 4) ? reach : -reach));
            const openvdb::Vec3d index = transform->worldToIndex(world);
            for (int axis = 0; axis < 3; ++axis) {
                box.min[axis] = std::min(box.min[axis], index[axis]);
                box.max[axis] = std::max(box.max[axis], index[axis]);
            }
        }
        return box;
    }();
    auto accessor = grid->getAccessor();
    for (int i = int(std::floor(indexBox.min.x)); i <= int(std::ceil(indexBox.max.x)); ++i) {
        for (int j = int(std::floor(indexBox.min.y)); j <= int(std::ceil(indexBox.max.y)); ++j) {
            for (int k = int(std::floor(indexBox.min.z)); k <= int(std::ceil(indexBox.max.z));
                 ++k) {
                const openvdb::Vec3d world = transform->indexToWorld(openvdb::Vec3d(i, j, k));
                const double distance =
                    glm::length(glm::dvec3(world.x(), world.y(), world.z()) - centre) -
                    options.radiusWorld;
                if (options.fog) {
                    const double density = std::clamp(0.5 - 0.5 * distance / bandWorld, 0.0, 1.0);
                    if (density > 0.0) accessor.setValue(openvdb::Coord(i, j, k), float(density));
                } else if (std::abs(distance) < bandWorld) {
                    accessor.setValue(openvdb::Coord(i, j, k), float(distance));
                }
            }
        }
    }
    if (!options.fog) openvdb::tools::signedFloodFill(grid->tree());
    grid->pruneGrid();
    openvdb::io::File vdbFile(file.string());
    vdbFile.write({grid});
    vdbFile.close();
}

}  // namespace distile
