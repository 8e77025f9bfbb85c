// distile view and distile preview: a tile as a web page (the reference shader in WebGL2) and
// as a contact sheet of its slices.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cli/arguments.h"
#include "cli/commands.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "sampler/tile_io.h"
#include "view/contact_sheet.h"
#include "view/tile_page.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

struct ViewArguments {
    fs::path tile;
    fs::path output;
    TilePageView view;
    std::vector<float> uvScale;
    std::vector<float> sphereUvScale;
    bool openFloor = false;
};

void runView(const ViewArguments& arguments) {
    requireOutput(arguments.output, "-o", {".html"});
    TilePageView view = arguments.view;
    if (!arguments.uvScale.empty()) view.uvScale = {arguments.uvScale[0], arguments.uvScale[1]};
    if (!arguments.sphereUvScale.empty())
        view.sphereUvScale = {arguments.sphereUvScale[0], arguments.sphereUvScale[1]};
    view.solidFloor = !arguments.openFloor;
    OutputFiles files;
    const fs::path page = files.add(arguments.output, "-o");
    const Tile tile = readTileExr(arguments.tile);
    try {
        writeTilePage(tile, arguments.tile.filename().string(), view, page);
    } catch (const InputError& error) {
        throw shownUnder(error, {{"object", "--object"},
                                 {"uvScale.x", "--uv-scale"},
                                 {"uvScale.y", "--uv-scale"},
                                 {"depthWorld", "--depth"},
                                 {"sphereUvScale.x", "--sphere-uv-scale"},
                                 {"sphereUvScale.y", "--sphere-uv-scale"},
                                 {"sphereDepthWorld", "--sphere-depth"}});
    }
    files.commit();
    // WebGL2 promises 3D textures of 256 texels a side; GPUs give 2048 and more.
    const Size3 size = tile.size();
    if (std::max({size.width, size.height, size.depth}) > 2048) {
        std::fprintf(stderr,
                     "distile: warning: the tile is %dx%dx%d texels; most GPUs take 3D textures of "
                     "at most 2048 a side, and the page says so where this one does not fit\n",
                     size.width, size.height, size.depth);
    }
    std::printf("page written to %s (open it in a browser with WebGL2)\n",
                arguments.output.c_str());
}

struct PreviewArguments {
    fs::path tile;
    fs::path output;
};

void runPreview(const PreviewArguments& arguments) {
    requireOutput(arguments.output, "-o", {".png"});
    OutputFiles files;
    const fs::path picture = files.add(arguments.output, "-o");
    const Tile tile = readTileExr(arguments.tile);
    const bool labelled = writeTilePreview(tile, picture);
    files.commit();
    if (!labelled) {
        std::fprintf(stderr,
                     "distile: warning: the labels were left out: no DejaVu Sans font "
                     "(Debian: fonts-dejavu-core)\n");
    }
    std::printf("contact sheet written to %s\n", arguments.output.c_str());
}

}  // namespace

void addViewCommands(CLI::App& app) {
    auto view = std::make_shared<ViewArguments>();
    CLI::App* command = app.add_subcommand(
        "view",
        "Write a self-contained web page showing the tile on a plane and a sphere with the "
        "reference GLSL shader (WebGL2), orbitable with the mouse");
    command->add_option("tile", view->tile, "Tile file (.exr)")->required();
    command->add_option("-o,--output", view->output, "Page to write (.html)")->required();
    command
        ->add_option("--object", view->view.object, "Object the page opens with: plane or sphere")
        ->capture_default_str();
    command
        ->add_option("--uv-scale", view->uvScale, "Tile repeats over the plane, U V (default 4 4)")
        ->expected(2);
    command->add_option("--depth", view->view.depthWorld, "Shell depth on the plane, world units")
        ->capture_default_str();
    command
        ->add_option("--sphere-uv-scale", view->sphereUvScale,
                     "Tile repeats over the sphere, U V (default 8 4)")
        ->expected(2);
    command
        ->add_option("--sphere-depth", view->view.sphereDepthWorld,
                     "Shell depth on the sphere (radius 1), world units")
        ->capture_default_str();
    command->add_flag("--open-floor", view->openFloor,
                      "Rays pass through the floor z = 0 (holes show what is behind)");
    command->callback([view] { runView(*view); });

    auto preview = std::make_shared<PreviewArguments>();
    command = app.add_subcommand(
        "preview",
        "Draw the tile's slices as a contact sheet (PNG): inside blue, outside red, the zero "
        "contour in black, y up, a colour bar in texels");
    command->add_option("tile", preview->tile, "Tile file (.exr)")->required();
    command->add_option("-o,--output", preview->output, "Picture to write (.png)")->required();
    command->callback([preview] { runPreview(*preview); });
}

}  // namespace distile::cli
