/// @file
/// Which vertices of a mesh are one point of its surface: the copies along a uv seam, also where
/// a script or exporter wrote them with rounding noise (sin(2 pi) is not 0). Shared by the base
/// mesh's normals (mesh/), the shell's neighbour links (render/) and the world reference's open
/// borders (vdb/), so all three see the same surface.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

namespace distile {

/// Vertices closer than this fraction of the mesh's median edge length weld into one point: far
/// below any edge a mesh means to have, far above the rounding of its positions. The median,
/// not the mesh's extent, so one stray face far away changes nothing.
inline constexpr double kWeldFraction = 1e-3;

/// kWeldFraction times the median length of the triangles' edges (the positions' units); 0
/// without triangles.
double weldDistanceWorld(std::span<const glm::vec3> positions,
                         std::span<const glm::uvec3> triangles);

/// Per vertex, the lowest index of the vertices welded with it: whose positions lie within
/// weldDistanceWorld of each other, directly or through a chain of such vertices (equal positions
/// only, where that is 0). Ids are near their vertices' own indices. The same for any thread
/// count. Preconditions: finite positions.
std::vector<std::uint32_t> weldedPositionGroups(std::span<const glm::vec3> positions,
                                                std::span<const glm::uvec3> triangles);

}  // namespace distile
