#include "vdb/mesh_level_set.h"

#include <string>

#include "common/error.h"
#include "vdb/detail/openvdb_module.h"

namespace distile {

LevelSet levelSetFromMesh(const TriangleSoup& meshTexels, const Size3& tile, float halfBandTexels,
                          const std::string& source, const std::string& params,
                          const ProgressCallback& progress, const InsideTest& insideTest) {
    validateTileSize(tile, "mesh level set");
    if (!(halfBandTexels >= 1.0f && halfBandTexels <= 1024.0f)) {
        throw InputError("mesh level set: half band width " + numberText(halfBandTexels) +
                         " texels is not accepted; it must be in [1, 1024]");
    }
    validateTriangleSoup(meshTexels, "mesh level set");
    return LevelSet({detail::openVdb().levelSetFromMesh(meshTexels, tile, halfBandTexels, source,
                                                        params, progress, insideTest),
                     tile, source, params});
}

}  // namespace distile
