/// @file
/// What the OpenImageIO module exports to the loader (common/image_files.cpp,
/// common/detail/module_loader.h): one table of functions, found by its C name.
#pragma once

#include "common/image_files.h"

namespace distile::image_files::detail {

struct ModuleFunctions {
    std::unique_ptr<Input> (*open)(const std::filesystem::path& file, std::string& error);
    std::string (*write)(const std::filesystem::path& file, const Spec& spec, PixelType given,
                         const void* pixels);
    bool (*drawText)(std::span<float> rgb, int width, int height, int x, int baseline,
                     const std::string& text, int fontPixels, const std::string& font,
                     const float (&color)[3]);
};

/// The name the module exports its table under: `const void* NAME()`, a ModuleFunctions.
inline constexpr const char* kModuleEntry = "distile_image_files_module";

}  // namespace distile::image_files::detail
