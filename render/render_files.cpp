#include "render/render_files.h"

#include <algorithm>
#include <string_view>
#include <utility>

#include "common/atomic_file.h"
#include "common/error.h"

namespace distile {

namespace fs = std::filesystem;

fs::path aovPath(const fs::path& image, const std::string& name, const std::string& extension) {
    return image.parent_path() / (image.stem().string() + "." + name + extension);
}

bool holdsAov(std::span<const char* const> aovs, std::string_view name) {
    return aovs.empty() ||
           std::ranges::any_of(aovs, [&](const char* held) { return name == held; });
}

void writeRenderFiles(const RenderResult& render, const fs::path& image,
                      std::span<const char* const> aovs) {
    requireImageExtension(image);  // named as given, not as its temporary
    OutputFiles files;
    writeImage(render.image, files.add(image, "image"));
    if (render.aovs) {
        for (const AovFile& aov : kAovFiles) {
            if (!holdsAov(aovs, aov.name)) continue;
            writeImage((*render.aovs).*aov.layer,
                       files.add(aovPath(image, aov.name, aov.extension),
                                 "image (its AOV " + std::string(aov.name) + ")"));
        }
    }
    files.commit();
}

namespace {

Image readLayer(const fs::path& file, const std::string& role) {
    if (!fs::exists(file)) {
        throw InputError(role + ": " + file.string() +
                         " does not exist; compare needs renders written with --aovs");
    }
    return readImage(file);
}

}  // namespace

RenderFiles readRenderFiles(const fs::path& image, const std::string& role) {
    if (!fs::exists(image))
        throw InputError(role + ": image " + image.string() + " does not exist");
    const fs::path depth = aovPath(image, "depth", ".exr");
    const fs::path normal = aovPath(image, "normal", ".png");
    const fs::path texelScale = aovPath(image, "texel_scale", ".exr");
    RenderFiles files{readImage(image), readLayer(depth, role), readLayer(normal, role),
                      readLayer(texelScale, role)};
    const auto sizeOf = [](const Image& layer) {
        return std::to_string(layer.width) + "x" + std::to_string(layer.height);
    };
    for (const auto& [layer, file] :
         {std::pair{&files.depth, &depth}, std::pair{&files.normal, &normal},
          std::pair{&files.texelScale, &texelScale}}) {
        if (layer->width == files.image.width && layer->height == files.image.height) continue;
        throw InputError(role + ": " + file->string() + " is " + sizeOf(*layer) +
                         " but its image " + image.string() + " is " + sizeOf(files.image) +
                         "; compare needs the AOVs written with the image (render --aovs)");
    }
    return files;
}

}  // namespace distile
