#include "bake/solid_mesh.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <span>
#include <sstream>
#include <string>

#include "bake/mesh_surface.h"
#include "bake/resample.h"
#include "bake/soup_distance.h"
#include "bake/soup_distance_grid.h"
#include "common/error.h"
#include "mesh/detail_mesh.h"
#include "truth/mesh_truth.h"

namespace distile {

SolidDetailMesh loadSolidDetailMesh(const std::filesystem::path& path,
                                    const MeshSignOptions& sign) {
    const std::string file = path.string();
    SolidDetailMesh solid{loadDetailMesh(path), {}};
    const MeshTopology topology = inspectMesh(solid.mesh);
    const bool signedByWindingNumber = !sign.unsignedDistance;
    if (signedByWindingNumber && (!topology.closed || !topology.manifold)) {
        std::ostringstream message;
        message << file << ": the mesh is ";
        if (!topology.closed) message << "open (" << topology.boundaryEdges << " boundary edges)";
        if (!topology.closed && !topology.manifold) message << " and ";
        if (!topology.manifold) message << "non-manifold or not orientable";
        message << "; inside is where its winding number exceeds 1/2";
        solid.warnings.push_back(message.str());
    }
    if (topology.degenerateFaces > 0) {
        solid.warnings.push_back(file + ": " + std::to_string(topology.degenerateFaces) +
                                 " degenerate (zero-area) faces");
    }
    if (signedByWindingNumber && topology.selfIntersecting) {
        solid.warnings.push_back(file +
                                 ": the mesh intersects itself; inside is where its winding "
                                 "number exceeds 1/2");
    }
    return solid;
}

SolidMeshBake bakeSolidMesh(const TriangleSoup& mesh, const MeshPlacement& placement,
                            const BakeOptions& options, const std::string& file,
                            const ProgressCallback& progress, const MeshSignOptions& sign) {
    validateBakeOptions(options);
    const TriangleSoup placed = placeMesh(mesh, placement, options.size);
    if (sign.unsignedDistance &&
        !(std::isfinite(sign.thicknessTexels) && sign.thicknessTexels >= 0.0 &&
          sign.thicknessTexels <= options.size.depth)) {
        throw InputError::inField("sign.thicknessTexels",
                                  numberText(sign.thicknessTexels) +
                                      " texels is not accepted; it must be in [0, " +
                                      std::to_string(options.size.depth) + "] (the tile depth)");
    }
    const float halfBand = validatedHalfBandTexels(options);
    const SoupDistance soup(placed, options.size);
    const double halfThickness = sign.unsignedDistance ? 0.5 * sign.thicknessTexels : 0.0;
    // Nothing beyond the band is needed: the level set clamps there.
    const double cutoff = double(halfBand) + halfThickness;
    // The placement as used (also when fitted): `check` and reference renders place the source
    // mesh by it.
    const MeshPlacement used = explicitPlacement(mesh, placement, options.size);
    std::ostringstream params;
    params.precision(17);
    params << "{\"placement\":\"" << (placement.fit ? "fit" : "explicit")
           << "\",\"scale\":" << used.scale << ",\"offset_texels\":[" << used.offsetTexels.x << ","
           << used.offsetTexels.y << "," << used.offsetTexels.z
           << "],\"triangles\":" << placed.triangles.size() << ",\"sign\":\""
           << (sign.unsignedDistance ? "unsigned" : "winding number") << "\"";
    if (sign.unsignedDistance) params << ",\"thickness_texels\":" << sign.thicknessTexels;
    params << "}";
    // Every voxel of the level set that is asked for: the tile and, unless left out, the band
    // margin above and below it; at first the distance to all triangles.
    const int margin = options.fillLevelSetMargins ? int(std::ceil(halfBand)) : 0;
    SoupDistanceGrid grid = soupDistanceGrid(soup, -margin, options.size.depth + margin, cutoff,
                                             !sign.unsignedDistance, progress);
    // Signed, the distances measure the boundary of the inside (bake/mesh_surface.h), as `check`
    // and reference renders do: for a closed mesh whose parts neither overlap nor touch, all its
    // triangles, so nothing more to do; the grid tells so when every voxel's nearest point
    // provably bounds the inside. Otherwise (triangles trimmed, caps over holes) the distances
    // are measured again to that surface, keeping their signs.
    std::optional<MeshSurface> surface;
    if (!sign.unsignedDistance && !grid.nearestPointsBound) {
        surface.emplace(placed, soup, options.size);
        if (surface->trimmedTriangles() == 0 && surface->caps().triangles.empty()) surface.reset();
    }
    if (surface) {
        // Measured again a vertical line at a time, each from its row neighbour's nearest
        // triangles of the surface, which replace the grid's as the hints below.
        const int slices = grid.zEnd - grid.zBegin;
        const std::size_t slab = std::size_t(options.size.width) * std::size_t(options.size.height);
        std::vector<double> sliceZ(static_cast<std::size_t>(slices));
        for (int slice = 0; slice < slices; ++slice)
            sliceZ[std::size_t(slice)] = grid.zBegin + slice + 0.5;
        tbb::parallel_for(0, options.size.height, [&](int j) {
            std::vector<SoupDistance::NearestHint> hints(static_cast<std::size_t>(slices));
            std::vector<double> line(static_cast<std::size_t>(slices));
            for (int i = 0; i < options.size.width; ++i) {
                surface->unsignedDistancesOnLine({i + 0.5, j + 0.5}, sliceZ, cutoff, hints, line);
                for (int slice = 0; slice < slices; ++slice) {
                    const std::size_t voxel = std::size_t(slice) * slab +
                                              std::size_t(j) * std::size_t(options.size.width) +
                                              std::size_t(i);
                    double& distance = grid.distancesTexels[voxel];
                    distance =
                        distance < 0.0 ? -line[std::size_t(slice)] : line[std::size_t(slice)];
                    grid.nearest[voxel] = hints[std::size_t(slice)];
                }
            }
        });
    }
    // The exact distances the conservative correction measures against, a vertical line at a
    // time; each point starts from the nearest triangle of its nearest voxel (the grid's, or the
    // surface's where it was measured again).
    const ExactDistancesOnLine exactDistances = [&](const glm::dvec2& xy, std::span<const double> z,
                                                    std::span<double> distances) {
        std::vector<SoupDistance::NearestHint> hints(z.size());
        for (std::size_t n = 0; n < z.size(); ++n) hints[n] = grid.hintNear({xy.x, xy.y, z[n]});
        if (surface) {
            surface->signedDistancesOnLine(xy, z, cutoff, hints, distances);
            return;
        }
        soup.unsignedDistancesOnLine(xy, z, cutoff, hints, distances);
        for (std::size_t n = 0; n < z.size(); ++n) {
            distances[n] =
                sign.unsignedDistance
                    ? distances[n] - halfThickness
                    : signedDistanceBesideGrid(soup, grid, {xy.x, xy.y, z[n]}, distances[n]);
        }
    };
    const auto rowDistance = [&](int j, int k, std::span<double> row) {
        const double* distances = grid.row(j, k);
        for (std::size_t i = 0; i < row.size(); ++i) row[i] = distances[i] - halfThickness;
    };
    LevelSet levelSet = LevelSet::fromDistanceRows(rowDistance, options.size, halfBand, "mesh",
                                                   params.str(), {}, options.fillLevelSetMargins);

    std::vector<float> texels(options.size.texelCount());
    levelSet.copyTileVoxels(texels);
    const std::size_t insideTexels =
        std::size_t(std::count_if(texels.begin(), texels.end(), [](float d) { return d < 0.0f; }));
    if (insideTexels == 0 && !sign.unsignedDistance) {
        throw InputError::inField(
            "sign.unsignedDistance",
            "needed for " + file +
                ": the mesh has no inside in the tile (its winding number is nowhere above "
                "1/2), as sheet-like detail has none; bake it as an unsigned distance");
    }
    Tile tile = tileFromLevelSet(levelSet, options.conservative, exactDistances);
    return {{std::move(levelSet), std::move(tile)}, insideTexels};
}

}  // namespace distile
