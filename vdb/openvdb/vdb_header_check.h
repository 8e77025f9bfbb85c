/// @file
/// A .vdb file walked before OpenVDB reads it: OpenVDB allocates whatever a length, count or
/// compressed chunk size says (a flipped byte asks for gigabytes) and follows grid offsets past
/// the end of the file, so every such field is checked against the file's size and the memory
/// budget first.
#pragma once

#include <cstdint>
#include <filesystem>

namespace distile::detail {

/// Walks the file header, the file's metadata, the grid descriptors, each grid's metadata and
/// transform (the parts OpenVDB reads to list grids) and, for float grids (the only ones distile
/// reads voxels of), the tree: its nodes, and each blosc or zip chunk's declared size. Checks that
/// every string, metadata value, count, offset and chunk fits in the file's `fileBytes` and
/// agrees with what OpenVDB will read, and that the trees fit in kInputMemoryBudgetBytes.
/// Accepts file format versions 222 to 224 (OpenVDB 2 and later). Throws FormatError naming the
/// field and its byte offset otherwise, or when the file does not start with OpenVDB's magic
/// number.
void checkVdbHeader(const std::filesystem::path& file, std::uint64_t fileBytes);

}  // namespace distile::detail
