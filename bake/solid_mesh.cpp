#include "bake/solid_mesh.h"

#include <algorithm>
#include <cmath>
#include <span>
#include <sstream>
#include <string>

#include "bake/mesh_surface.h"
#include "bake/resample.h"
#include "bake/soup_distance.h"
#include "common/error.h"
#include "mesh/detail_mesh.h"
#include "truth/mesh_truth.h"

namespace distile {

SolidDetailMesh loadSolidDetailMesh(const std::filesystem::path& path) {
    const std::string file = path.string();
    SolidDetailMesh solid{loadDetailMesh(path), {}};
    const MeshTopology topology = inspectMesh(solid.mesh);
    if (!topology.closed || !topology.manifold) {
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
    if (topology.selfIntersecting) {
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
                                  std::to_string(sign.thicknessTexels) +
                                      " texels is not accepted; it must be in [0, " +
                                      std::to_string(options.size.depth) + "] (the tile depth)");
    }
    const float halfBand =
        options.halfBandTexels > 0.0f ? options.halfBandTexels : float(options.size.depth);
    const SoupDistance soup(placed, options.size);
    // What the distances measure (bake/mesh_surface.h): signed, the boundary of the inside (the
    // triangles that bound it, caps over holes), as `check` and reference renders measure it.
    const MeshSurface surface = sign.unsignedDistance ? MeshSurface(soup)
                                                      : MeshSurface(placed, soup, options.size);
    const double halfThickness = sign.unsignedDistance ? 0.5 * sign.thicknessTexels : 0.0;
    // Nothing beyond the band is needed: the level set clamps there.
    const double cutoff = double(halfBand) + halfThickness;
    const ExactDistance exactDistance = [&](const glm::dvec3& p) {
        SoupDistance::NearestHint none;
        if (sign.unsignedDistance) return surface.unsignedDistance(p, cutoff, none) - halfThickness;
        return surface.signedDistance(p, cutoff);
    };
    // The placement as used (also when fitted): `check` and reference renders place the source
    // mesh by it.
    const MeshPlacement used = explicitPlacement(mesh, placement, options.size);
    std::ostringstream params;
    params.precision(17);
    params << "{\"placement\":\"" << (placement.fit ? "fit" : "explicit")
           << "\",\"scale\":" << used.scale << ",\"offset_texels\":[" << used.offsetTexels.x
           << "," << used.offsetTexels.y << "," << used.offsetTexels.z
           << "],\"triangles\":" << placed.triangles.size() << ",\"sign\":\""
           << (sign.unsignedDistance ? "unsigned" : "winding number") << "\"";
    if (sign.unsignedDistance) params << ",\"thickness_texels\":" << sign.thicknessTexels;
    params << "}";
    // Along a row, the previous texel's nearest triangle starts the search: the same exact
    // result, much less of the tree visited.
    // The sign likewise: where the winding number changes only across the surface, a texel 1
    // texel from its row neighbour, nearer to it than the neighbour is to the surface, shares its
    // sign (the segment between them crosses no surface).
    const bool signPropagates = soup.windingChangesOnlyAcrossTheSurface();
    const auto rowDistance = [&](int j, int k, std::span<double> row) {
        double previous = cutoff;
        bool previousInside = false;
        SoupDistance::NearestHint hint;
        for (std::size_t i = 0; i < row.size(); ++i) {
            const glm::dvec3 p(double(i) + 0.5, j + 0.5, k + 0.5);
            const double distance = surface.unsignedDistance(p, cutoff, hint);
            if (sign.unsignedDistance) {
                row[i] = distance - halfThickness;
            } else {
                const bool inside = signPropagates && i > 0 && previous > 1.0 + 1e-9
                                        ? previousInside
                                        : soup.windingNumber(p) > 0.5;
                row[i] = inside ? -distance : distance;
                previousInside = inside;
            }
            previous = distance;
        }
    };
    LevelSet levelSet = LevelSet::fromDistanceRows(rowDistance, options.size, halfBand, "mesh",
                                                   params.str(), progress);

    std::vector<float> texels(options.size.texelCount());
    levelSet.copyTileVoxels(texels);
    const std::size_t insideTexels =
        std::size_t(std::count_if(texels.begin(), texels.end(), [](float d) { return d < 0.0f; }));
    if (insideTexels == 0 && !sign.unsignedDistance) {
        throw InputError::inField(
            "sign.unsignedDistance",
            file +
                ": the mesh has no inside in the tile (its winding number is nowhere above "
                "1/2); sheet-like detail must be baked as an unsigned distance");
    }
    Tile tile = tileFromLevelSet(levelSet, options.conservative, exactDistance);
    return {{std::move(levelSet), std::move(tile)}, insideTexels};
}

}  // namespace distile
