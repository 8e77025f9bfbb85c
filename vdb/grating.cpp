#include "vdb/grating.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "common/error.h"

namespace distile {

namespace {

/// Exact signed distance to a rectangle of half extents (halfWidth, halfHeight) centred at the
/// origin whose corners are rounded with `radius` (<= both half extents).
double roundedRectangleDistance(double across, double up, double halfWidth, double halfHeight,
                                double radius) {
    const double qx = std::abs(across) - (halfWidth - radius);
    const double qy = std::abs(up) - (halfHeight - radius);
    const double outside = std::hypot(std::max(qx, 0.0), std::max(qy, 0.0));
    const double inside = std::min(std::max(qx, qy), 0.0);
    return outside + inside - radius;
}

/// Offset of `value` from the nearest bar centre of a family at (k + 1/2) * spacing.
double offsetFromNearestBar(double value, double spacing) {
    const double shifted = value / spacing - 0.5;
    return (shifted - std::round(shifted)) * spacing;
}

}  // namespace

Grating::Grating(const GratingOptions& options, const Size3& tile)
    : options_(options), tile_(tile) {
    validateTileSize(tile, "grating");
    // About the field of ProceduralOptions it came from ("grating.barsPerTile"), so a program can
    // show it under the flag or key that filled it.
    auto reject = [](const char* member, double value, const std::string& accepted) {
        throw InputError::inField(std::string("grating.") + member,
                                  numberText(value) + " is not accepted; " + accepted);
    };
    if (options.barsPerTile < 1 || options.barsPerTile > std::min(tile.width, tile.height) / 4) {
        reject("barsPerTile", options.barsPerTile, "it must be in [1, min(width, height)/4]");
    }
    const double spacing = double(std::min(tile.width, tile.height)) / options.barsPerTile;
    if (!(options.barWidthTexels > 0.0 && options.barWidthTexels < spacing)) {
        reject("barWidthTexels", options.barWidthTexels,
               "it must be positive and below the bar spacing (texels)");
    }
    if (!(options.barHeightTexels > 0.0 && std::isfinite(options.barHeightTexels))) {
        reject("barHeightTexels", options.barHeightTexels,
               "it must be a positive number of texels");
    }
    const double halfSmaller = 0.5 * std::min(options.barWidthTexels, options.barHeightTexels);
    if (!(options.edgeRadiusTexels >= 0.0 && options.edgeRadiusTexels <= halfSmaller)) {
        reject("edgeRadiusTexels", options.edgeRadiusTexels,
               "it must be in [0, half the bar width and height]");
    }
    if (!(options.layerGapTexels > 0.0 && std::isfinite(options.layerGapTexels))) {
        reject("layerGapTexels", options.layerGapTexels,
               "it must be a positive number of texels (the layers must not touch)");
    }
    if (heightTexels() > tile.depth - 1.0) {
        std::ostringstream message;
        message << "grating: bars and gap are " << heightTexels() << " texels tall but the tile is "
                << tile.depth
                << " deep; they need half a texel of margin at the top and the bottom";
        throw InputError(message.str());
    }
}

double Grating::heightTexels() const {
    return 2.0 * options_.barHeightTexels + options_.layerGapTexels;
}

double Grating::signedDistanceTexels(const glm::dvec3& p) const {
    const double halfWidth = 0.5 * options_.barWidthTexels;
    const double halfHeight = 0.5 * options_.barHeightTexels;
    const double layerOffset = 0.5 * (options_.barHeightTexels + options_.layerGapTexels);
    const double z = p.z - 0.5 * tile_.depth;
    // Bars run infinitely along their axis, so each family's nearest bar is the one whose centre
    // line is nearest across: its cross-section distance is the family's distance.
    const double upperAcross =
        offsetFromNearestBar(p.y, double(tile_.height) / options_.barsPerTile);
    const double lowerAcross =
        offsetFromNearestBar(p.x, double(tile_.width) / options_.barsPerTile);
    const double upper = roundedRectangleDistance(upperAcross, z - layerOffset, halfWidth,
                                                  halfHeight, options_.edgeRadiusTexels);
    const double lower = roundedRectangleDistance(lowerAcross, z + layerOffset, halfWidth,
                                                  halfHeight, options_.edgeRadiusTexels);
    return std::min(upper, lower);
}

std::string Grating::paramsJson() const {
    std::ostringstream json;
    json.precision(15);
    json << "{\"bars_per_tile\":" << options_.barsPerTile
         << ",\"bar_width_texels\":" << options_.barWidthTexels
         << ",\"bar_height_texels\":" << options_.barHeightTexels
         << ",\"edge_radius_texels\":" << options_.edgeRadiusTexels
         << ",\"layer_gap_texels\":" << options_.layerGapTexels << "}";
    return json.str();
}

}  // namespace distile
