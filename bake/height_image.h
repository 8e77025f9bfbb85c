/// @file
/// Height maps from image files (OpenImageIO): 8/16-bit PNG or EXR, read as float grey, and
/// their sampling onto a tile's texel columns (vdb/height_field.h).
#pragma once

#include <filesystem>
#include <vector>

#include "common/size3.h"
#include "vdb/height_field.h"

namespace distile {

/// A grey image, values in [0, 1]; pixel (column c, row r) at values[c + r * width]. Row 0 is the
/// file's first row and maps to y = 0 of the tile, as in the tile atlas.
struct HeightImage {
    int width = 0;
    int height = 0;
    std::vector<float> values;
};

/// Largest pixel count readHeightImage accepts (2^28: 1 GiB of floats).
inline constexpr long long kMaxHeightImagePixels = 1ll << 28;

/// Reads `file` as float grey: one or two channels (grey, grey + alpha) give the first channel,
/// three or more the Rec. 709 luminance of the first three. 8- and 16-bit files are normalised to
/// [0, 1] by OpenImageIO; float (EXR) values must already be in [0, 1].
/// @throws InputError  the file does not exist or is not a regular file (a folder, a device).
/// @throws FormatError OpenImageIO cannot read it (empty, truncated, corrupted, not an image, a
///                     broken PNG), it has no pixels or more than kMaxHeightImagePixels, reading
///                     it needs more than kInputMemoryBudgetBytes, or a value is NaN/Inf or
///                     outside [0, 1] (naming the pixel).
HeightImage readHeightImage(const std::filesystem::path& file);

/// The image sampled periodically and bilinearly at the centres of the tile's texel columns:
/// node (i, j) takes the image at (u, v) = ((i + 0.5) / W, (j + 0.5) / H) of its area (pixel
/// centres at (c + 0.5) / width), times heightTexels. Any image size works.
/// @throws InputError the tile size is invalid, heightTexels is not finite and in (0, D], or the
///                    image is empty or inconsistent.
HeightField heightFieldFromImage(const HeightImage& image, const Size3& tile, double heightTexels);

}  // namespace distile
