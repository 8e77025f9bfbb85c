/// @file
/// Pictures of a tile: its slices side by side as a contact sheet, coloured by a diverging map
/// (inside blue, outside red, white at 0), with the zero contour in black, a label per slice
/// (its texel-centre z) and a colour bar in texels. `distile preview` draws a tile's distances
/// with it, `distile check --plot` the error of a tile against its truth.
///
/// Each slice is drawn with y up: the bottom pixel row of a cell is y = 0 (the atlas of the
/// tile file has y = 0 in its top row). Cells follow the atlas grid (sampler/tile_io.h
/// atlasGrid): slice k at column k % cols, row k / cols, counted from the top left. Tiles
/// narrower than kCellTargetPixels are magnified by an integer factor (every texel a square of
/// pixels), wider ones shown every n-th texel.
#pragma once

#include <filesystem>
#include <functional>
#include <glm/vec3.hpp>
#include <span>
#include <string>

#include "common/size3.h"
#include "sampler/tile.h"

namespace distile {

/// The colour (sRGB-encoded, components in [0, 1]) of `value` in [-1, 1] on the diverging map:
/// -1 deep blue, 0 near white, +1 deep red, linear in between; values beyond are clamped.
glm::vec3 divergingColor(float value);

/// The colour of the zero contour.
inline constexpr glm::vec3 kContourColor{0.0f, 0.0f, 0.0f};

/// Where a contact sheet puts things, in pixels (x right, y down from the top left).
struct ContactSheetLayout {
    static constexpr int kCellTargetPixels = 256;
    Size3 size;    ///< of the field drawn
    int cols = 1;  ///< cells per row (the atlas grid's)
    int rows = 1;
    int magnify = 1;    ///< pixels per texel (>= 1)
    int stride = 1;     ///< texels per pixel (>= 1; magnify or stride is 1)
    int cellWidth = 0;  ///< pixels
    int cellHeight = 0;
    int margin = 8;        ///< around and between cells
    int labelHeight = 18;  ///< above each cell
    int barWidth = 24;     ///< the colour bar, right of the cells
    int barLabelWidth = 128;
    int width = 0;  ///< of the whole picture
    int height = 0;

    /// The layout for a field of `size`.
    explicit ContactSheetLayout(const Size3& size);
    /// Top-left pixel of slice `slice`'s cell.
    int cellLeft(int slice) const;
    int cellTop(int slice) const;
    /// A pixel showing texel (x, y) of slice `slice` (the top-left one of its square when
    /// magnified). Preconditions: the texel lies in the field and is shown (x, y multiples of
    /// stride).
    int pixelX(int slice, int x) const { return cellLeft(slice) + (x / stride) * magnify; }
    int pixelY(int slice, int y) const {
        return cellTop(slice) + cellHeight - magnify - (y / stride) * magnify;
    }
    /// The colour bar: its left pixel column and its top and bottom rows (top: +range).
    int barLeft() const;
    int barTop() const;
    int barBottom() const;
};

/// What a contact sheet shows.
struct ContactSheetOptions {
    /// Half the range of the colour map (texels): values at -range and +range take its ends.
    /// Must be > 0 and finite.
    float rangeTexels = 1.0f;
    std::string barTitle = "texels";  ///< above the colour bar
    /// Where the zero contour lies: texels whose sign (< 0) differs from a neighbour's in x or y
    /// in this field are drawn in kContourColor. Empty: the field's own sign.
    std::span<const float> contourField;
};

/// Writes `values` (a W x H x D field in tile order, x fastest; texels) as a contact sheet PNG
/// (8-bit RGB, sRGB) at `file` through writeAtomically. Returns false when the labels could not
/// be drawn (no DejaVu Sans font: the picture is written without them). Throws InputError for a
/// file not ending in .png, a folder that does not exist, values or contourField of the wrong
/// size, or a range that is not finite and > 0; std::runtime_error when OpenImageIO fails.
bool writeContactSheet(std::span<const float> values, const Size3& size,
                       const ContactSheetOptions& options, const std::filesystem::path& file);

/// `distile preview`: the tile's distances, the map's range the tile's largest |distance|.
bool writeTilePreview(const Tile& tile, const std::filesystem::path& file);

/// `distile check --plot`: where the tile errs. Each texel shows tile - truth at its centre (red:
/// the tile overestimates, blue: it underestimates), the truth clamped to [-truthClampTexels,
/// truthClampTexels] (the band the tile holds), the map's range the largest |error|; the zero
/// contour is the truth's surface. `truth` is called on this thread only, once per texel, in tile
/// order. Throws as writeContactSheet, and std::runtime_error when the truth returns NaN.
bool writeTileErrorPlot(const Tile& tile, const std::function<double(const glm::dvec3&)>& truth,
                        double truthClampTexels, const std::filesystem::path& file);

}  // namespace distile
