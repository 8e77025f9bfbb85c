#include "vdb/height_field.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <sstream>

#include "common/error.h"
#include "vdb/detail/openvdb_mesh.h"

namespace distile {

namespace {

int wrap(int index, int count) {
    const int r = index % count;
    return r < 0 ? r + count : r;
}

/// Squared distance from p to triangle (a, b, c), double precision (closest point by Voronoi
/// regions of the vertices, edges and face).
double squaredDistanceToTriangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                 const glm::dvec3& c) {
    const auto squared = [](const glm::dvec3& v) { return glm::dot(v, v); };
    const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return squared(ap);
    const glm::dvec3 bp = p - b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return squared(bp);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return squared(ap - ab * (d1 / (d1 - d3)));
    const glm::dvec3 cp = p - c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return squared(cp);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return squared(ap - ac * (d2 / (d2 - d6)));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        return squared(bp - (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    const double denominator = 1.0 / (va + vb + vc);
    return squared(ap - ab * (vb * denominator) - ac * (vc * denominator));
}

/// Exact unsigned distance from `p` to the triangulated surface, or `bound` if nothing is nearer
/// than `bound`: every cell whose box (x/y footprint times the range of its four node heights)
/// comes nearer than the best distance so far is tested. @pre bound >= 0.
double distanceToSurface(const HeightField& field, const std::vector<glm::dvec2>& cellHeightRange,
                         const glm::dvec3& p, double bound) {
    double best = bound;
    // Cell (ci, cj) spans x in [ci + 0.5, ci + 1.5], y in [cj + 0.5, cj + 1.5].
    const int ciBegin = int(std::floor(p.x - 1.5 - best)),
              ciEnd = int(std::floor(p.x - 0.5 + best));
    const int cjBegin = int(std::floor(p.y - 1.5 - best)),
              cjEnd = int(std::floor(p.y - 0.5 + best));
    const auto gap = [](double value, double low, double high) {
        return value < low ? low - value : (value > high ? value - high : 0.0);
    };
    for (int cj = cjBegin; cj <= cjEnd; ++cj) {
        const double dy = gap(p.y, cj + 0.5, cj + 1.5);
        if (dy >= best) continue;
        for (int ci = ciBegin; ci <= ciEnd; ++ci) {
            const double dx = gap(p.x, ci + 0.5, ci + 1.5);
            const glm::dvec2 range =
                cellHeightRange[std::size_t(wrap(ci, field.width)) +
                                std::size_t(wrap(cj, field.height)) * std::size_t(field.width)];
            const double dz = gap(p.z, range.x, range.y);
            if (dx * dx + dy * dy + dz * dz >= best * best) continue;
            const glm::dvec3 n00(ci + 0.5, cj + 0.5, field.node(ci, cj));
            const glm::dvec3 n10(ci + 1.5, cj + 0.5, field.node(ci + 1, cj));
            const glm::dvec3 n01(ci + 0.5, cj + 1.5, field.node(ci, cj + 1));
            const glm::dvec3 n11(ci + 1.5, cj + 1.5, field.node(ci + 1, cj + 1));
            const double squared = std::min(squaredDistanceToTriangle(p, n00, n10, n11),
                                            squaredDistanceToTriangle(p, n00, n11, n01));
            best = std::min(best, std::sqrt(squared));
        }
    }
    return best;
}

}  // namespace

double HeightField::node(int i, int j) const {
    return heightsTexels[std::size_t(wrap(i, width)) +
                         std::size_t(wrap(j, height)) * std::size_t(width)];
}

void validateHeightField(const HeightField& field, const Size3& tile, const std::string& what) {
    if (field.width != tile.width || field.height != tile.height ||
        field.heightsTexels.size() != std::size_t(field.width) * std::size_t(field.height)) {
        std::ostringstream message;
        message << what << ": height field of " << field.width << "x" << field.height << " nodes ("
                << field.heightsTexels.size() << " heights) does not match the " << tile.width
                << "x" << tile.height << " tile footprint; one height per texel column is expected";
        throw InputError(message.str());
    }
    for (std::size_t n = 0; n < field.heightsTexels.size(); ++n) {
        const double h = field.heightsTexels[n];
        if (!(std::isfinite(h) && h >= 0.0 && h <= double(tile.depth))) {
            std::ostringstream message;
            message << what << ": height " << h << " at node (" << n % std::size_t(field.width)
                    << ", " << n / std::size_t(field.width)
                    << ") is not accepted; heights must be finite and in [0, " << tile.depth
                    << "] texels";
            throw InputError(message.str());
        }
    }
}

double heightFieldSurfaceTexels(const HeightField& field, double x, double y) {
    const double u = x - 0.5, v = y - 0.5;
    const double iFloor = std::floor(u), jFloor = std::floor(v);
    const double fx = u - iFloor, fy = v - jFloor;
    const int i = int(iFloor), j = int(jFloor);
    const double h00 = field.node(i, j), h10 = field.node(i + 1, j);
    const double h01 = field.node(i, j + 1), h11 = field.node(i + 1, j + 1);
    // Split along the (i, j)-(i+1, j+1) diagonal: triangle (00, 10, 11) below it, (00, 11, 01)
    // above.
    if (fx >= fy) return h00 + fx * (h10 - h00) + fy * (h11 - h10);
    return h00 + fy * (h01 - h00) + fx * (h11 - h01);
}

TriangleSoup heightFieldTriangles(const HeightField& field, int marginNodes) {
    TriangleSoup soup;
    const int first = -marginNodes;
    const int columns = field.width + 2 * marginNodes + 1;  // nodes along x
    const int rows = field.height + 2 * marginNodes + 1;
    soup.positions.reserve(std::size_t(columns) * std::size_t(rows));
    for (int j = 0; j < rows; ++j) {
        for (int i = 0; i < columns; ++i) {
            soup.positions.emplace_back(first + i + 0.5, first + j + 0.5,
                                        field.node(first + i, first + j));
        }
    }
    const auto index = [columns](int i, int j) { return unsigned(i + j * columns); };
    soup.triangles.reserve(2 * std::size_t(columns - 1) * std::size_t(rows - 1));
    for (int j = 0; j + 1 < rows; ++j) {
        for (int i = 0; i + 1 < columns; ++i) {
            // Counter-clockwise seen from above (+z), split as heightFieldSurfaceTexels does.
            soup.triangles.emplace_back(index(i, j), index(i + 1, j), index(i + 1, j + 1));
            soup.triangles.emplace_back(index(i, j), index(i + 1, j + 1), index(i, j + 1));
        }
    }
    return soup;
}

LevelSet levelSetFromHeightField(const HeightField& field, const Size3& tile, float halfBandTexels,
                                 const std::string& source, const std::string& params,
                                 const ProgressCallback& progress) {
    validateTileSize(tile, "height field level set");
    if (!(halfBandTexels >= 1.0f && halfBandTexels <= 1024.0f)) {
        throw InputError("height field level set: half band width " +
                         std::to_string(halfBandTexels) +
                         " texels is not accepted; it must be in [1, 1024]");
    }
    validateHeightField(field, tile, "height field level set");
    openvdb::initialize();

    // The surface over the footprint plus periodic neighbours wider than the band, so every voxel
    // of the tile within the band sees all triangles that can be nearest to it.
    const float convertedBand = halfBandTexels + 2.0f;  // OpenVDB's band is ragged at its edge
    const TriangleSoup surface = heightFieldTriangles(field, int(std::ceil(convertedBand)) + 2);
    const detail::OpenVdbMesh mesh = detail::toOpenVdbIndexSpace(surface);
    const auto transform = openvdb::math::Transform::createLinearTransform(1.0);
    const openvdb::FloatGrid::Ptr unsignedGrid =
        openvdb::tools::meshToUnsignedDistanceField<openvdb::FloatGrid>(
            *transform, mesh.points, mesh.triangles, std::vector<openvdb::Vec4I>(), convertedBand);
    if (progress) progress(0.5);

    // OpenVDB's band expansion propagates the nearest triangle from neighbouring voxels, which is
    // not always the nearest one (errors up to half a texel away from the surface). Its value is
    // the distance to some triangle, though, so it bounds the exact search over nearby cells.
    std::vector<glm::dvec2> cellHeightRange(field.heightsTexels.size());
    for (int j = 0; j < field.height; ++j) {
        for (int i = 0; i < field.width; ++i) {
            const double a = field.node(i, j), b = field.node(i + 1, j);
            const double c = field.node(i, j + 1), d = field.node(i + 1, j + 1);
            cellHeightRange[std::size_t(i) + std::size_t(j) * std::size_t(field.width)] =
                glm::dvec2(std::min(std::min(a, b), std::min(c, d)),
                           std::max(std::max(a, b), std::max(c, d)));
        }
    }
    const openvdb::FloatTree& tree = unsignedGrid->tree();  // reads are thread-safe
    const auto distance = [&](const glm::dvec3& texel) {
        const openvdb::Coord voxel(int(std::floor(texel.x)), int(std::floor(texel.y)),
                                   int(std::floor(texel.z)));
        const double surfaceHeight = heightFieldSurfaceTexels(field, texel.x, texel.y);
        // Bounds: OpenVDB's value (plus float rounding), the vertical distance, the band.
        const double bound = std::min({double(tree.getValue(voxel)) + 1e-4,
                                       std::abs(texel.z - surfaceHeight), double(convertedBand)});
        const double unsignedDistance = distanceToSurface(field, cellHeightRange, texel, bound);
        return texel.z < surfaceHeight ? -unsignedDistance : unsignedDistance;
    };
    const ProgressCallback resampleProgress =
        progress ? ProgressCallback([&](double done) { progress(0.5 + 0.5 * done); })
                 : ProgressCallback();
    return LevelSet::fromDistance(distance, tile, halfBandTexels, source, params, resampleProgress);
}

}  // namespace distile
