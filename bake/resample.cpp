#include "bake/resample.h"

namespace distile {

Tile tileFromLevelSet(const LevelSet& levelSet, const ConservativeOptions& conservative,
                      const ExactDistancesOnLine& exactDistances) {
    Tile tile(levelSet.tileSize());
    levelSet.copyTileVoxels(tile.distancesTexels());
    tile.provenance.source = levelSet.source();
    tile.provenance.params = levelSet.params();
    tile.provenance.halfBandTexels = levelSet.halfBandTexels();
    makeConservative(tile, conservative, exactDistances);
    return tile;
}

}  // namespace distile
