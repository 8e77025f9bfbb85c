#include "sampler/tile.h"

namespace distile {

Tile::Tile(const Size3& size, float fillTexels) : size_(size) {
    validateTileSize(size, "tile");
    distances_.assign(size.texelCount(), fillTexels);
}

}  // namespace distile
