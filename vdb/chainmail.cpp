#include "vdb/chainmail.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "common/error.h"

namespace distile {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Signed distance to a torus around the local z axis: centreline radius R, tube radius r.
double torusDistance(const glm::dvec3& local, double centrelineRadius, double tubeRadius) {
    const double radial = std::hypot(local.x, local.y) - centrelineRadius;
    return std::hypot(radial, local.z) - tubeRadius;
}

double wrap(double value, double period) {
    const double wrapped = std::fmod(value, period);
    return wrapped < 0.0 ? wrapped + period : wrapped;
}

}  // namespace

Chainmail::Chainmail(const ChainmailOptions& options, const Size3& tile)
    : options_(options), tile_(tile) {
    validateTileSize(tile, "chainmail");
    auto reject = [](const std::string& field, double value, const std::string& accepted) {
        std::ostringstream message;
        message << "chainmail: " << field << " = " << value << " is not accepted; " << accepted;
        throw InputError(message.str());
    };
    if (options.ringsPerRow < 1 || options.ringsPerRow > tile.width / 4) {
        reject("rings per row", options.ringsPerRow, "it must be in [1, width/4]");
    }
    if (options.rowsPerTile < 2 || options.rowsPerTile % 2 != 0 ||
        options.rowsPerTile > tile.height / 2) {
        reject("rows per tile", options.rowsPerTile, "it must be even and in [2, height/2]");
    }
    if (!(options.ringRadiusSpacings > 0.0 && options.ringRadiusSpacings <= 2.0)) {
        reject("ring radius", options.ringRadiusSpacings, "it must be in (0, 2] ring spacings");
    }
    if (!(options.wireRadiusSpacings > 0.0 &&
          options.wireRadiusSpacings < options.ringRadiusSpacings)) {
        reject("wire radius", options.wireRadiusSpacings,
               "it must be positive and below the ring radius");
    }
    if (!(options.tiltDeg >= 0.0 && options.tiltDeg <= 60.0)) {
        reject("tilt", options.tiltDeg, "it must be in [0, 60] degrees");
    }
    ringSpacingTexels_ = double(tile.width) / options.ringsPerRow;
    rowSpacingTexels_ = double(tile.height) / options.rowsPerTile;
    ringRadiusTexels_ = options.ringRadiusSpacings * ringSpacingTexels_;
    wireRadiusTexels_ = options.wireRadiusSpacings * ringSpacingTexels_;
    cosTilt_ = std::cos(options.tiltDeg * kPi / 180.0);
    sinTilt_ = std::sin(options.tiltDeg * kPi / 180.0);

    constexpr double kMarginTexels = 0.5;
    if (heightTexels() > tile.depth - 2.0 * kMarginTexels) {
        std::ostringstream message;
        message << "chainmail: rings are " << heightTexels() << " texels tall but the tile is "
                << tile.depth << " deep; they need half a texel of margin at the top and the "
                << "bottom (lower the tilt, the radii, or raise the depth)";
        throw InputError(message.str());
    }
}

double Chainmail::heightTexels() const {
    // The centreline circle (radius R) tilted by t spans 2 R sin t vertically; the tube adds r
    // above and below.
    return 2.0 * (ringRadiusTexels_ * sinTilt_ + wireRadiusTexels_);
}

double Chainmail::signedDistanceTexels(const glm::dvec3& texelPosition) const {
    const double x = wrap(texelPosition.x, tile_.width);
    const double y = wrap(texelPosition.y, tile_.height);
    const double z = texelPosition.z - 0.5 * tile_.depth;

    // Distance to the ring at lattice position (row, column).
    auto ringDistance = [&](int row, int column) {
        const bool oddRow = (row % 2 + 2) % 2 == 1;
        const double sinTilt = oddRow ? -sinTilt_ : sinTilt_;
        const double centreX = column * ringSpacingTexels_ + (oddRow ? 0.5 * ringSpacingTexels_ : 0.0);
        const glm::dvec3 offset{x - centreX, y - row * rowSpacingTexels_, z};
        // Rotate into the ring's frame (rotation about y by -tilt); the ring lies in local z = 0.
        const glm::dvec3 local{cosTilt_ * offset.x - sinTilt * offset.z, offset.y,
                               sinTilt * offset.x + cosTilt_ * offset.z};
        return torusDistance(local, ringRadiusTexels_, wireRadiusTexels_);
    };
    auto nearestColumn = [&](int row) {
        const double rowShift = (row % 2 + 2) % 2 == 1 ? 0.5 * ringSpacingTexels_ : 0.0;
        return int(std::lround((x - rowShift) / ringSpacingTexels_));
    };

    // A ring whose centre is a horizontal distance h away is at least h - (R + r) away, so once
    // one ring's distance d is known, only centres within d + R + r can be nearer.
    const int nearestRow = int(std::lround(y / rowSpacingTexels_));
    double distance = ringDistance(nearestRow, nearestColumn(nearestRow));
    const double reach = std::abs(distance) + ringRadiusTexels_ + wireRadiusTexels_;
    const int rowReach = int(std::ceil(reach / rowSpacingTexels_));
    const int columnReach = int(std::ceil(reach / ringSpacingTexels_));
    for (int row = nearestRow - rowReach; row <= nearestRow + rowReach; ++row) {
        const int centreColumn = nearestColumn(row);
        for (int column = centreColumn - columnReach; column <= centreColumn + columnReach; ++column) {
            distance = std::min(distance, ringDistance(row, column));
        }
    }
    return distance;
}

std::string Chainmail::paramsJson() const {
    std::ostringstream json;
    json << "{\"weave\":\"european4in1\",\"rings_per_row\":" << options_.ringsPerRow
         << ",\"rows_per_tile\":" << options_.rowsPerTile
         << ",\"ring_radius_spacings\":" << options_.ringRadiusSpacings
         << ",\"wire_radius_spacings\":" << options_.wireRadiusSpacings
         << ",\"tilt_deg\":" << options_.tiltDeg << "}";
    return json.str();
}

}  // namespace distile
