// Fuzz target: tile files (OpenEXR atlas with distile's attributes).
#include "fuzz/fuzz_reader.h"
#include "sampler/tile_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return distile::fuzz::readAsFile(data, size, "tile.exr", [](const std::filesystem::path& file) {
        distile::readTileExr(file);
    });
}
