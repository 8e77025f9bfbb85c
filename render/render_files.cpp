#include "render/render_files.h"

#include "common/atomic_file.h"
#include "common/error.h"

namespace distile {

namespace fs = std::filesystem;

fs::path aovPath(const fs::path& image, const std::string& name, const std::string& extension) {
    return image.parent_path() / (image.stem().string() + "." + name + extension);
}

void writeRenderFiles(const RenderResult& render, const fs::path& image) {
    OutputFiles files;
    writeImage(render.image, files.add(image, "image"));
    if (render.aovs) {
        for (const AovFile& aov : kAovFiles) {
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
    return {readImage(image), readLayer(aovPath(image, "depth", ".exr"), role),
            readLayer(aovPath(image, "normal", ".png"), role),
            readLayer(aovPath(image, "texel_scale", ".exr"), role)};
}

}  // namespace distile
