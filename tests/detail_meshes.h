/// @file
/// Closed test meshes with known geometry, shared by the mesh, vdb and truth tests.
#pragma once

#include <cmath>
#include <glm/vec3.hpp>
#include <numbers>

#include "common/triangle_soup.h"

namespace distile::test {

/// Axis-aligned box [lo, hi], 8 vertices, 12 triangles, counter-clockwise seen from outside.
inline TriangleSoup makeBoxSoup(const glm::dvec3& lo, const glm::dvec3& hi) {
    TriangleSoup soup;
    for (int corner = 0; corner < 8; ++corner) {
        soup.positions.emplace_back(corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y,
                                    corner & 4 ? hi.z : lo.z);
    }
    // Each face as a quad (a, b, c, d) counter-clockwise from outside.
    const unsigned quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                  {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : quads) {
        soup.triangles.emplace_back(q[0], q[1], q[2]);
        soup.triangles.emplace_back(q[0], q[2], q[3]);
    }
    return soup;
}

/// Torus around the z axis through `centre`, major radius R, minor radius r, vertices on the
/// analytic surface, segmentsMajor x segmentsMinor quads split in two triangles, outward facing.
inline TriangleSoup makeTorusSoup(const glm::dvec3& centre, double R, double r, int segmentsMajor,
                                  int segmentsMinor) {
    TriangleSoup soup;
    const double tau = 2.0 * std::numbers::pi;
    for (int i = 0; i < segmentsMajor; ++i) {
        const double theta = tau * i / segmentsMajor;
        for (int j = 0; j < segmentsMinor; ++j) {
            const double psi = tau * j / segmentsMinor;
            const double ring = R + r * std::cos(psi);
            soup.positions.push_back(centre + glm::dvec3(ring * std::cos(theta),
                                                         ring * std::sin(theta),
                                                         r * std::sin(psi)));
        }
    }
    const auto index = [&](int i, int j) {
        return unsigned((i % segmentsMajor) * segmentsMinor + (j % segmentsMinor));
    };
    for (int i = 0; i < segmentsMajor; ++i) {
        for (int j = 0; j < segmentsMinor; ++j) {
            soup.triangles.emplace_back(index(i, j), index(i + 1, j), index(i + 1, j + 1));
            soup.triangles.emplace_back(index(i, j), index(i + 1, j + 1), index(i, j + 1));
        }
    }
    return soup;
}

/// Largest distance between the tessellated torus and the analytic one: the chord sagitta of
/// the outer equator plus that of the tube's cross-section.
inline double torusTessellationError(double R, double r, int segmentsMajor, int segmentsMinor) {
    return (R + r) * (1.0 - std::cos(std::numbers::pi / segmentsMajor)) +
           r * (1.0 - std::cos(std::numbers::pi / segmentsMinor));
}

}  // namespace distile::test
