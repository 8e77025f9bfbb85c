/// @file
/// Detail meshes: closed triangle meshes (chain links, rivets, any solid) that are baked into
/// distance tiles. Only positions and faces matter; no UVs are needed.
#pragma once

#include <filesystem>

#include "common/triangle_soup.h"

namespace distile {

/// Largest coordinate magnitude loadDetailMesh accepts, in file units. Beyond it squared
/// lengths overflow OpenMesh's float arithmetic (1e30 squared is not a float) and a placement
/// into a tile of at most 65536 texels cannot keep the mesh's shape in float.
inline constexpr double kMaxDetailCoordinate = 1e9;

/// Reads a detail mesh through OpenMesh: `.obj`, `.ply` (ASCII or binary), `.off`, `.stl`
/// (ASCII or binary); the extension picks the reader, case-insensitively. Polygons are
/// split into triangles by triangulatePolygon (mesh/polygon.h: convex ones as the fan from their
/// first corner, concave ones by ear clipping in their plane). Positions are returned in file units. Corners at
/// identical positions are welded into one vertex in every format (a soup of unwelded corners
/// loads as the same mesh from OBJ, PLY, OFF and STL); triangles whose corners merged (no
/// area) are dropped.
/// Checked before OpenMesh reads the file (it crashes or silently drops data otherwise): OBJ
/// lines (finite numbers, in-range face indices, as loadBaseMesh does); binary STL size
/// (exactly 84 + 50 x the triangle count in its header); PLY data against its header (enough
/// bytes, or enough lines for ASCII, for the counts the header promises).
/// Thread-safety as loadBaseMesh (reads are serialised).
/// @throws InputError  the file does not exist, is not a regular file or cannot be opened.
/// @throws FormatError the extension is not one of the above, the file is truncated or
///                     corrupted, the counts a header declares do not fit in the file or in
///                     kInputMemoryBudgetBytes, a PLY/OFF value is not a number within its
///                     type's range, OpenMesh cannot read it, the mesh has no faces, a face refers
///                     to a missing vertex, a coordinate is NaN/Inf or beyond
///                     +-kMaxDetailCoordinate.
TriangleSoup loadDetailMesh(const std::filesystem::path& file);

}  // namespace distile
