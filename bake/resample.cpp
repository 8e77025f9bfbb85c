#include "bake/resample.h"

namespace distile {

Tile tileFromLevelSet(const LevelSet& levelSet, const ConservativeOptions& conservative,
                      const ExactDistance& exactDistance) {
    Tile tile(levelSet.tileSize());
    levelSet.copyTileVoxels(tile.distancesTexels());
    tile.provenance = {levelSet.source(), levelSet.params()};
    makeConservative(tile, conservative, exactDistance);
    return tile;
}

}  // namespace distile
