/// @file
/// PNG files written with libpng itself (common/image_files.cpp): a render's image, a tile's PNG
/// atlas or a contact sheet needs none of OpenImageIO's plugins, so writing one does not load them.
#pragma once

#include <filesystem>
#include <string>

#include "common/image_files.h"

namespace distile::image_files::detail {

/// Writes `pixels` as image_files::write does, to a PNG: 1 to 4 channels (grey, grey and alpha,
/// RGB, RGBA), stored as spec.pixelType UInt8 or UInt16, given as UInt8, UInt16 or Float (floats
/// clamped to [0, 1] and rounded to the nearest code). The chunks follow OpenImageIO's PNG writer,
/// so either library reads the file back alike: "oiio:ColorSpace" sRGB writes the sRGB chunk
/// (with its gAMA and cHRM), Linear a gAMA of 1; every string attribute is a tEXt chunk of its
/// name; "png:compressionLevel" (zlib's 0-9, default 6) and "png:filter" (libpng's PNG_FILTER_*
/// flags, default all five) set the compression; other integer and float attributes are not
/// stored. Without row filters (png:filter PNG_FILTER_NONE) the rows are deflated by zlib in
/// bands of 32 rows in parallel, each primed with the 32 KB before it: the same bytes on any
/// number of threads. Returns "" or what went wrong.
std::string writePng(const std::filesystem::path& file, const Spec& spec, PixelType given,
                     const void* pixels);

}  // namespace distile::image_files::detail
