#include "sampler/resample.h"

namespace distile {

Tile tileFromLevelSet(const LevelSet& levelSet) {
    Tile tile(levelSet.tileSize());
    levelSet.copyTileVoxels(tile.distancesTexels());
    tile.provenance = {levelSet.source(), levelSet.params()};
    return tile;
}

}  // namespace distile
