// Fuzz target: PLY meshes, as detail meshes (bake mesh) and as base meshes (scene objects).
#include "fuzz/fuzz_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return distile::fuzz::readMesh(data, size, "mesh.ply");
}
