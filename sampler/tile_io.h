/// @file
/// Tile files: the OpenEXR atlas distile reads and writes, and the PNG export for GPU shaders.
///
/// Layout (docs/tile_format.md): the D slices of a W x H x D tile are laid out as a 2D atlas of
/// cols = ceil(sqrt(D)) columns and rows = ceil(D / cols) rows; slice k sits at column k % cols,
/// row k / cols, so texel (x, y, k) is atlas pixel (k % cols * W + x, k / cols * H + y), x fastest,
/// pixel row 0 at the top. A 256x256x16 tile is a 4 x 4 atlas of 1024 x 1024 pixels. Atlas cells
/// past the last slice hold the tile's largest distance.
///
/// EXR files have one channel, "distance", in texel units, zip-compressed, and these string
/// header attributes: distile:size ("256x256x16"), distile:layout (the sentence above, short),
/// distile:units ("texels"), distile:source, distile:params (the tile's provenance),
/// distile:version ("0.1.0") and distile:hash (tileHash() as 16 lowercase hex digits). A file
/// without them is not a tile. A tile baked from a file also carries distile:source_file (the
/// provenance's sourceFile, relative to the tile file's folder when it can be, else absolute) and
/// distile:source_hash; tiles without them (procedural detail, older files) are read as before. EXR
/// cannot keep an empty attribute, so an empty source is written as "unknown" and empty params as
/// "{}" (and read back that way). Every file is written through writeAtomically().
#pragma once

#include <cstdint>
#include <filesystem>

#include "common/size3.h"
#include "sampler/tile.h"

namespace distile {

/// How an EXR tile stores its distances: 32-bit float (exact) or 16-bit half (rounded down:
/// relative error below 2^-10, never above the float value; |distance| at most 65504 texels).
enum class TileStorage { Float32, Half16 };

/// Columns and rows of the slice atlas of a tile `depthSlices` deep (see the file note).
struct AtlasGrid {
    int cols = 1;
    int rows = 1;
};
AtlasGrid atlasGrid(int depthSlices);

/// 64-bit FNV-1a over the tile size (width, height, depth as little-endian 32-bit integers) and
/// then every distance as its little-endian IEEE 754 float bits, in tile order (x fastest).
std::uint64_t tileHash(const Tile& tile);

/// The bits of the largest 16-bit half float at most `value` (rounded toward -infinity, where a
/// plain conversion rounds to nearest): distances stored as halves never exceed the float ones,
/// so a conservative tile stays conservative. Precondition: |value| <= 65504 or NaN.
std::uint16_t halfBitsAtMost(float value);

/// Writes `tile` as an OpenEXR atlas (see the file note). With Half16 the distances are rounded
/// down to half first and distile:hash is the hash of the rounded values, so the file verifies when
/// read back. Throws InputError if `file` does not end in .exr, if a distance is NaN or
/// infinite, if a distance does not fit in a half (Half16), or if the target's folder does not
/// exist; std::runtime_error if OpenEXR fails to write. Never leaves a partial file at `file`.
void writeTileExr(const Tile& tile, const std::filesystem::path& file,
                  TileStorage storage = TileStorage::Float32);

/// Reads a tile written by writeTileExr(), half or float, into float distances in texel units,
/// with its provenance (a recorded relative source file resolved from the tile file's folder).
/// Throws InputError if `file` does not exist or is not a regular file (a folder, a device);
/// FormatError if it is not an OpenEXR file OpenEXR can read, has no distile: attributes ("not
/// a distile tile"), does not have exactly one channel named "distance", has atlas dimensions that
/// disagree with distile:size, needs more than kInputMemoryBudgetBytes to read, holds NaN or
/// infinite distances, declares a band (distile:band_texels) that is not positive or beyond
/// 2 maxHalfBandTexels(size), holds distances outside the declared band (at least minus the band
/// minus the tile depth) or, without one, beyond +-2 maxHalfBandTexels(size), or fails the
/// distile:hash check.
Tile readTileExr(const std::filesystem::path& file);

/// Writes `tile` as a one-channel grey PNG atlas of `bitsPerChannel` 8 or 16 bits, for GPU
/// shaders; same layout as the EXR. As in GPU Gems 2 ch. 8, each distance is normalised by the
/// tile depth: value = clamp(distanceTexels / D, 0, 1) with D the tile depth in texels, stored as
/// the nearest code round(value * 255) or round(value * 65535). Negative distances (inside
/// material) clamp to 0, distances beyond D to 1. The distile: attributes go into PNG text chunks
/// (distile:units describes the normalisation; distile:hash is the float tile's tileHash()), and
/// the file is tagged as linear data (a PNG gAMA of 1.0), not sRGB. Throws InputError if
/// `bitsPerChannel` is not 8 or 16, if `file` does not end in .png, if a distance is NaN, or if
/// the target's folder does not exist.
void writeTilePng(const Tile& tile, const std::filesystem::path& file, int bitsPerChannel);

/// The half range R (texels) of writeSignedTilePng for `tile`: its largest |distance|, 1 for a
/// tile of zeros.
float signedPngRangeTexels(const Tile& tile);

/// Writes `tile` as a 16-bit grey PNG atlas that keeps the sign (same layout as the EXR):
/// value = 0.5 + distanceTexels / (2 R) with R = signedPngRangeTexels(tile), stored as the nearest
/// code round(value * 65535), so a reader gets distance = code / 65535 * 2 R - R back within half
/// a code step (R / 65535 texels); 0 texels is code 32768 (up to rounding), inside the material is
/// below. R is recorded as the text attribute distile:png_range_texels (and in distile:units);
/// the rest as writeTilePng. Throws InputError if `file` does not end in .png, if a distance is
/// not finite, or if the target's folder does not exist.
void writeSignedTilePng(const Tile& tile, const std::filesystem::path& file);

}  // namespace distile
