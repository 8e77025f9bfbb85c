#include "bake/bake.h"

#include <algorithm>
#include <cmath>
#include <span>
#include <sstream>

#include "bake/resample.h"
#include "common/error.h"
#include "vdb/height_field.h"
#include "vdb/mesh_level_set.h"

namespace distile {

namespace {

bool isFinite(const glm::dvec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

void validateBakeOptions(const BakeOptions& options) {
    validateTileSize(options.size, "size");
    const float widest = maxHalfBandTexels(options.size);
    if (!(options.halfBandTexels == 0.0f ||
          (options.halfBandTexels >= 1.0f && options.halfBandTexels <= widest))) {
        std::ostringstream message;
        message << options.halfBandTexels << " texels is not accepted; it must be in [1, " << widest
                << "] (twice the tile depth, at most 1024), or 0 for the tile depth (at most 1024)";
        throw InputError::inField("halfBandTexels", message.str());
    }
}

float validatedHalfBandTexels(const BakeOptions& options) {
    validateBakeOptions(options);
    return options.halfBandTexels > 0.0f
               ? options.halfBandTexels
               : std::min(float(options.size.depth), maxHalfBandTexels(options.size));
}

BakeResult bakeChainmail(const ChainmailOptions& chainmailOptions, const BakeOptions& options,
                         const ProgressCallback& progress) {
    ProceduralOptions procedural;
    procedural.kind = ProceduralKind::Chainmail;
    procedural.chainmail = chainmailOptions;
    return bakeProcedural(procedural, options, progress);
}

BakeResult bakeProcedural(const ProceduralOptions& proceduralOptions, const BakeOptions& options,
                          const ProgressCallback& progress) {
    const float halfBand = validatedHalfBandTexels(options);
    const ProceduralDistance procedural = proceduralDistance(proceduralOptions, options.size);
    LevelSet levelSet =
        LevelSet::fromDistance(procedural.signedDistanceTexels, options.size, halfBand,
                               procedural.source, procedural.paramsJson, progress);
    // The estimated correction, lowered further where the analytic distance shows a point
    // outside the detail still overestimates (bake/conservative.h: the measured correction
    // alone lowers too much across the wires' centreline kinks).
    ConservativeOptions conservative = options.conservative;
    conservative.measuredOnTopOfEstimate = true;
    Tile tile = tileFromLevelSet(
        levelSet, conservative,
        [&](const glm::dvec2& xy, std::span<const double> z, std::span<double> distances) {
            for (std::size_t k = 0; k < z.size(); ++k)
                distances[k] = procedural.signedDistanceTexels({xy.x, xy.y, z[k]});
        });
    return {std::move(levelSet), std::move(tile)};
}

FootprintFit fitToFootprint(const Bounds3& box, const Size3& tile, const std::string& what) {
    const glm::dvec3 extent = box.max - box.min;
    const double scale = std::min(extent.x > 0.0 ? tile.width / extent.x : HUGE_VAL,
                                  extent.y > 0.0 ? tile.height / extent.y : HUGE_VAL);
    const glm::dvec3 centre = 0.5 * (box.min + box.max);
    const glm::dvec3 offset(0.5 * tile.width - scale * centre.x,
                            0.5 * tile.height - scale * centre.y, -scale * box.min.z);
    if (scale * extent.z > tile.depth) {
        std::ostringstream message;
        message << what << ": fitted to the " << tile.width << "x" << tile.height
                << " footprint it is " << scale * extent.z << " texels tall, more than the "
                << "tile depth " << tile.depth
                << "; use a deeper tile size or an explicit scale and offset";
        throw InputError::inField("size", message.str());
    }
    return {scale, offset};
}

void requireMeshInTile(const Bounds3& placedTexels, const Size3& tile) {
    const glm::dvec3 extent = placedTexels.max - placedTexels.min;
    const glm::dvec3 tileTexels(tile.width, tile.height, tile.depth);
    const double largestExtent = std::max({extent.x, extent.y, extent.z});
    std::ostringstream problem;
    const char* field = "placement.scale";  // its size is wrong; else where it lies
    if (!(largestExtent >= 1.0)) {
        problem << "is " << largestExtent << " texels across, less than one texel";
    } else if (!(extent.x <= kMaxPlacedFootprints * tile.width &&
                 extent.y <= kMaxPlacedFootprints * tile.height &&
                 extent.z <= kMaxPlacedFootprints * std::max(tile.width, tile.height))) {
        problem << "spans " << extent.x << " x " << extent.y << " x " << extent.z
                << " texels; at most " << kMaxPlacedFootprints
                << " tile footprints in x and y (and as much in z) are accepted";
    } else {
        for (int axis = 0; axis < 3; ++axis) {
            if (placedTexels.max[axis] < 0.0 || placedTexels.min[axis] > tileTexels[axis]) {
                problem << "lies at "
                        << "xyz"[axis] << " in [" << placedTexels.min[axis] << ", "
                        << placedTexels.max[axis] << "], outside the tile's [0, "
                        << tileTexels[axis] << "]";
                field = "placement.offsetTexels";
                break;
            }
        }
    }
    if (!problem.str().empty()) {
        throw InputError::inField(field, "detail mesh: placed in the " + toString(tile) +
                                             " tile it " + problem.str() +
                                             " (check the scale and offset)");
    }
}

MeshPlacement explicitPlacement(const TriangleSoup& meshFileUnits, const MeshPlacement& placement,
                                const Size3& tile) {
    validateTileSize(tile, "size");
    validateTriangleSoup(meshFileUnits, "detail mesh");
    const Bounds3 box = boundsOf(meshFileUnits);
    const glm::dvec3 extent = box.max - box.min;
    double scale = placement.scale;
    glm::dvec3 offset = placement.offsetTexels;
    if (placement.fit) {
        if (!(extent.x > 0.0 || extent.y > 0.0)) {
            throw InputError(
                "detail mesh: has no extent in x or y, so it cannot be fitted to "
                "the tile footprint; place it with an explicit scale and offset");
        }
        const FootprintFit fitted = fitToFootprint(box, tile, "detail mesh");
        scale = fitted.scale;
        offset = fitted.offsetTexels;
    } else {
        if (!(std::isfinite(scale) && scale > 0.0)) {
            throw InputError::inField(
                "placement.scale",
                numberText(scale) +
                    " is not accepted; it must be a finite number > 0 (texels per unit)");
        }
        if (!isFinite(offset)) {
            throw InputError::inField("placement.offsetTexels",
                                      "must be three finite numbers (texels)");
        }
    }
    MeshPlacement result;
    result.fit = false;
    result.scale = scale;
    result.offsetTexels = offset;
    return result;
}

TriangleSoup placeMesh(const TriangleSoup& meshFileUnits, const MeshPlacement& placement,
                       const Size3& tile) {
    const MeshPlacement used = explicitPlacement(meshFileUnits, placement, tile);
    const double scale = used.scale;
    const glm::dvec3 offset = used.offsetTexels;
    TriangleSoup placed;
    placed.triangles = meshFileUnits.triangles;
    placed.positions.reserve(meshFileUnits.positions.size());
    for (const glm::dvec3& p : meshFileUnits.positions) {
        const glm::dvec3 texel = scale * p + offset;
        if (!(std::abs(texel.x) <= kMaxPlacedTexelCoordinate &&
              std::abs(texel.y) <= kMaxPlacedTexelCoordinate &&
              std::abs(texel.z) <= kMaxPlacedTexelCoordinate)) {
            std::ostringstream message;
            message << "detail mesh: placed at (" << texel.x << ", " << texel.y << ", " << texel.z
                    << ") texels; placed coordinates must be within +-" << kMaxPlacedTexelCoordinate
                    << " (check the scale and offset)";
            const bool offsetBeyond =
                std::max({std::abs(offset.x), std::abs(offset.y), std::abs(offset.z)}) >
                0.5 * kMaxPlacedTexelCoordinate;
            throw InputError::inField(offsetBeyond ? "placement.offsetTexels" : "placement.scale",
                                      message.str());
        }
        placed.positions.push_back(texel);
    }
    requireMeshInTile(boundsOf(placed), tile);
    return placed;
}

BakeResult bakeMesh(const TriangleSoup& meshFileUnits, const MeshPlacement& placement,
                    const BakeOptions& options, const ProgressCallback& progress,
                    const InsideTest& insideTest, const ExactDistancesOnLine& exactDistances) {
    const float halfBand = validatedHalfBandTexels(options);
    const TriangleSoup placed = placeMesh(meshFileUnits, placement, options.size);
    const MeshPlacement used = explicitPlacement(meshFileUnits, placement, options.size);
    std::ostringstream params;
    params.precision(17);
    params << "{\"placement\":\"" << (placement.fit ? "fit" : "explicit")
           << "\",\"scale\":" << used.scale << ",\"offset_texels\":[" << used.offsetTexels.x << ","
           << used.offsetTexels.y << "," << used.offsetTexels.z
           << "],\"triangles\":" << placed.triangles.size() << "}";
    LevelSet levelSet = levelSetFromMesh(placed, options.size, halfBand, "mesh", params.str(),
                                         progress, insideTest);
    Tile tile = tileFromLevelSet(levelSet, options.conservative, exactDistances);
    return {std::move(levelSet), std::move(tile)};
}

BakeResult bakeHeightMap(const HeightImage& image, const HeightMapOptions& heightMap,
                         const BakeOptions& options, const ProgressCallback& progress) {
    const float halfBand = validatedHalfBandTexels(options);
    const double heightTexels =
        heightMap.heightTexels != 0.0 ? heightMap.heightTexels : double(options.size.depth - 1);
    const HeightField field = heightFieldFromImage(image, options.size, heightTexels);
    std::ostringstream params;
    params.precision(17);
    params << "{\"image\":\"" << image.width << "x" << image.height
           << "\",\"height_texels\":" << heightTexels << "}";
    LevelSet levelSet =
        levelSetFromHeightField(field, options.size, halfBand, "heightmap", params.str(), progress);
    // The conservative correction measures against the exact distance to the surface, as a mesh
    // bake's does (its points lie within half a texel of the footprint).
    const HeightFieldDistance surface(field, double(halfBand) + 2.0);
    const ExactDistancesOnLine exactDistances = [&](const glm::dvec2& xy, std::span<const double> z,
                                                    std::span<double> distances) {
        for (std::size_t n = 0; n < z.size(); ++n)
            distances[n] = surface.signedDistanceTexels({xy.x, xy.y, z[n]});
    };
    Tile tile = tileFromLevelSet(levelSet, options.conservative, exactDistances);
    return {std::move(levelSet), std::move(tile)};
}

}  // namespace distile
