#include "bake/vdb_bake.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <glm/common.hpp>
#include <nlohmann/json.hpp>
#include <span>
#include <sstream>

#include "bake/resample.h"
#include "common/error.h"

namespace distile {

namespace {

std::string boxText(const Bounds3& box) {
    std::ostringstream text;
    text << "(" << box.min.x << ", " << box.min.y << ", " << box.min.z << ") - (" << box.max.x
         << ", " << box.max.y << ", " << box.max.z << ")";
    return text.str();
}

/// The window's placement, after checking it against the tile and the volume.
TexelPlacement windowPlacement(const Bounds3& window, const VdbVolume& volume, const Size3& tile) {
    const glm::dvec3 extent = window.max - window.min;
    for (int axis = 0; axis < 3; ++axis) {
        if (!(std::isfinite(window.min[axis]) && std::isfinite(window.max[axis]) &&
              extent[axis] > 0.0)) {
            throw InputError::inField("placement.windowWorld",
                                      boxText(window) +
                                          " is not accepted; give six finite numbers X0 Y0 Z0 X1 "
                                          "Y1 Z1 with X0 < X1, Y0 < Y1, Z0 < Z1 (world units)");
        }
    }
    const double scale = tile.width / extent.x;
    const double scaleY = tile.height / extent.y;
    if (std::abs(scaleY - scale) > 1e-6 * scale) {
        std::ostringstream problem;
        problem << boxText(window) << " is " << extent.x << " x " << extent.y
                << " in x and y; one period must have the tile's aspect " << tile.width << ":"
                << tile.height;
        throw InputError::inField("placement.windowWorld", problem.str());
    }
    if (extent.z * scale > tile.depth * (1.0 + 1e-9)) {
        std::ostringstream problem;
        problem << boxText(window) << " is " << extent.z * scale << " texels tall at " << scale
                << " texels per unit, more than the tile depth " << tile.depth;
        throw InputError::inField("placement.windowWorld", problem.str());
    }
    const Bounds3 active = volume.activeBoundsWorld();
    const Bounds3 surface = volume.surfaceBoundsWorld();
    const double slack = 1e-6 * std::max(extent.x, extent.y);
    const bool withinActive =
        window.min.x >= active.min.x - slack && window.max.x <= active.max.x + slack &&
        window.min.y >= active.min.y - slack && window.max.y <= active.max.y + slack;
    bool meetsSurface = true;
    for (int axis = 0; axis < 3; ++axis) {
        meetsSurface = meetsSurface && window.min[axis] <= surface.max[axis] &&
                       window.max[axis] >= surface.min[axis];
    }
    if (!withinActive || !meetsSurface) {
        throw InputError::inField(
            "placement.windowWorld",
            boxText(window) + " is outside grid '" + volume.gridName() +
                "': its x and y must lie within its active voxels' centres " + boxText(active) +
                " (nothing is extrapolated) and it must meet the surface " + boxText(surface));
    }
    return {scale, -scale * window.min + 0.0};  // + 0.0: no negative zeros
}

TexelPlacement resolvePlacement(const VdbPlacement& placement, const VdbVolume& volume,
                                const Size3& tile) {
    switch (placement.mode) {
        case VdbPlacement::Mode::Explicit:
            return {placement.scale, placement.offsetTexels};
        case VdbPlacement::Mode::Window:
            return windowPlacement(placement.windowWorld, volume, tile);
        case VdbPlacement::Mode::Fit:
            break;
    }
    const FootprintFit fitted =
        fitToFootprint(volume.surfaceBoundsWorld(), tile, "grid '" + volume.gridName() + "'");
    return {fitted.scale, fitted.offsetTexels};
}

/// Throws InputError (naming the placement's offset) unless the surface of `volume` placed by
/// `placement` is at least a texel across and its box overlaps the tile: otherwise the tile holds
/// no detail (or a speck no texel resolves). The surface may extend beyond the tile: a placement
/// may cut one tile out of a larger volume.
void requireSurfaceInTile(const VdbVolume& volume, const TexelPlacement& placement,
                          const Size3& tile, const std::string& fileName) {
    const Bounds3 world = volume.surfaceBoundsWorld();
    const glm::dvec3 low = placement.scale * world.min + placement.offsetTexels;
    const glm::dvec3 high = placement.scale * world.max + placement.offsetTexels;
    const glm::dvec3 tileTexels(tile.width, tile.height, tile.depth);
    std::ostringstream problem;
    problem << fileName << ": the surface of grid '" << volume.gridName() << "', placed at "
            << placement.scale << " texels per unit in the " << toString(tile) << " tile, ";
    const double largestExtent = std::max({high.x - low.x, high.y - low.y, high.z - low.z});
    if (!(largestExtent >= 1.0)) {
        problem << "is " << largestExtent << " texels across, less than one texel";
        throw InputError::inField("placement.scale", problem.str());
    }
    for (int axis = 0; axis < 3; ++axis) {
        if (high[axis] < 0.0 || low[axis] > tileTexels[axis]) {
            problem << "lies at "
                    << "xyz"[axis] << " in [" << low[axis] << ", " << high[axis]
                    << "], outside the tile's [0, " << tileTexels[axis] << "]";
            throw InputError::inField("placement.offsetTexels", problem.str());
        }
    }
}

/// The largest difference between the faces x = 0 and x = W (y = 0 and y = H) at the texel
/// rows that cross them, texels.
glm::dvec2 seamMismatch(const VdbDistance& sampler, const Size3& tile) {
    glm::dvec2 mismatch(0.0);
    for (int k = 0; k < tile.depth; ++k) {
        for (int j = 0; j < tile.height; ++j) {
            const double y = j + 0.5;
            const double z = k + 0.5;
            mismatch.x = std::max(mismatch.x, std::abs(sampler.distanceTexels({0.0, y, z}) -
                                                       sampler.distanceTexels({tile.width, y, z})));
        }
        for (int i = 0; i < tile.width; ++i) {
            const double x = i + 0.5;
            const double z = k + 0.5;
            mismatch.y =
                std::max(mismatch.y, std::abs(sampler.distanceTexels({x, 0.0, z}) -
                                              sampler.distanceTexels({x, tile.height, z})));
        }
    }
    return mismatch;
}

/// The triangles of `soup` whose box comes within `reach` of `box`, as a soup of their own.
TriangleSoup trianglesNear(const TriangleSoup& soup, const Bounds3& box, double reach) {
    TriangleSoup near;
    near.positions = soup.positions;
    for (const glm::uvec3& t : soup.triangles) {
        bool overlaps = true;
        for (int axis = 0; axis < 3 && overlaps; ++axis) {
            const double lo = std::min(
                {soup.positions[t.x][axis], soup.positions[t.y][axis], soup.positions[t.z][axis]});
            const double hi = std::max(
                {soup.positions[t.x][axis], soup.positions[t.y][axis], soup.positions[t.z][axis]});
            overlaps = lo <= box.max[axis] + reach && hi >= box.min[axis] - reach;
        }
        if (overlaps) near.triangles.push_back(t);
    }
    return near;
}

}  // namespace

VdbDistance::VdbDistance(const VdbVolume& volume, const TexelPlacement& placement,
                         const Size3& tile, float halfBandTexels)
    : source_(volume, placement), tile_(tile), halfBandTexels_(halfBandTexels) {
    validateTileSize(tile, "size");
    if (!(halfBandTexels >= 1.0f && halfBandTexels <= 1024.0f)) {
        throw InputError::inField("halfBandTexels", numberText(halfBandTexels) +
                                                        " texels is not accepted; it must be in "
                                                        "[1, 1024]");
    }
    const glm::dvec3 voxel = volume.voxelSizeWorld() * placement.scale;
    const double voxelTexels = std::max({voxel.x, voxel.y, voxel.z});
    if (source_.isLevelSet() && source_.bandTexels() >= halfBandTexels) return;

    // The surface near the tile's box, placed in texel space.
    const Bounds3 queries{glm::dvec3(-(halfBandTexels_ + 1.0)),
                          glm::dvec3(tile.width, tile.height, tile.depth) + halfBandTexels_ + 1.0};
    const double reach = halfBandTexels_ + voxelTexels;
    const Bounds3 regionWorld{(queries.min - reach - placement.offsetTexels) / placement.scale,
                              (queries.max + reach - placement.offsetTexels) / placement.scale};
    TriangleSoup placed =
        volume.refinedSurfaceWorld(kVdbSurfaceEdgeTexels / placement.scale, regionWorld);
    for (glm::dvec3& position : placed.positions)
        position = placement.scale * position + placement.offsetTexels;
    placed = trianglesNear(placed, queries, halfBandTexels_);
    rebuilt_ = true;
    if (placed.triangles.empty()) return;  // nothing within the band: +-band everywhere
    // SoupDistance repeats the soup with a period; one wider than the soup and the queries
    // together plus the search radius keeps every other copy out of reach.
    const Bounds3 soupBox = boundsOf(placed);
    const glm::dvec3 span = glm::max(soupBox.max, queries.max) - glm::min(soupBox.min, queries.min);
    const double period = std::ceil(std::max(span.x, span.y) + halfBandTexels_ + 1.0);
    if (!(period < double(INT_MAX))) {
        throw InputError::inField("placement.scale",
                                  numberText(placement.scale) +
                                      " texels per unit makes the source's voxels too large to "
                                      "rebuild its band");
    }
    surface_ =
        std::make_shared<const SoupDistance>(placed, Size3{int(period), int(period), tile.depth});
}

double VdbDistance::distanceTexels(const glm::dvec3& texelPosition) const {
    SoupDistance::NearestHint none;
    return distanceTexels(texelPosition, none);
}

double VdbDistance::distanceTexels(const glm::dvec3& texelPosition,
                                   SoupDistance::NearestHint& hint) const {
    const double band = halfBandTexels_;
    const VdbSourceSampler::Sample sample = source_.sample(texelPosition);
    const double sourceTexels = std::clamp(sample.valueTexels, -band, band);
    if (!rebuilt_) return sourceTexels;
    const double outside = band + 1.0;
    const bool inReach = texelPosition.x >= -outside && texelPosition.y >= -outside &&
                         texelPosition.z >= -outside && texelPosition.x <= tile_.width + outside &&
                         texelPosition.y <= tile_.height + outside &&
                         texelPosition.z <= tile_.depth + outside;
    if (!surface_ || !inReach) return sample.inside ? -band : band;
    const double unsignedTexels = surface_->unsignedDistance(texelPosition, band, hint);
    return sample.inside ? -unsignedTexels : unsignedTexels;
}

VdbBakeResult bakeVdb(const VdbVolume& volume, const VdbPlacement& placement,
                      const BakeOptions& options, const std::string& fileName,
                      const ProgressCallback& progress) {
    const float halfBand = validatedHalfBandTexels(options);
    const TexelPlacement texelPlacement = resolvePlacement(placement, volume, options.size);
    const VdbDistance sampler(volume, texelPlacement, options.size, halfBand);  // checks it
    requireSurfaceInTile(volume, texelPlacement, options.size, fileName);

    nlohmann::json params = {
        {"file", fileName},
        {"grid", volume.gridName()},
        {"placement", placement.mode == VdbPlacement::Mode::Fit        ? "fit"
                      : placement.mode == VdbPlacement::Mode::Explicit ? "explicit"
                                                                       : "window"},
        {"scale", texelPlacement.scale},
        {"offset",
         {texelPlacement.offsetTexels.x, texelPlacement.offsetTexels.y,
          texelPlacement.offsetTexels.z}}};
    if (placement.mode == VdbPlacement::Mode::Window) {
        const Bounds3& window = placement.windowWorld;
        params["window"] = {window.min.x, window.min.y, window.min.z,
                            window.max.x, window.max.y, window.max.z};
    }
    if (!volume.isLevelSet() || volume.iso() != 0.0) params["iso"] = volume.iso();

    VdbBakeResult result{
        {LevelSet::fromDistanceRows(
             [&sampler](int j, int k, std::span<double> row) {
                 // The previous texel's nearest triangle starts the search: the same result.
                 SoupDistance::NearestHint hint;
                 for (std::size_t i = 0; i < row.size(); ++i)
                     row[i] = sampler.distanceTexels({double(i) + 0.5, j + 0.5, k + 0.5}, hint);
             },
             options.size, halfBand, "vdb", params.dump(), progress),
         Tile(options.size)},
        texelPlacement,
        std::nullopt,
        sampler.rebuilt()};
    result.bake.tile = tileFromLevelSet(result.bake.levelSet, options.conservative);
    if (placement.mode == VdbPlacement::Mode::Window) {
        result.seamMismatchTexels = seamMismatch(sampler, options.size);
    }
    return result;
}

}  // namespace distile
