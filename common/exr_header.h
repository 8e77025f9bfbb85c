/// @file
/// The header of an OpenEXR file, walked before OpenImageIO and OpenEXR open it: OpenEXR
/// allocates what a damaged attribute, data window or tile size declares (gigabytes from a few
/// bytes), so every size the header declares is checked against the file's size and the memory
/// budget first.
#pragma once

#include <filesystem>

namespace distile {

/// Throws FormatError if `file` starts with OpenEXR's magic number and its header is broken or
/// declares more than the file or kInputMemoryBudgetBytes holds: the version field and its flags,
/// every attribute's name, type and size (printable names of at most 31 characters, or 255 with
/// the long-names flag; attributes of fixed-size types of exactly that size), the channel list,
/// the data window, the compression, the tile description, the chunk count and the offset
/// table, and each chunk's declared data size. Multi-part and deep files are refused (distile
/// reads single-part flat images only). Other files pass unchecked.
void checkExrHeader(const std::filesystem::path& file);

/// True when `file` starts with OpenEXR's magic number.
bool startsAsExr(const std::filesystem::path& file);

}  // namespace distile
