/// @file
/// Closed test meshes with known geometry, shared by the mesh, vdb and truth tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <map>
#include <numbers>
#include <utility>
#include <vector>

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

/// Icosphere: an icosahedron whose faces are split `subdivisions` times into four, vertices
/// projected onto the sphere of `radius` around `centre`, outward facing. Corners shared.
inline TriangleSoup makeIcosphereSoup(const glm::dvec3& centre, double radius, int subdivisions) {
    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    std::vector<glm::dvec3> unit = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                    {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                    {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    for (glm::dvec3& p : unit) p /= std::sqrt(1.0 + t * t);
    std::vector<glm::uvec3> faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                     {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                     {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                     {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    for (int level = 0; level < subdivisions; ++level) {
        std::map<std::pair<unsigned, unsigned>, unsigned> midpoints;
        const auto midpoint = [&](unsigned a, unsigned b) {
            const auto key = std::minmax(a, b);
            const auto [entry, isNew] = midpoints.try_emplace({key.first, key.second}, 0u);
            if (isNew) {
                entry->second = unsigned(unit.size());
                const glm::dvec3 m = 0.5 * (unit[a] + unit[b]);
                unit.push_back(m / std::sqrt(m.x * m.x + m.y * m.y + m.z * m.z));
            }
            return entry->second;
        };
        std::vector<glm::uvec3> finer;
        for (const glm::uvec3& f : faces) {
            const unsigned ab = midpoint(f.x, f.y), bc = midpoint(f.y, f.z),
                           ca = midpoint(f.z, f.x);
            finer.insert(finer.end(), {{f.x, ab, ca}, {f.y, bc, ab}, {f.z, ca, bc}, {ab, bc, ca}});
        }
        faces = std::move(finer);
    }
    TriangleSoup soup;
    for (const glm::dvec3& p : unit) soup.positions.push_back(centre + radius * p);
    soup.triangles = std::move(faces);
    return soup;
}

/// Largest distance between a mesh inscribed in the sphere (vertices on it) and the sphere: the
/// radius minus the nearest face plane's distance from the centre.
inline double inscribedTessellationError(const TriangleSoup& soup, const glm::dvec3& centre,
                                         double radius) {
    double nearestPlane = radius;
    for (const glm::uvec3& f : soup.triangles) {
        const glm::dvec3 a = soup.positions[f.x], b = soup.positions[f.y], c = soup.positions[f.z];
        const glm::dvec3 n = glm::cross(b - a, c - a);
        nearestPlane =
            std::min(nearestPlane, std::abs(glm::dot(a - centre, n)) / std::sqrt(glm::dot(n, n)));
    }
    return radius - nearestPlane;
}

}  // namespace distile::test
