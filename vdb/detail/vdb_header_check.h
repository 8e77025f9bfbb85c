/// @file
/// The header of a .vdb file, walked before OpenVDB reads it: OpenVDB allocates whatever a
/// length or count field says (a flipped byte asks for gigabytes) and follows grid offsets past
/// the end of the file, so every such field is checked against the file's size first.
#pragma once

#include <cstdint>
#include <filesystem>

namespace distile::detail {

/// Walks the file header, the file's metadata, the grid descriptors and each grid's metadata
/// (the parts OpenVDB reads to list grids), checking that every string, metadata value, count
/// and grid offset fits in the file's `fileBytes`. Throws FormatError naming the field and the
/// byte offset otherwise, or when the file does not start with OpenVDB's magic number.
void checkVdbHeader(const std::filesystem::path& file, std::uint64_t fileBytes);

}  // namespace distile::detail
