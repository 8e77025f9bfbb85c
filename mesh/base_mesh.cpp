// Tangent frames and the built-in base meshes (plane, UV sphere, torus).
#include "mesh/base_mesh.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <numbers>
#include <numeric>
#include <string>

#include "common/error.h"
#include "common/position_weld.h"

namespace distile {
namespace {

/// A triangle is degenerate (in 3D or in UV space) when |e1 x e2| <= kDegenerateSine |e1| |e2|,
/// i.e. the sine of its angle at the first corner is this small or an edge has zero length.
constexpr double kDegenerateSine = 1e-7;
/// Two uvs whose difference is this close to a whole-number vector are the same texture point.
constexpr double kWholeUvTolerance = 1e-5;
/// Coincident-vertex groups up to this size are searched pairwise for tangent welding.
constexpr std::uint32_t kMaxWeldGroup = 64;
/// A summed direction shorter than this fraction of the summed weights has cancelled out.
constexpr double kCancelledFraction = 1e-6;

bool isFinite(const glm::vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
bool isFinite(const glm::vec2& v) {
    return std::isfinite(v.x) && std::isfinite(v.y);
}

void validateForFrames(const BaseMesh& mesh) {
    const std::size_t vertexCount = mesh.positions.size();
    if (mesh.uvs.size() != vertexCount) {
        throw InputError("computeTangentFrames: mesh has " + std::to_string(vertexCount) +
                         " positions but " + std::to_string(mesh.uvs.size()) +
                         " uvs; needs exactly one uv per position");
    }
    for (std::size_t v = 0; v < vertexCount; ++v) {
        if (!isFinite(mesh.positions[v]) || !isFinite(mesh.uvs[v])) {
            throw InputError("computeTangentFrames: vertex " + std::to_string(v) +
                             " has a NaN/Inf position or uv; needs finite values");
        }
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        for (int corner = 0; corner < 3; ++corner) {
            if (mesh.triangles[t][corner] >= vertexCount) {
                throw InputError("computeTangentFrames: triangle " + std::to_string(t) +
                                 " refers to vertex " + std::to_string(mesh.triangles[t][corner]) +
                                 "; indices must be below the vertex count " +
                                 std::to_string(vertexCount));
            }
        }
    }
}

/// For each vertex, the vertex whose tangent sums it shares: the first vertex (in index order)
/// welded at the same position and a uv that differs by a whole-number vector (within
/// kWholeUvTolerance), e.g. the u = 0 and u = 1 copies on a sphere's seam. Across such a seam
/// the texture continues unchanged (tiles repeat every whole uv), so the parametrisation and
/// its dP/du, dP/dv are continuous there and both copies must get the same tangent. Groups of
/// more than kMaxWeldGroup coincident vertices (pathological input) are left unwelded, and so
/// are the two sides of a mirror line (different uv handedness, see splitMirroredVertices).
std::vector<std::uint32_t> tangentWeldTargets(const std::vector<std::uint32_t>& groupOf,
                                              const std::vector<glm::vec2>& uvs,
                                              const std::vector<std::int8_t>& uvSides) {
    const std::size_t vertexCount = groupOf.size();
    std::vector<std::uint32_t> target(vertexCount);
    std::iota(target.begin(), target.end(), 0u);
    if (vertexCount == 0) return target;
    // Members of each group, contiguous and in index order (counting sort by group).
    const std::size_t groupCount = *std::max_element(groupOf.begin(), groupOf.end()) + 1;
    std::vector<std::uint32_t> groupStart(groupCount + 1, 0);
    for (std::uint32_t group : groupOf) ++groupStart[group + 1];
    for (std::size_t g = 0; g < groupCount; ++g) groupStart[g + 1] += groupStart[g];
    std::vector<std::uint32_t> members(vertexCount);
    std::vector<std::uint32_t> fill(groupStart.begin(), groupStart.end() - 1);
    for (std::uint32_t v = 0; v < vertexCount; ++v) members[fill[groupOf[v]]++] = v;

    auto wholeOffset = [&](std::uint32_t a, std::uint32_t b) {
        const glm::dvec2 offset = glm::dvec2(uvs[a]) - glm::dvec2(uvs[b]);
        return uvSides[a] == uvSides[b] &&
               std::abs(offset.x - std::round(offset.x)) <= kWholeUvTolerance &&
               std::abs(offset.y - std::round(offset.y)) <= kWholeUvTolerance;
    };
    for (std::size_t g = 0; g < groupCount; ++g) {
        const std::uint32_t begin = groupStart[g];
        const std::uint32_t end = groupStart[g + 1];
        if (end - begin < 2 || end - begin > kMaxWeldGroup) continue;
        for (std::uint32_t k = begin + 1; k < end; ++k) {
            for (std::uint32_t first = begin; first < k; ++first) {
                if (wholeOffset(members[k], members[first])) {
                    target[members[k]] = target[members[first]];
                    break;
                }
            }
        }
    }
    return target;
}

/// Unit direction of `sum` if it has not cancelled relative to `weight`, else nothing.
bool normalizeIfClear(const glm::dvec3& sum, double weight, glm::dvec3& unit) {
    const double length = glm::length(sum);
    if (!(weight > 0.0) || !(length > kCancelledFraction * weight)) return false;
    unit = sum / length;
    return true;
}

/// Deterministic unit vector orthogonal to the unit vector n: the coordinate axis least aligned
/// with n (lowest index on ties), with its n component removed.
glm::dvec3 anyOrthogonal(const glm::dvec3& n) {
    int axis = 0;
    for (int i = 1; i < 3; ++i) {
        if (std::abs(n[i]) < std::abs(n[axis])) axis = i;
    }
    glm::dvec3 a(0.0);
    a[axis] = 1.0;
    return glm::normalize(a - n * glm::dot(n, a));
}

/// Angle at corner `at` of a triangle whose other corners are `b` and `c`, in radians.
double cornerAngle(const glm::dvec3& at, const glm::dvec3& b, const glm::dvec3& c) {
    const glm::dvec3 e1 = b - at;
    const glm::dvec3 e2 = c - at;
    return std::atan2(glm::length(glm::cross(e1, e2)), glm::dot(e1, e2));
}

void validateSegments(const char* function, const char* name, int value, int minimum) {
    if (value < minimum || value > kMaxSegments) {
        throw InputError(std::string(function) + ": " + name + " = " + std::to_string(value) +
                         "; accepted: " + std::to_string(minimum) + " to " +
                         std::to_string(kMaxSegments));
    }
}

void validateLength(const char* function, const char* name, float value) {
    if (!std::isfinite(value) || !(value > 0.0f)) {
        throw InputError(std::string(function) + ": " + name + " = " + numberText(value) +
                         "; accepted: a finite number > 0");
    }
}

/// Appends a (columns + 1) x (rows + 1) vertex grid, vertex (i, j) at index
/// first + j * (columns + 1) + i, and two counter-clockwise triangles per cell, assuming the
/// surface's outward normal is along cross(d/di, d/dj).
template <typename PositionAt, typename UvAt>
void appendGrid(BaseMesh& mesh, int columns, int rows, PositionAt positionAt, UvAt uvAt) {
    const auto first = static_cast<std::uint32_t>(mesh.positions.size());
    for (int j = 0; j <= rows; ++j) {
        for (int i = 0; i <= columns; ++i) {
            mesh.positions.push_back(positionAt(i, j));
            mesh.uvs.push_back(uvAt(i, j));
        }
    }
    const auto stride = static_cast<std::uint32_t>(columns + 1);
    for (std::uint32_t j = 0; j < static_cast<std::uint32_t>(rows); ++j) {
        for (std::uint32_t i = 0; i < static_cast<std::uint32_t>(columns); ++i) {
            const std::uint32_t a = first + j * stride + i;
            const std::uint32_t b = a + 1;
            const std::uint32_t c = b + stride;
            const std::uint32_t d = a + stride;
            mesh.triangles.emplace_back(a, b, c);
            mesh.triangles.emplace_back(a, c, d);
        }
    }
}

/// Mirrored UV layouts share vertices between triangles whose uv mapping has opposite
/// handedness (the mirror line): no single tangent frame serves both sides, and averaging their
/// tangents cancels them. As MikkTSpace does, such a vertex is split: the triangles of negative
/// uv handedness get their own copy (same position and uv), so each side gets its own frame.
/// Returns, per vertex after the split, which handedness uses it: bit 0 positive, bit 1 negative.
std::vector<std::int8_t> splitMirroredVertices(BaseMesh& mesh) {
    const std::size_t vertexCount = mesh.positions.size();
    std::vector<std::int8_t> sides(vertexCount,
                                   0);  // bit 0: a positive triangle uses it, bit 1: negative
    std::vector<int> handedness(mesh.triangles.size(), 0);
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        const glm::uvec3& triangle = mesh.triangles[t];
        const glm::dvec2 d1 = glm::dvec2(mesh.uvs[triangle[1]]) - glm::dvec2(mesh.uvs[triangle[0]]);
        const glm::dvec2 d2 = glm::dvec2(mesh.uvs[triangle[2]]) - glm::dvec2(mesh.uvs[triangle[0]]);
        const double uvDeterminant = d1.x * d2.y - d2.x * d1.y;
        if (!(std::abs(uvDeterminant) > kDegenerateSine * glm::length(d1) * glm::length(d2)))
            continue;
        handedness[t] = uvDeterminant > 0.0 ? 1 : -1;
        for (int corner = 0; corner < 3; ++corner)
            sides[triangle[corner]] |= handedness[t] > 0 ? 1 : 2;
    }
    std::vector<std::uint32_t> copyOf(vertexCount, 0);
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        if (handedness[t] >= 0) continue;
        for (int corner = 0; corner < 3; ++corner) {
            const std::uint32_t v = mesh.triangles[t][corner];
            if (sides[v] != 3) continue;
            if (copyOf[v] == 0) {
                copyOf[v] = std::uint32_t(mesh.positions.size());
                mesh.positions.push_back(mesh.positions[v]);
                mesh.uvs.push_back(mesh.uvs[v]);
                sides.push_back(2);
            }
            mesh.triangles[t][corner] = copyOf[v];
        }
    }
    for (std::size_t v = 0; v < vertexCount; ++v) {
        if (sides[v] == 3) sides[v] = 1;
    }
    return sides;
}

}  // namespace

void computeTangentFrames(BaseMesh& mesh) {
    validateForFrames(mesh);
    const std::vector<std::int8_t> uvSides = splitMirroredVertices(mesh);
    const std::size_t vertexCount = mesh.positions.size();
    auto position = [&](std::uint32_t v) { return glm::dvec3(mesh.positions[v]); };
    auto uv = [&](std::uint32_t v) { return glm::dvec2(mesh.uvs[v]); };

    // Normals: the length of cross(e1, e2) is twice the area, so summing it area-weights.
    const std::vector<std::uint32_t> groupOf = weldedPositionGroups(mesh.positions, mesh.triangles);
    const std::size_t groupCount =
        vertexCount == 0 ? 0 : *std::max_element(groupOf.begin(), groupOf.end()) + 1;
    std::vector<glm::dvec3> groupSum(groupCount, glm::dvec3(0.0));
    std::vector<double> groupWeight(groupCount, 0.0);
    std::vector<glm::dvec3> vertexSum(vertexCount, glm::dvec3(0.0));
    std::vector<double> vertexWeight(vertexCount, 0.0);
    for (const glm::uvec3& triangle : mesh.triangles) {
        const glm::dvec3 p0 = position(triangle[0]);
        const glm::dvec3 faceNormal =
            glm::cross(position(triangle[1]) - p0, position(triangle[2]) - p0);
        const double faceWeight = glm::length(faceNormal);
        for (int corner = 0; corner < 3; ++corner) {
            const std::uint32_t v = triangle[corner];
            groupSum[groupOf[v]] += faceNormal;
            groupWeight[groupOf[v]] += faceWeight;
            vertexSum[v] += faceNormal;
            vertexWeight[v] += faceWeight;
        }
    }
    std::vector<glm::dvec3> normals(vertexCount);
    for (std::size_t v = 0; v < vertexCount; ++v) {
        if (!normalizeIfClear(groupSum[groupOf[v]], groupWeight[groupOf[v]], normals[v]) &&
            !normalizeIfClear(vertexSum[v], vertexWeight[v], normals[v])) {
            normals[v] = glm::dvec3(0.0, 0.0, 1.0);
        }
    }

    // Tangents: per triangle, solve [e1 e2] = [dP/du dP/dv] * [duv1 duv2] for dP/du, dP/dv.
    std::vector<glm::dvec3> tangentSum(vertexCount, glm::dvec3(0.0));
    std::vector<glm::dvec3> bitangentSum(vertexCount, glm::dvec3(0.0));
    std::vector<double> tangentWeight(vertexCount, 0.0);
    for (const glm::uvec3& triangle : mesh.triangles) {
        const glm::dvec3 p[3] = {position(triangle[0]), position(triangle[1]),
                                 position(triangle[2])};
        const glm::dvec2 t[3] = {uv(triangle[0]), uv(triangle[1]), uv(triangle[2])};
        const glm::dvec3 e1 = p[1] - p[0];
        const glm::dvec3 e2 = p[2] - p[0];
        const glm::dvec2 d1 = t[1] - t[0];
        const glm::dvec2 d2 = t[2] - t[0];
        const double uvDeterminant = d1.x * d2.y - d2.x * d1.y;
        const bool degenerate3d = !(glm::length(glm::cross(e1, e2)) >
                                    kDegenerateSine * glm::length(e1) * glm::length(e2));
        const bool degenerateUv =
            !(std::abs(uvDeterminant) > kDegenerateSine * glm::length(d1) * glm::length(d2));
        if (degenerate3d || degenerateUv) continue;
        const glm::dvec3 dPdu = (e1 * d2.y - e2 * d1.y) / uvDeterminant;
        const glm::dvec3 dPdv = (e2 * d1.x - e1 * d2.x) / uvDeterminant;
        const glm::dvec3 dPdvUnit = glm::normalize(dPdv);
        for (int corner = 0; corner < 3; ++corner) {
            const std::uint32_t v = triangle[corner];
            const glm::dvec3& n = normals[v];
            const glm::dvec3 inPlane = dPdu - n * glm::dot(n, dPdu);
            const double inPlaneLength = glm::length(inPlane);
            if (!(inPlaneLength > kCancelledFraction * glm::length(dPdu))) continue;
            const double angle = cornerAngle(p[corner], p[(corner + 1) % 3], p[(corner + 2) % 3]);
            tangentSum[v] += angle * (inPlane / inPlaneLength);
            bitangentSum[v] += angle * dPdvUnit;
            tangentWeight[v] += angle;
        }
    }

    // Seam copies of one texture point pool their sums (see tangentWeldTargets).
    const std::vector<std::uint32_t> weldTarget = tangentWeldTargets(groupOf, mesh.uvs, uvSides);
    for (std::size_t v = 0; v < vertexCount; ++v) {
        const std::uint32_t target = weldTarget[v];
        if (target == v) continue;
        tangentSum[target] += tangentSum[v];
        bitangentSum[target] += bitangentSum[v];
        tangentWeight[target] += tangentWeight[v];
    }
    for (std::size_t v = 0; v < vertexCount; ++v) {
        const std::uint32_t target = weldTarget[v];
        tangentSum[v] = tangentSum[target];
        bitangentSum[v] = bitangentSum[target];
        tangentWeight[v] = tangentWeight[target];
    }

    mesh.normals.resize(vertexCount);
    mesh.tangents.resize(vertexCount);
    for (std::size_t v = 0; v < vertexCount; ++v) {
        const glm::dvec3& n = normals[v];
        const glm::dvec3 inPlane = tangentSum[v] - n * glm::dot(n, tangentSum[v]);
        glm::dvec3 tangent;
        double handedness = 1.0;
        if (normalizeIfClear(inPlane, tangentWeight[v], tangent)) {
            handedness = glm::dot(glm::cross(n, tangent), bitangentSum[v]) < 0.0 ? -1.0 : 1.0;
        } else {
            tangent = anyOrthogonal(n);
        }
        mesh.normals[v] = glm::vec3(n);
        mesh.tangents[v] = glm::vec4(glm::vec3(tangent), static_cast<float>(handedness));
    }
}

std::size_t removeTrianglesWithoutArea(BaseMesh& mesh) {
    if (mesh.positions.empty()) return 0;
    const double tolerance = weldDistanceWorld(mesh.positions, mesh.triangles);
    const std::size_t before = mesh.triangles.size();
    std::erase_if(mesh.triangles, [&](const glm::uvec3& triangle) {
        const glm::dvec3 p0(mesh.positions[triangle[0]]), p1(mesh.positions[triangle[1]]),
            p2(mesh.positions[triangle[2]]);
        const double longestEdge =
            std::max({glm::distance(p0, p1), glm::distance(p1, p2), glm::distance(p2, p0)});
        // Twice the area over the longest edge: the height above it.
        return glm::length(glm::cross(p1 - p0, p2 - p0)) <= tolerance * longestEdge;
    });
    return before - mesh.triangles.size();
}

BaseMesh makePlane(float sizeWorld, int segments) {
    validateLength("makePlane", "sizeWorld", sizeWorld);
    validateSegments("makePlane", "segments", segments, 1);
    BaseMesh mesh;
    const double step = 1.0 / segments;
    appendGrid(
        mesh, segments, segments,
        [&](int i, int j) {
            return glm::vec3(
                glm::dvec3((i * step - 0.5) * sizeWorld, (j * step - 0.5) * sizeWorld, 0.0));
        },
        [&](int i, int j) { return glm::vec2(glm::dvec2(i * step, j * step)); });
    computeTangentFrames(mesh);
    return mesh;
}

BaseMesh makeUvSphere(float radiusWorld, int segmentsAround, int ringsAlong) {
    validateLength("makeUvSphere", "radiusWorld", radiusWorld);
    validateSegments("makeUvSphere", "segmentsAround", segmentsAround, 3);
    validateSegments("makeUvSphere", "ringsAlong", ringsAlong, 2);
    constexpr double pi = std::numbers::pi;
    const double r = radiusWorld;
    // Column i % segmentsAround keeps the seam duplicates at bit-identical positions.
    auto ringPoint = [&](int i, int ring) {
        const double phi = 2.0 * pi * (i % segmentsAround) / segmentsAround;
        const double polar = pi * ring / ringsAlong;
        return glm::vec3(glm::dvec3(r * std::sin(polar) * std::cos(phi),
                                    r * std::sin(polar) * std::sin(phi), -r * std::cos(polar)));
    };
    auto ringUv = [&](int i, int ring) {
        return glm::vec2(glm::dvec2(static_cast<double>(i) / segmentsAround,
                                    static_cast<double>(ring) / ringsAlong));
    };

    BaseMesh mesh;
    // Vertex rings 1 .. ringsAlong - 1 as a grid; grid row j is ring j + 1.
    appendGrid(
        mesh, segmentsAround, ringsAlong - 2, [&](int i, int j) { return ringPoint(i, j + 1); },
        [&](int i, int j) { return ringUv(i, j + 1); });
    const auto stride = static_cast<std::uint32_t>(segmentsAround + 1);
    const std::uint32_t lowestRing = 0;
    const std::uint32_t highestRing = static_cast<std::uint32_t>(ringsAlong - 2) * stride;
    // Pole fans: one pole vertex per column, at the column's centre u.
    for (int i = 0; i < segmentsAround; ++i) {
        const float u = static_cast<float>((i + 0.5) / segmentsAround);
        const auto south = static_cast<std::uint32_t>(mesh.positions.size());
        mesh.positions.emplace_back(0.0f, 0.0f, -radiusWorld);
        mesh.uvs.emplace_back(u, 0.0f);
        const auto north = south + 1;
        mesh.positions.emplace_back(0.0f, 0.0f, radiusWorld);
        mesh.uvs.emplace_back(u, 1.0f);
        const auto column = static_cast<std::uint32_t>(i);
        mesh.triangles.emplace_back(south, lowestRing + column + 1, lowestRing + column);
        mesh.triangles.emplace_back(highestRing + column, highestRing + column + 1, north);
    }
    computeTangentFrames(mesh);
    return mesh;
}

BaseMesh makeTorus(float majorRadiusWorld, float minorRadiusWorld, int segmentsMajor,
                   int segmentsMinor) {
    validateLength("makeTorus", "majorRadiusWorld", majorRadiusWorld);
    validateLength("makeTorus", "minorRadiusWorld", minorRadiusWorld);
    if (!(minorRadiusWorld < majorRadiusWorld)) {
        throw InputError("makeTorus: minorRadiusWorld = " + numberText(minorRadiusWorld) +
                         " with majorRadiusWorld = " + numberText(majorRadiusWorld) +
                         "; accepted: minor radius < major radius");
    }
    validateSegments("makeTorus", "segmentsMajor", segmentsMajor, 3);
    validateSegments("makeTorus", "segmentsMinor", segmentsMinor, 3);
    constexpr double pi = std::numbers::pi;
    const double major = majorRadiusWorld;
    const double minor = minorRadiusWorld;
    BaseMesh mesh;
    // i runs along θ (u), j along ψ (v); cross(dP/dθ, dP/dψ) points outward, as appendGrid
    // assumes. Indices modulo the segment counts keep seam duplicates bit-identical.
    appendGrid(
        mesh, segmentsMajor, segmentsMinor,
        [&](int i, int j) {
            const double theta = 2.0 * pi * (i % segmentsMajor) / segmentsMajor;
            const double psi = 2.0 * pi * (j % segmentsMinor) / segmentsMinor;
            const double ring = major + minor * std::cos(psi);
            return glm::vec3(
                glm::dvec3(ring * std::cos(theta), ring * std::sin(theta), minor * std::sin(psi)));
        },
        [&](int i, int j) {
            return glm::vec2(glm::dvec2(static_cast<double>(i) / segmentsMajor,
                                        static_cast<double>(j) / segmentsMinor));
        });
    computeTangentFrames(mesh);
    return mesh;
}

}  // namespace distile
