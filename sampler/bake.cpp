#include "sampler/bake.h"

#include "common/error.h"
#include "sampler/resample.h"

namespace distile {

BakeResult bakeChainmail(const ChainmailOptions& chainmailOptions, const BakeOptions& options,
                         const ProgressCallback& progress) {
    validateTileSize(options.size, "--size");
    if (!(options.halfBandTexels >= 0.0f)) {
        throw InputError("--band: " + std::to_string(options.halfBandTexels) +
                         " texels is not accepted; it must be at least 1 (or 0 for the tile depth)");
    }
    const Chainmail chainmail(chainmailOptions, options.size);
    const float halfBand = options.halfBandTexels > 0.0f ? options.halfBandTexels : float(options.size.depth);
    LevelSet levelSet = LevelSet::fromDistance(
        [&](const glm::dvec3& p) { return chainmail.signedDistanceTexels(p); }, options.size, halfBand,
        "chainmail", chainmail.paramsJson(), progress);
    Tile tile = tileFromLevelSet(levelSet);
    return {std::move(levelSet), std::move(tile)};
}

}  // namespace distile
