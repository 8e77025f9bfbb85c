/// @file
/// The mesh fuzz targets (one per format, so each corpus stays in one format): the bytes read
/// as a detail mesh and as a base mesh.
#pragma once

#include "fuzz/fuzz_reader.h"
#include "mesh/base_mesh.h"
#include "mesh/detail_mesh.h"

namespace distile::fuzz {

inline int readMesh(const std::uint8_t* data, std::size_t size, const std::string& name) {
    readAsFile(data, size, name, [](const std::filesystem::path& file) { loadDetailMesh(file); });
    return readAsFile(data, size, name,
                      [](const std::filesystem::path& file) { loadBaseMesh(file); });
}

}  // namespace distile::fuzz
