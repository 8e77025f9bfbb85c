// Fuzz target: height-map images (bake heightmap), PNG being the common case.
#include "bake/height_image.h"
#include "fuzz/fuzz_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return distile::fuzz::readAsFile(data, size, "height.png", [](const std::filesystem::path& file) {
        distile::readHeightImage(file);
    });
}
