/// @file
/// Image files, read and written through OpenImageIO, which lives in a module loaded on first use,
/// except PNG files, which are written with libpng itself: a render's image needs no module.
/// OpenImageIO's plugins bring about 260 shared libraries (OpenCV, FFmpeg, DCMTK, libheif...),
/// and linking them dynamically cost every process that linked them 0.2-0.45 s before main:
/// most of `distile --help`, a third of the demo's whole `distile render`. Here only a process
/// that touches an image pays it, and one that knows it will (a render writes its image at the
/// end) loads the module on a second thread while it works. Every function that needs the module
/// throws InternalError if it cannot be loaded (the build is incomplete).
#pragma once

#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace distile::image_files {

/// How pixel values are stored in a file or laid out in memory.
enum class PixelType { UInt8, UInt16, Half, Float };

/// One metadata entry of a file. Reading keeps the string, integer and float entries.
struct Attribute {
    std::string name;
    std::variant<std::string, int, float> value;
};

/// What a file holds, or is to hold.
struct Spec {
    int width = 0, height = 0, depth = 1, channels = 0;
    bool deep = false;
    PixelType pixelType = PixelType::Float;  ///< as stored in the file
    std::vector<std::string> channelNames;   ///< writing: empty for the format's default names
    std::vector<Attribute> attributes;

    /// Sets the entry `name` to `value`, replacing one of that name.
    void set(const std::string& name, std::variant<std::string, int, float> value);
    /// The entry `name`, or null.
    const Attribute* find(std::string_view name) const;
    /// The string entry `name`, or "" (absent or not a string).
    std::string text(std::string_view name) const;
};

/// An image file open for reading.
class Input {
  public:
    virtual ~Input() = default;
    virtual const Spec& spec() const = 0;
    /// Reads the first `channels` channels of every pixel as floats, row by row, into `pixels`
    /// (width * height * channels values). Returns "" or what went wrong.
    virtual std::string readFloats(int channels, std::span<float> pixels) = 0;
};

/// Opens `file` with the reader its extension names, and only that one: a file that reader
/// cannot read is not offered to every other format in turn (OpenImageIO's fallback), where a
/// damaged .exr would be tried as DICOM, FITS... each with its own costs (the DICOM reader alone
/// took 2 GB on a fuzzed tile). A PNG's chunks and an EXR's header are checked first
/// (checkPngChunks, checkExrHeader): the libraries would print a broken chunk on stderr and
/// allocate what a damaged header declares.
/// @throws FormatError "FILE: not a readable image (OpenImageIO's reason)" followed by
///         `acceptedNote` (e.g. "; a height map must be ..."), or the checks' errors.
std::unique_ptr<Input> open(const std::filesystem::path& file, std::string_view acceptedNote = "");

/// True when writing `file` does not load the module: a PNG or an OpenEXR file (by its
/// extension), written with libpng or OpenEXR itself.
bool writesWithoutModule(const std::filesystem::path& file);

/// Writes `pixels` (spec.width * spec.height pixels of spec.channels values of type `given`, row
/// by row) to `file` in the format its extension names, stored as spec.pixelType with spec's
/// channel names and attributes (a PNG as common/detail/png_file.h says). `file` is usually
/// writeAtomically's temporary for `target`; throws std::runtime_error naming `target` if the
/// writing fails.
void write(const std::filesystem::path& file, const std::filesystem::path& target, const Spec& spec,
           PixelType given, const void* pixels);

/// Draws `text` into `rgb` (width * height pixels of three floats, row by row) in `color`, from
/// (`x`, `baseline`), in the font `font` at `fontPixels` pixels. False if there is no such font.
bool drawText(std::span<float> rgb, int width, int height, int x, int baseline,
              const std::string& text, int fontPixels, const std::string& font,
              const float (&color)[3]);

/// Starts loading the module on a second thread and returns at once: for a process that will
/// read or write an image later. Any use waits for the load to finish. Throws InternalError at
/// once if the module's file is missing.
void loadInBackground();

/// The first line of an OpenImageIO message, or `fallback` when it is empty.
inline std::string firstLine(const std::string& message,
                             const std::string& fallback = "unknown OpenImageIO error") {
    std::string line = message.substr(0, message.find('\n'));
    return line.empty() ? fallback : line;
}

}  // namespace distile::image_files
