/// @file
/// OpenEXR files written with OpenEXR itself (common/image_files.cpp, sampler/tile_io.cpp): a
/// render's image, its depth and texel-scale AOVs or a tile's atlas need none of OpenImageIO's
/// plugins, so writing one does not load them.
#pragma once

#include <filesystem>
#include <string>

#include "common/image_files.h"

namespace distile::image_files::detail {

/// Writes `pixels` as image_files::write does, to a scanline OpenEXR file: spec.channels
/// channels named spec.channelNames (or, without names, Y for one channel and R, G, B, A for
/// three or four), stored as spec.pixelType Half or Float, given as Float. As OpenImageIO's
/// writer does: the attribute "compression" names the compression (none, rle, zips, zip, piz,
/// pxr24, b44, b44a, dwaa or dwab; zip without it), attributes named "oiio:..." are hints and
/// not stored, and every other string, integer and float attribute is stored under its name.
/// Compresses on OpenEXR's threads (useExrThreads). Returns "" or what went wrong.
std::string writeExr(const std::filesystem::path& file, const Spec& spec, PixelType given,
                     const void* pixels);

/// OpenEXR compresses and decompresses a file's chunks on its own pool of threads, none unless
/// told: as many as TBB may use at the first call (the --threads limit). The bytes and pixels
/// do not depend on it.
void useExrThreads();

}  // namespace distile::image_files::detail
