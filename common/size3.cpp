#include "common/size3.h"

#include <algorithm>
#include <charconv>

#include "common/error.h"

namespace distile {

namespace {

/// The `count` whole numbers of `text` joined by 'x' into `extents`; false for any other text.
bool parseExtents(std::string_view text, int* extents, int count) {
    const char* cursor = text.data();
    const char* end = text.data() + text.size();
    for (int axis = 0; axis < count; ++axis) {
        if (axis > 0) {
            if (cursor == end || *cursor != 'x') return false;
            ++cursor;
        }
        const auto [next, error] = std::from_chars(cursor, end, extents[axis]);
        if (error != std::errc() || next == cursor) return false;
        cursor = next;
    }
    return cursor == end;
}

}  // namespace

Size3 parseSize3(std::string_view text, const std::string& field) {
    int extents[3] = {0, 0, 0};
    if (!parseExtents(text, extents, 3)) {
        throw InputError::inField(
            field, "'" + std::string(text) + "' is not a size; write WxHxD, e.g. 256x256x16");
    }
    return {extents[0], extents[1], extents[2]};
}

std::array<int, 2> parseSize2(std::string_view text, const std::string& field) {
    std::array<int, 2> extents{0, 0};
    if (!parseExtents(text, extents.data(), 2)) {
        throw InputError::inField(field,
                                  "'" + std::string(text) + "' is not a size; write WxH, e.g. 2x2");
    }
    return extents;
}

std::string toString(const Size3& size) {
    return std::to_string(size.width) + "x" + std::to_string(size.height) + "x" +
           std::to_string(size.depth);
}

void validateTileSize(const Size3& size, const std::string& what) {
    for (int extent : {size.width, size.height, size.depth}) {
        if (extent < kMinTileExtent || extent > kMaxTileExtent) {
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

float maxHalfBandTexels(const Size3& size) {
    return std::min(1024.0f, 2.0f * float(size.depth));
}

}  // namespace distile
