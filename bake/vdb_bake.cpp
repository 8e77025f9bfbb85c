#include "bake/vdb_bake.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
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

/// The largest difference between the faces x = 0 and x = W (y = 0 and y = H) at the texel
/// rows that cross them, texels.
glm::dvec2 seamMismatch(const VdbTileSampler& sampler, const Size3& tile) {
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

}  // namespace

VdbBakeResult bakeVdb(const VdbVolume& volume, const VdbPlacement& placement,
                      const BakeOptions& options, const std::string& fileName,
                      const ProgressCallback& progress) {
    const float halfBand = validatedHalfBandTexels(options);
    const TexelPlacement texelPlacement = resolvePlacement(placement, volume, options.size);
    const VdbTileSampler sampler(volume, texelPlacement, options.size, halfBand);

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
        {LevelSet::fromDistance(
             [&sampler](const glm::dvec3& texel) { return sampler.distanceTexels(texel); },
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
