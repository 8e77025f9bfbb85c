#include "sampler/conservative.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "common/error.h"

namespace distile {

void makeConservative(Tile& tile, const ConservativeOptions& options) {
    auto requireNonNegative = [](float value, const char* field) {
        if (!(value >= 0.0f && std::isfinite(value))) {
            throw InputError(std::string("conservative resampling: ") + field + " = " +
                             std::to_string(value) +
                             " is not accepted; it must be a finite number >= 0");
        }
    };
    requireNonNegative(options.toleranceTexels, "tolerance");
    requireNonNegative(options.smoothFactor, "smooth factor");
    requireNonNegative(options.kinkThresholdTexels, "kink threshold");
    requireNonNegative(options.kinkFactor, "kink factor");
    if (!options.enabled) return;

    const Size3 size = tile.size();
    const std::vector<float> exact(tile.distancesTexels().begin(), tile.distancesTexels().end());
    auto at = [&](int x, int y, int z) { return exact[tile.index(x, y, z)]; };
    auto estimate = [&](float secondDifference) {
        const float positive = std::max(secondDifference, 0.0f);
        return positive > options.kinkThresholdTexels ? options.kinkFactor * positive
                                                      : options.smoothFactor * positive;
    };
    const float allowance = 0.9f * options.toleranceTexels;
    std::span<float> texels = tile.distancesTexels();
    tbb::parallel_for(
        tbb::blocked_range<int>(0, size.depth), [&](const tbb::blocked_range<int>& slices) {
            for (int z = slices.begin(); z != slices.end(); ++z) {
                // The centred z difference of the first and last slice is that of their inner
                // neighbour.
                const int zCentre = size.depth < 3 ? -1 : std::clamp(z, 1, size.depth - 2);
                for (int y = 0; y < size.height; ++y) {
                    const int yBelow = y == 0 ? size.height - 1 : y - 1;
                    const int yAbove = y + 1 == size.height ? 0 : y + 1;
                    for (int x = 0; x < size.width; ++x) {
                        const int xBelow = x == 0 ? size.width - 1 : x - 1;
                        const int xAbove = x + 1 == size.width ? 0 : x + 1;
                        const float centre = at(x, y, z);
                        float lowering =
                            estimate(at(xAbove, y, z) - 2.0f * centre + at(xBelow, y, z)) +
                            estimate(at(x, yAbove, z) - 2.0f * centre + at(x, yBelow, z));
                        if (zCentre >= 0) {
                            lowering += estimate(at(x, y, zCentre + 1) - 2.0f * at(x, y, zCentre) +
                                                 at(x, y, zCentre - 1));
                        }
                        texels[tile.index(x, y, z)] = centre - std::max(0.0f, lowering - allowance);
                    }
                }
            }
        });
}

}  // namespace distile
