#include "vdb/chainmail.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include "common/error.h"

namespace distile {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Signed distance to a torus around the local z axis: centreline radius R, tube radius r. Plain
/// square roots, not std::hypot: the coordinates are texels, far from overflow, and glibc's
/// hypot was half of a chain-mail bake's time.
double torusDistance(const glm::dvec3& local, double centrelineRadius, double tubeRadius) {
    const double radial = std::sqrt(local.x * local.x + local.y * local.y) - centrelineRadius;
    return std::sqrt(radial * radial + local.z * local.z) - tubeRadius;
}

double wrap(double value, double period) {
    const double wrapped = std::fmod(value, period);
    return wrapped < 0.0 ? wrapped + period : wrapped;
}

}  // namespace

ChainmailOptions japanese4in1Defaults() {
    ChainmailOptions options;
    options.weave = ChainmailWeave::Japanese4in1;
    options.ringsPerRow = 8;
    options.rowsPerTile = 8;
    options.ringRadiusSpacings = 0.4296875;       // 13.75 texels at 32-texel spacing
    options.wireRadiusSpacings = 0.046875;        // 1.5 texels
    options.smallRingRadiusSpacings = 0.1875;     // 6 texels
    options.smallWireRadiusSpacings = 0.0390625;  // 1.25 texels
    options.tiltDeg = 0.0;
    return options;
}

const char* weaveName(ChainmailWeave weave) {
    return weave == ChainmailWeave::Japanese4in1 ? "japanese4in1" : "european4in1";
}

Chainmail::Chainmail(const ChainmailOptions& options, const Size3& tile)
    : options_(options), tile_(tile) {
    validateTileSize(tile, "chainmail");
    // About the field of ProceduralOptions it came from ("chainmail.rowsPerTile"), so a program
    // can show it under the flag or key that filled it.
    auto reject = [](const char* member, double value, const std::string& accepted) {
        throw InputError::inField(std::string("chainmail.") + member,
                                  numberText(value) + " is not accepted; " + accepted);
    };
    if (options.ringsPerRow < 1 || options.ringsPerRow > tile.width / 4) {
        reject("ringsPerRow", options.ringsPerRow, "it must be in [1, width/4]");
    }
    const bool japanese = options.weave == ChainmailWeave::Japanese4in1;
    if (japanese) {
        if (options.rowsPerTile < 1 || options.rowsPerTile > tile.height / 4) {
            reject("rowsPerTile", options.rowsPerTile, "it must be in [1, height/4]");
        }
    } else if (options.rowsPerTile < 2 || options.rowsPerTile % 2 != 0 ||
               options.rowsPerTile > tile.height / 2) {
        reject("rowsPerTile", options.rowsPerTile, "it must be even and in [2, height/2]");
    }
    if (!(options.ringRadiusSpacings > 0.0 && options.ringRadiusSpacings <= 2.0)) {
        reject("ringRadiusSpacings", options.ringRadiusSpacings,
               "it must be in (0, 2] ring spacings");
    }
    if (!(options.wireRadiusSpacings > 0.0 &&
          options.wireRadiusSpacings < options.ringRadiusSpacings)) {
        reject("wireRadiusSpacings", options.wireRadiusSpacings,
               "it must be positive and below the ring radius");
    }
    if (!(options.tiltDeg >= 0.0 && options.tiltDeg <= 60.0)) {
        reject("tiltDeg", options.tiltDeg, "it must be in [0, 60] degrees");
    }
    ringSpacingTexels_ = double(tile.width) / options.ringsPerRow;
    rowSpacingTexels_ = double(tile.height) / options.rowsPerTile;
    ringRadiusTexels_ = options.ringRadiusSpacings * ringSpacingTexels_;
    wireRadiusTexels_ = options.wireRadiusSpacings * ringSpacingTexels_;
    cosTilt_ = std::cos(options.tiltDeg * kPi / 180.0);
    sinTilt_ = std::sin(options.tiltDeg * kPi / 180.0);
    if (japanese) {
        if (!(options.smallRingRadiusSpacings > 0.0 && options.smallRingRadiusSpacings <= 1.0)) {
            reject("smallRingRadiusSpacings", options.smallRingRadiusSpacings,
                   "it must be in (0, 1] ring spacings");
        }
        if (!(options.smallWireRadiusSpacings > 0.0 &&
              options.smallWireRadiusSpacings < options.smallRingRadiusSpacings)) {
            reject("smallWireRadiusSpacings", options.smallWireRadiusSpacings,
                   "it must be positive and below the small ring radius");
        }
        smallRingRadiusTexels_ = options.smallRingRadiusSpacings * ringSpacingTexels_;
        smallWireRadiusTexels_ = options.smallWireRadiusSpacings * ringSpacingTexels_;
        const double outerRadius = ringRadiusTexels_ + wireRadiusTexels_;
        if (2.0 * outerRadius >= std::min(ringSpacingTexels_, rowSpacingTexels_)) {
            reject(
                "ringRadiusSpacings", options.ringRadiusSpacings,
                "Japanese 4-in-1 large rings (ring + wire radius) must not touch their neighbours");
        }
    }

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
    if (options_.weave == ChainmailWeave::Japanese4in1) {
        // Flat large rings are 2 r tall; vertical small rings 2 (rho + r_s).
        return 2.0 * std::max(wireRadiusTexels_, smallRingRadiusTexels_ + smallWireRadiusTexels_);
    }
    // The centreline circle (radius R) tilted by t spans 2 R sin t vertically; the tube adds r
    // above and below.
    return 2.0 * (ringRadiusTexels_ * sinTilt_ + wireRadiusTexels_);
}

double Chainmail::signedDistanceTexels(const glm::dvec3& texelPosition) const {
    const double x = wrap(texelPosition.x, tile_.width);
    const double y = wrap(texelPosition.y, tile_.height);
    const double z = texelPosition.z - 0.5 * tile_.depth;
    // Every ring lies in the slab |z| <= heightTexels() / 2. Far above or below it the searches
    // below would visit every ring within the point's distance, a disk growing with it (points
    // 1e13 texels away, where a reference render's rays through a shell 3e-14 units deep sample,
    // kept a render of 8 pixels busy for over 5 minutes). Beyond farSlabTexels() the distance to
    // the slab is returned instead: a lower bound, so steps stay safe, short of the exact distance
    // by at most the slab's thickness plus about (ring spacing)^2 / that distance. No tile or
    // check samples that far from the rings.
    const double aboveSlab = std::abs(z) - 0.5 * heightTexels();
    if (aboveSlab > farSlabTexels()) return aboveSlab;
    if (options_.weave == ChainmailWeave::Japanese4in1) return japaneseDistanceTexels(x, y, z);

    // Distance to the ring at lattice position (row, column).
    auto ringDistance = [&](int row, int column) {
        const bool oddRow = (row % 2 + 2) % 2 == 1;
        const double sinTilt = oddRow ? -sinTilt_ : sinTilt_;
        const double centreX =
            column * ringSpacingTexels_ + (oddRow ? 0.5 * ringSpacingTexels_ : 0.0);
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
    // The same bound prunes candidates as the distance shrinks (skipped rings cannot be nearer, so
    // the minimum is unchanged); compared squared: distance + extent >= R > 0.
    const double extent = ringRadiusTexels_ + wireRadiusTexels_;
    for (int row = nearestRow - rowReach; row <= nearestRow + rowReach; ++row) {
        const double dy = y - row * rowSpacingTexels_;
        if (std::abs(dy) >= distance + extent) continue;
        const int centreColumn = nearestColumn(row);
        const double rowShift = (row % 2 + 2) % 2 == 1 ? 0.5 * ringSpacingTexels_ : 0.0;
        for (int column = centreColumn - columnReach; column <= centreColumn + columnReach;
             ++column) {
            const double dx = x - (column * ringSpacingTexels_ + rowShift);
            const double reachNow = distance + extent;
            if (dx * dx + dy * dy >= reachNow * reachNow) continue;
            distance = std::min(distance, ringDistance(row, column));
        }
    }
    return distance;
}

double Chainmail::japaneseDistanceTexels(double x, double y, double z) const {
    // Three ring families on the lattice (s along x, t along y), centred at mid-depth:
    //  large flat rings at (i s, j t), axis z;
    //  small rings joining neighbours along x at ((i + 1/2) s, j t), in the x-z plane (axis y);
    //  small rings joining neighbours along y at (i s, (j + 1/2) t), in the y-z plane (axis x).
    const double s = ringSpacingTexels_;
    const double t = rowSpacingTexels_;
    struct Family {
        double offsetX, offsetY;  ///< centre of ring (0, 0), texels
        double extentTexels;  ///< horizontal distance from the centre to the farthest surface point
    };
    const Family families[3] = {{0.0, 0.0, ringRadiusTexels_ + wireRadiusTexels_},
                                {0.5 * s, 0.0, smallRingRadiusTexels_ + smallWireRadiusTexels_},
                                {0.0, 0.5 * t, smallRingRadiusTexels_ + smallWireRadiusTexels_}};
    auto ringDistance = [&](int family, int column, int row) {
        const double dx = x - (column * s + families[family].offsetX);
        const double dy = y - (row * t + families[family].offsetY);
        if (family == 0) return torusDistance({dx, dy, z}, ringRadiusTexels_, wireRadiusTexels_);
        const glm::dvec3 local = family == 1 ? glm::dvec3(dx, z, dy) : glm::dvec3(dy, z, dx);
        return torusDistance(local, smallRingRadiusTexels_, smallWireRadiusTexels_);
    };
    // Nearest ring of each family first; then, as for the European weave, only rings whose centre
    // is within |d| + extent horizontally can be nearer (a ring's surface lies within `extent` of
    // its centre horizontally, so a point h away from the centre is at least h - extent away).
    double distance = std::numeric_limits<double>::infinity();
    for (int family = 0; family < 3; ++family) {
        distance = std::min(
            distance, ringDistance(family, int(std::lround((x - families[family].offsetX) / s)),
                                   int(std::lround((y - families[family].offsetY) / t))));
    }
    const double bound = std::abs(distance);
    for (int family = 0; family < 3; ++family) {
        const Family& f = families[family];
        const double reach = bound + f.extentTexels;
        const int columnBegin = int(std::ceil((x - reach - f.offsetX) / s));
        const int columnEnd = int(std::floor((x + reach - f.offsetX) / s));
        const int rowBegin = int(std::ceil((y - reach - f.offsetY) / t));
        const int rowEnd = int(std::floor((y + reach - f.offsetY) / t));
        for (int row = rowBegin; row <= rowEnd; ++row) {
            const double dy = y - (row * t + f.offsetY);
            for (int column = columnBegin; column <= columnEnd; ++column) {
                // Prune as the distance shrinks: a ring h away horizontally is at least h - extent
                // away.
                const double dx = x - (column * s + f.offsetX);
                const double reachNow = distance + f.extentTexels;
                if (reachNow > 0.0 && dx * dx + dy * dy >= reachNow * reachNow) continue;
                distance = std::min(distance, ringDistance(family, column, row));
            }
        }
    }
    return distance;
}

std::string Chainmail::paramsJson() const {
    std::ostringstream json;
    json.precision(15);  // decimal options round-trip through the tile's provenance
    if (options_.weave == ChainmailWeave::Japanese4in1) {
        json << "{\"weave\":\"japanese4in1\",\"rings_per_row\":" << options_.ringsPerRow
             << ",\"rows_per_tile\":" << options_.rowsPerTile
             << ",\"ring_radius_spacings\":" << options_.ringRadiusSpacings
             << ",\"wire_radius_spacings\":" << options_.wireRadiusSpacings
             << ",\"small_ring_radius_spacings\":" << options_.smallRingRadiusSpacings
             << ",\"small_wire_radius_spacings\":" << options_.smallWireRadiusSpacings << "}";
        return json.str();
    }
    json << "{\"weave\":\"european4in1\",\"rings_per_row\":" << options_.ringsPerRow
         << ",\"rows_per_tile\":" << options_.rowsPerTile
         << ",\"ring_radius_spacings\":" << options_.ringRadiusSpacings
         << ",\"wire_radius_spacings\":" << options_.wireRadiusSpacings
         << ",\"tilt_deg\":" << options_.tiltDeg << "}";
    return json.str();
}

namespace {

/// Throws InputError unless the weave and segment counts can be tessellated.
void validateTessellation(const Chainmail& chainmail, int segmentsAround, int segmentsTube) {
    if (chainmail.options().weave != ChainmailWeave::European4in1) {
        throw InputError("chainmail tessellation: only the european4in1 weave is supported, not " +
                         std::string(weaveName(chainmail.options().weave)));
    }
    for (const int segments : {segmentsAround, segmentsTube}) {
        if (segments < 3 || segments > 4096) {
            throw InputError("chainmail tessellation: " + std::to_string(segments) +
                             " segments is not accepted; it must be in [3, 4096]");
        }
    }
}

}  // namespace

TriangleSoup tessellateChainmail(const Chainmail& chainmail, int segmentsAround, int segmentsTube) {
    validateTessellation(chainmail, segmentsAround, segmentsTube);
    const ChainmailOptions& options = chainmail.options();
    const Size3& tile = chainmail.tileSize();
    const double spacing = double(tile.width) / options.ringsPerRow;
    const double rowSpacing = double(tile.height) / options.rowsPerTile;
    const double ringRadius = options.ringRadiusSpacings * spacing;
    const double wireRadius = options.wireRadiusSpacings * spacing;
    const auto verticesPerRing = std::size_t(segmentsAround) * std::size_t(segmentsTube);
    const auto rings = std::size_t(options.rowsPerTile) * std::size_t(options.ringsPerRow);
    TriangleSoup soup;
    soup.positions.reserve(rings * verticesPerRing);
    soup.triangles.reserve(2 * rings * verticesPerRing);
    for (int row = 0; row < options.rowsPerTile; ++row) {
        const bool oddRow = row % 2 == 1;
        const double tilt = (oddRow ? -1.0 : 1.0) * options.tiltDeg * kPi / 180.0;
        const double cosTilt = std::cos(tilt);
        const double sinTilt = std::sin(tilt);
        for (int column = 0; column < options.ringsPerRow; ++column) {
            const glm::dvec3 centre{column * spacing + (oddRow ? 0.5 * spacing : 0.0),
                                    row * rowSpacing, 0.5 * tile.depth};
            const auto first = unsigned(soup.positions.size());
            for (int i = 0; i < segmentsAround; ++i) {
                const double around = 2.0 * kPi * i / segmentsAround;
                for (int j = 0; j < segmentsTube; ++j) {
                    const double tube = 2.0 * kPi * j / segmentsTube;
                    // The torus in the ring's frame (axis local z), rotated about y by the tilt:
                    // the inverse of the rotation in signedDistanceTexels().
                    const double radial = ringRadius + wireRadius * std::cos(tube);
                    const glm::dvec3 local{radial * std::cos(around), radial * std::sin(around),
                                           wireRadius * std::sin(tube)};
                    soup.positions.push_back(
                        centre + glm::dvec3{cosTilt * local.x + sinTilt * local.z, local.y,
                                            -sinTilt * local.x + cosTilt * local.z});
                }
            }
            auto vertex = [&](int i, int j) {
                return first + unsigned((i % segmentsAround) * segmentsTube + j % segmentsTube);
            };
            for (int i = 0; i < segmentsAround; ++i) {
                for (int j = 0; j < segmentsTube; ++j) {
                    soup.triangles.push_back(
                        {vertex(i, j), vertex(i + 1, j), vertex(i + 1, j + 1)});
                    soup.triangles.push_back(
                        {vertex(i, j), vertex(i + 1, j + 1), vertex(i, j + 1)});
                }
            }
        }
    }
    return soup;
}

double chainmailTessellationErrorTexels(const Chainmail& chainmail, int segmentsAround,
                                        int segmentsTube) {
    validateTessellation(chainmail, segmentsAround, segmentsTube);
    const ChainmailOptions& options = chainmail.options();
    const double spacing = double(chainmail.tileSize().width) / options.ringsPerRow;
    const double ringRadius = options.ringRadiusSpacings * spacing;
    const double wireRadius = options.wireRadiusSpacings * spacing;
    return (ringRadius + wireRadius) * (1.0 - std::cos(kPi / segmentsAround)) +
           wireRadius * (1.0 - std::cos(kPi / segmentsTube));
}

}  // namespace distile
