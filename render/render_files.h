/// @file
/// A render's files: the image and, beside it, its AOVs as `distile render --aovs` writes them
/// ("out.png" -> "out.depth.exr", "out.normal.png", ...), which `distile compare` reads back.
#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "render/compare.h"
#include "render/image.h"
#include "render/renderer.h"

namespace distile {

/// The file of the layer `name` beside `image`: "out.png", "depth", ".exr" -> "out.depth.exr".
std::filesystem::path aovPath(const std::filesystem::path& image, const std::string& name,
                              const std::string& extension);

/// One AOV of RenderAovs and the name and extension of its file: EXR for the layers that hold
/// measurements (depth in world units, texels per world unit), PNG for the pictures.
struct AovFile {
    const char* name;
    const char* extension;
    Image RenderAovs::*layer;
};
inline constexpr AovFile kAovFiles[] = {
    {"depth", ".exr", &RenderAovs::depth},
    {"normal", ".png", &RenderAovs::normal},
    {"iterations", ".png", &RenderAovs::iterations},
    {"shadow_samples", ".png", &RenderAovs::shadowSamples},
    {"shadow_map_samples", ".png", &RenderAovs::shadowMapSamples},
    {"curvature", ".png", &RenderAovs::curvature},
    {"texel_scale", ".exr", &RenderAovs::texelScale},
};

/// Whether `aovs` (names of kAovFiles; empty: every AOV) holds the AOV `name`.
bool holdsAov(std::span<const char* const> aovs, std::string_view name);

/// Writes `render`'s image to `image` (writeImage chooses the format by extension) and, when it
/// has AOVs, each AOV beside it (aovPath), or those of kAovFiles named in `aovs` when it is not
/// empty, all or none (common/atomic_file.h). Throws as OutputFiles::add and writeImage.
void writeRenderFiles(const RenderResult& render, const std::filesystem::path& image,
                      std::span<const char* const> aovs = {});

/// The layers `compare` reads of a render written with its AOVs: the image and its depth, normal
/// and texel-scale AOVs.
struct RenderFiles {
    Image image, depth, normal, texelScale;
    RenderLayersView view() const { return {image, depth, normal, texelScale}; }
};

/// Reads the render whose image is `image` and its AOVs beside it. `role` names it in messages
/// ("A", "B"). Throws InputError when a file does not exist (an AOV: "compare needs renders
/// written with --aovs"), as readImage otherwise.
RenderFiles readRenderFiles(const std::filesystem::path& image, const std::string& role);

}  // namespace distile
