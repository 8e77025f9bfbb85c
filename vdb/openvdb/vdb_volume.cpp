// The OpenVDB half of vdb/vdb_volume.h, in the module (vdb/detail/openvdb_module.h).
#include "vdb/openvdb/openvdb_parts.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <sstream>

#include "common/error.h"
#include "common/input_file.h"
#include "vdb/openvdb/openvdb_setup.h"
#include "vdb/openvdb/vdb_header_check.h"

namespace distile::detail {

namespace {

using Accessor = openvdb::tree::ValueAccessor<const openvdb::FloatTree, /*IsSafe=*/false>;

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
    checkVdbHeader(file, requireRegularFile(file, "an OpenVDB .vdb file"));
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
    } catch (const openvdb::ArithmeticError& error) {
        // A transform whose matrix holds NaN or infinity cannot be inverted when it is read.
        throw FormatError(file.string() +
                          ": a grid's transform is not finite and invertible (" + error.what() +
                          ")");
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

/// The grid's value at an index-space point: triquadratic (OpenVDB's QuadraticSampler, third-order
/// accurate for a smooth field) where its 27 voxels are all active, else trilinear.
double sampleSmooth(const Accessor& accessor, const openvdb::Vec3d& index) {
    const openvdb::Coord base = openvdb::Coord::floor(index);
    bool active = true;
    for (int dx = -1; dx <= 1 && active; ++dx)
        for (int dy = -1; dy <= 1 && active; ++dy)
            for (int dz = -1; dz <= 1 && active; ++dz)
                active = accessor.isValueOn(base.offsetBy(dx, dy, dz));
    if (active) return openvdb::tools::QuadraticSampler::sample(accessor, index);
    return openvdb::tools::BoxSampler::sample(accessor, index);
}

/// `world` moved onto the grid's iso crossing by Newton steps along the gradient of the smooth
/// reconstruction; as it is when that does not converge within a voxel.
glm::dvec3 projectOntoIso(const openvdb::FloatGrid& grid, const Accessor& accessor, double iso,
                          const glm::dvec3& world, double voxelWorld) {
    const openvdb::math::Transform& transform = grid.transform();
    const auto value = [&](const glm::dvec3& p) {
        return sampleSmooth(accessor, transform.worldToIndex(openvdb::Vec3d(p.x, p.y, p.z))) - iso;
    };
    const double step = 0.25 * voxelWorld;
    glm::dvec3 p = world;
    for (int iteration = 0; iteration < 4; ++iteration) {
        const double f = value(p);
        if (std::abs(f) < 1e-9 * voxelWorld) break;
        const glm::dvec3 gradient(
            (value(p + glm::dvec3(step, 0, 0)) - value(p - glm::dvec3(step, 0, 0))) / (2 * step),
            (value(p + glm::dvec3(0, step, 0)) - value(p - glm::dvec3(0, step, 0))) / (2 * step),
            (value(p + glm::dvec3(0, 0, step)) - value(p - glm::dvec3(0, 0, step))) / (2 * step));
        const double gradientSquared = glm::dot(gradient, gradient);
        if (!(gradientSquared > 0.0)) return world;
        p -= (f / gradientSquared) * gradient;
    }
    const bool converged =
        std::abs(value(p)) < 1e-3 * voxelWorld && glm::length(p - world) < voxelWorld;
    return converged ? p : world;
}

/// A volume's grid, and the refinement of its iso surface.
class OpenVdbVolumeGrid final : public VolumeGrid {
  public:
    explicit OpenVdbVolumeGrid(openvdb::FloatGrid::Ptr grid) : grid_(std::move(grid)) {}

    glm::dvec3 voxelSizeWorld() const override {
        const openvdb::Vec3d size = grid_->transform().voxelSize();
        return {size.x(), size.y(), size.z()};
    }
    TriangleSoup refinedSurfaceWorld(const TriangleSoup& coarse, double iso, double maxEdgeWorld,
                                     const Bounds3& regionWorld) const override;
    std::unique_ptr<VolumeSampler> sampler(bool levelSet, double iso,
                                           const TexelPlacement& placement) const override;

  private:
    openvdb::FloatGrid::Ptr grid_;
};

/// A volume sampled in texel space.
class OpenVdbVolumeSampler final : public VolumeSampler {
  public:
    OpenVdbVolumeSampler(openvdb::FloatGrid::ConstPtr source, bool levelSet, double iso,
                         const TexelPlacement& placement)
        : source_(std::move(source)), levelSet_(levelSet), iso_(iso), placement_(placement) {
        // How far the stored distances reach: the largest active value, and a voxel beyond it
        // (the band's last voxels hold values up to a voxel short of its edge). A file may set
        // its background (what reads back beyond the band) larger than that; the band is the
        // smaller of the two, or values past the real band would read as distances.
        if (levelSet_) {
            float largest = 0.0f;
            for (auto value = source_->cbeginValueOn(); value; ++value)
                largest = std::max(largest, std::abs(*value));
            const openvdb::Vec3d voxel = source_->voxelSize();
            reachWorld_ = std::min(double(source_->background()),
                                   double(largest) + std::max({voxel[0], voxel[1], voxel[2]}));
        }
    }

    VdbSourceSampler::Sample sample(const glm::dvec3& texelPosition) const override {
        const glm::dvec3 world = (texelPosition - placement_.offsetTexels) / placement_.scale;
        const openvdb::Vec3d index =
            source_->transform().worldToIndex(openvdb::Vec3d(world.x, world.y, world.z));
        Accessor source(source_->tree());
        const double value = openvdb::tools::BoxSampler::sample(source, index) - iso_;
        const openvdb::Coord base = openvdb::Coord::floor(index);
        bool inBand = true;
        for (int corner = 0; corner < 8 && inBand; ++corner) {
            inBand = source.isValueOn(base.offsetBy(corner & 1, (corner >> 1) & 1, corner >> 2));
        }
        VdbSourceSampler::Sample result;
        result.valueTexels = (levelSet_ ? value : -value) * placement_.scale;
        result.inside = result.valueTexels < 0.0;
        result.inBand = inBand;
        return result;
    }

    double bandTexels() const override {
        if (!levelSet_) return 0.0;
        return std::max(0.0, (reachWorld_ - std::abs(iso_)) * placement_.scale);
    }

  private:
    openvdb::FloatGrid::ConstPtr source_;
    bool levelSet_ = true;
    double reachWorld_ = 0.0;  ///< the band the stored distances cover, world units
    double iso_ = 0.0;
    TexelPlacement placement_;
};

std::unique_ptr<VolumeSampler> OpenVdbVolumeGrid::sampler(bool levelSet, double iso,
                                                          const TexelPlacement& placement) const {
    return std::make_unique<OpenVdbVolumeSampler>(grid_, levelSet, iso, placement);
}

}  // namespace

std::vector<VdbGridInfo> listVdbGrids(const std::filesystem::path& file) {
    std::vector<VdbGridInfo> list;
    const openvdb::GridPtrVecPtr grids = readGridMetadata(file);  // kept alive over the loop
    for (const auto& grid : *grids) {
        list.push_back({grid->getName(), grid->valueType(),
                        openvdb::GridBase::gridClassToString(grid->getGridClass())});
    }
    return list;
}

ReadVolume readVolume(const std::filesystem::path& file, const std::string& gridName,
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
        std::vector<openvdb::GridBase::ConstPtr> levelSets, floatGrids;
        for (const auto& grid : *metadata) {
            if (grid->valueType() != openvdb::typeNameAsString<float>()) continue;
            floatGrids.push_back(grid);
            if (grid->getGridClass() == openvdb::GRID_LEVEL_SET) levelSets.push_back(grid);
        }
        // With an iso value, a file without level sets may hold one fog volume (or another float
        // grid) to take.
        if (levelSets.empty() && iso && floatGrids.size() == 1) levelSets = floatGrids;
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

    // VolumeToMesh throws on a NaN or an infinity anywhere it samples, from a worker thread (and
    // a value of a level set that is not finite is a corrupt file): refused first, with where.
    if (!std::isfinite(grid->background())) {
        std::ostringstream message;
        message << name << ": grid '" << grid->getName() << "' has the background value "
                << grid->background() << "; values must be finite";
        throw FormatError(message.str());
    }
    for (auto value = grid->cbeginValueAll(); value; ++value) {
        if (std::isfinite(*value)) continue;
        std::ostringstream message;
        message << name << ": grid '" << grid->getName() << "' has the value " << *value
                << " at voxel " << value.getCoord() << (value.isVoxelValue() ? "" : " (a tile)")
                << "; values must be finite";
        throw FormatError(message.str());
    }

    ReadVolume volume;
    volume.levelSet = levelSet;
    volume.iso = iso.value_or(0.0);
    volume.activeBounds =
        worldBoundsOfIndexBox(transform, active.min().asVec3d(), active.max().asVec3d());
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(*grid, points, triangles, quads, volume.iso, /*adaptivity=*/0.0);
    if (points.empty() || (triangles.empty() && quads.empty())) {
        std::ostringstream message;
        message << name << ": grid '" << grid->getName() << "' has no surface: its values never "
                << "cross " << volume.iso;
        throw FormatError(message.str());
    }
    TriangleSoup& soup = volume.surface;
    soup.positions.reserve(points.size());
    for (const openvdb::Vec3s& point : points)
        soup.positions.emplace_back(point.x(), point.y(), point.z());
    soup.triangles.reserve(triangles.size() + 2 * quads.size());
    for (const openvdb::Vec3I& t : triangles) soup.triangles.emplace_back(t[0], t[1], t[2]);
    for (const openvdb::Vec4I& q : quads) {
        soup.triangles.emplace_back(q[0], q[1], q[2]);
        soup.triangles.emplace_back(q[0], q[2], q[3]);
    }
    const Bounds3 surface = boundsOf(soup);
    if (!isFiniteBox(surface) || !isFiniteBox(volume.activeBounds)) {
        throw FormatError(name + ": grid '" + grid->getName() +
                          "' has world positions that are not finite (check its transform)");
    }
    volume.surfaceBounds = surface;
    volume.name = grid->getName();
    volume.grid = std::make_unique<OpenVdbVolumeGrid>(grid);
    return volume;
}

TriangleSoup OpenVdbVolumeGrid::refinedSurfaceWorld(const TriangleSoup& coarse, double iso,
                                                     double maxEdgeWorld,
                                                     const Bounds3& regionWorld) const {
    const openvdb::Vec3d voxel = grid_->transform().voxelSize();
    const double voxelWorld = std::max({voxel.x(), voxel.y(), voxel.z()});
    double longestEdge = 0.0;
    for (const glm::uvec3& t : coarse.triangles) {
        for (int corner = 0; corner < 3; ++corner) {
            longestEdge = std::max(longestEdge, glm::length(coarse.positions[t[corner]] -
                                                            coarse.positions[t[(corner + 1) % 3]]));
        }
    }
    // One subdivision count for every triangle, so neighbours share their edges' new vertices.
    const int parts =
        std::clamp(int(std::ceil(longestEdge / std::max(maxEdgeWorld, 1e-300))), 1, 16);
    std::vector<glm::uvec3> kept;
    for (const glm::uvec3& t : coarse.triangles) {
        bool near = true;
        for (int axis = 0; axis < 3 && near; ++axis) {
            const double lo = std::min({coarse.positions[t.x][axis], coarse.positions[t.y][axis],
                                        coarse.positions[t.z][axis]});
            const double hi = std::max({coarse.positions[t.x][axis], coarse.positions[t.y][axis],
                                        coarse.positions[t.z][axis]});
            near = lo <= regionWorld.max[axis] && hi >= regionWorld.min[axis];
        }
        if (near) kept.push_back(t);
    }
    // Triangle n's (parts + 1)(parts + 2) / 2 vertices and parts^2 triangles follow triangle
    // n - 1's; vertex (i, j) is a + (b - a) i / parts + (c - a) j / parts, i + j <= parts.
    const std::size_t vertices = std::size_t(parts + 1) * std::size_t(parts + 2) / 2;
    const std::size_t triangles = std::size_t(parts) * std::size_t(parts);
    TriangleSoup fine;
    fine.positions.resize(kept.size() * vertices);
    fine.triangles.resize(kept.size() * triangles);
    const openvdb::FloatGrid& grid = *grid_;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, kept.size()),
        [&](const tbb::blocked_range<std::size_t>& range) {
            Accessor accessor(grid.tree());
            for (std::size_t n = range.begin(); n != range.end(); ++n) {
                const glm::uvec3& t = kept[n];
                const glm::dvec3 a = coarse.positions[t.x], b = coarse.positions[t.y],
                                 c = coarse.positions[t.z];
                const std::uint32_t first = std::uint32_t(n * vertices);
                auto vertex = [&](int i, int j) {
                    return first + std::uint32_t(j * (parts + 1) - j * (j - 1) / 2 + i);
                };
                for (int j = 0; j <= parts; ++j) {
                    for (int i = 0; i + j <= parts; ++i) {
                        const glm::dvec3 p =
                            a + (b - a) * (double(i) / parts) + (c - a) * (double(j) / parts);
                        fine.positions[vertex(i, j)] =
                            projectOntoIso(grid, accessor, iso, p, voxelWorld);
                    }
                }
                std::size_t next = n * triangles;
                for (int j = 0; j < parts; ++j) {
                    for (int i = 0; i + j < parts; ++i) {
                        fine.triangles[next++] = {vertex(i, j), vertex(i + 1, j), vertex(i, j + 1)};
                        if (i + j + 1 < parts) {
                            fine.triangles[next++] = {vertex(i + 1, j), vertex(i + 1, j + 1),
                                                      vertex(i, j + 1)};
                        }
                    }
                }
            }
        });
    return fine;
}

namespace {

openvdb::FloatGrid::Ptr sphereGrid(const SphereVolumeOptions& options) {
    const double voxel = options.voxelSizeWorld;
    const double bandWorld = double(options.halfWidthVoxels) * voxel;
    auto transform = openvdb::math::Transform::createLinearTransform(voxel);
    const double radians = options.rotationDegrees * std::numbers::pi / 180.0;
    transform->postRotate(radians, openvdb::math::X_AXIS);
    transform->postRotate(radians, openvdb::math::Y_AXIS);
    const double background = options.backgroundWorld > 0.0 ? options.backgroundWorld : bandWorld;
    auto grid = openvdb::FloatGrid::create(options.fog ? 0.0f : float(background));
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
    return grid;
}

}  // namespace

void writeSphereVolumes(const std::filesystem::path& file,
                        const std::vector<SphereVolumeOptions>& spheres) {
    initializeOpenVdb();
    openvdb::GridPtrVec grids;
    for (const SphereVolumeOptions& sphere : spheres) grids.push_back(sphereGrid(sphere));
    openvdb::io::File vdbFile(file.string());
    vdbFile.write(grids);
    vdbFile.close();
}

}  // namespace distile::detail
