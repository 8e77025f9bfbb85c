// Fuzz target: scene files. The scene may name tiles, meshes and images next to it (they are
// missing here, so their paths are refused) and bake procedural tiles. The tiles are kept
// across inputs (as a program loading several scenes would), so a recipe is baked once per
// process; a bake that the size bounds allow but that takes too long is a finding.
#include "fuzz/fuzz_reader.h"
#include "scene/scene_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return distile::fuzz::readAsFile(data, size, "scene.json", [](const std::filesystem::path& file) {
        static distile::TileCache tiles;
        if (tiles.size() > 32) tiles.clear();  // bounded memory over a long campaign
        distile::loadSceneFile(file, tiles);
    });
}
