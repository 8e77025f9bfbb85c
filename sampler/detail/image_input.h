/// @file
/// Opening image files for reading, shared by the readers of tiles, images and height maps.
#pragma once

#include <OpenImageIO/imageio.h>

#include <filesystem>
#include <memory>
#include <string>

namespace distile::detail {

/// Opens `file` with the OpenImageIO plugin its extension names, and only that one. A file that
/// plugin cannot read is not offered to every other plugin in turn (OpenImageIO's fallback): a
/// damaged .exr would be tried as DICOM, FITS, ... each with its own costs (the DICOM reader alone
/// took 2 GB on a fuzzed tile). Null with `error` set when it cannot be opened.
inline std::unique_ptr<OIIO::ImageInput> openImageByExtension(const std::filesystem::path& file,
                                                              std::string& error) {
    auto input = OIIO::ImageInput::create(file.string());
    if (!input) {
        error = OIIO::geterror();
        if (error.empty()) error = "no image format is known by the extension";
        return nullptr;
    }
    OIIO::ImageSpec spec;
    if (!input->open(file.string(), spec)) {
        error = input->geterror();
        return nullptr;
    }
    return input;
}

}  // namespace distile::detail
