#include "common/size3.h"

#include "common/error.h"

namespace distile {

std::string toString(const Size3& size) {
    return std::to_string(size.width) + "x" + std::to_string(size.height) + "x" +
           std::to_string(size.depth);
}

void validateTileSize(const Size3& size, const std::string& what) {
    constexpr int kMinExtent = 2;
    constexpr int kMaxExtent = 65536;
    for (int extent : {size.width, size.height, size.depth}) {
        if (extent < kMinExtent || extent > kMaxExtent) {
            throw InputError::inField(what,
                                      "tile size " + toString(size) +
                                          " is not accepted; each extent must be in [2, 65536]");
        }
    }
    if (size.texelCount() > kMaxTileTexels) {
        throw InputError::inField(what, "tile size " + toString(size) + " has " +
                                            std::to_string(size.texelCount()) +
                                            " texels; at most " + std::to_string(kMaxTileTexels) +
                                            " (1 GiB of floats) are accepted");
    }
}

}  // namespace distile
