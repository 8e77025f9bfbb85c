// A scene file to a PNG with the distile libraries: load it (distile::scene, which bakes the
// tiles it asks for), render it (distile::render), write the image. The options are the
// renderer's defaults, as `distile render` uses them.
//
//   render_scene SCENE.json OUT.png [WIDTH HEIGHT]
#include <cstdio>
#include <exception>
#include <string>

#include "render/image.h"
#include "render/renderer.h"
#include "scene/scene_file.h"

int main(int argc, char** argv) {
    if (argc != 3 && argc != 5) {
        std::fprintf(stderr, "usage: render_scene SCENE.json OUT.png [WIDTH HEIGHT]\n");
        return 2;
    }
    const auto warn = [](const std::string& warning) {
        std::fprintf(stderr, "warning: %s\n", warning.c_str());
    };
    try {
        distile::TileCache tiles;  // tiles shared by the scene's objects
        const distile::SceneFile file = distile::loadSceneFile(argv[1], tiles, warn);

        distile::RenderOptions options;  // image size and samples from the scene file
        options.width = argc == 5 ? std::stoi(argv[3]) : file.image.width;
        options.height = argc == 5 ? std::stoi(argv[4]) : file.image.height;
        options.samplesPerPixel = file.image.samplesPerPixel;
        const distile::RenderResult result = distile::renderScene(file.scene, options);
        for (const std::string& warning : result.warnings) warn(warning);

        distile::writeImage(result.image, argv[2]);
        std::printf("%s: %dx%d written to %s\n", argv[1], options.width, options.height, argv[2]);
    } catch (const std::exception& error) {
        std::fprintf(stderr, "render_scene: %s\n", error.what());
        return 1;
    }
    return 0;
}
