// Fuzz target: OpenVDB files, read as `bake vdb` reads any level set and as `check --against`
// reads distile's own.
#include "fuzz/fuzz_reader.h"
#include "vdb/level_set.h"
#include "vdb/vdb_volume.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using distile::fuzz::readAsFile;
    readAsFile(data, size, "volume.vdb", [](const std::filesystem::path& file) {
        distile::VdbVolume::read(file);
    });
    return readAsFile(data, size, "volume.vdb", [](const std::filesystem::path& file) {
        distile::LevelSet::load(file);
    });
}
