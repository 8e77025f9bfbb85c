#include "bake/bake_cache.h"

#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include "common/error.h"
#include "sampler/tile_io.h"

namespace distile {

namespace fs = std::filesystem;

std::string contentHash(std::string_view bytes) {
    std::uint64_t hash = 0xcbf29ce484222325ull;  // FNV-1a 64
    for (unsigned char byte : bytes) {
        hash ^= byte;
        hash *= 0x100000001b3ull;
    }
    char digits[17];
    std::snprintf(digits, sizeof digits, "%016llx", static_cast<unsigned long long>(hash));
    return digits;
}

std::optional<fs::path> bakeCacheFolder() {
    if (const char* folder = std::getenv("DISTILE_CACHE"); folder && *folder) {
        if (std::string(folder) == "off") return std::nullopt;
        return fs::path(folder);
    }
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
        return fs::path(xdg) / "distile";
    if (const char* home = std::getenv("HOME"); home && *home)
        return fs::path(home) / ".cache" / "distile";
    return std::nullopt;
}

std::shared_ptr<const Tile> cachedBake(const std::string& recipe,
                                       const std::function<Tile()>& bake) {
    const std::string fullRecipe = "revision " + std::to_string(kBakeRevision) + "\n" + recipe;
    const std::optional<fs::path> folder = bakeCacheFolder();
    const fs::path file =
        folder ? *folder / ("tile-" + contentHash(fullRecipe) + ".exr") : fs::path();
    std::error_code error;
    if (folder && fs::is_regular_file(file, error)) {
        try {
            return std::make_shared<const Tile>(readTileExr(file));
        } catch (const std::exception&) {
            // Damaged or foreign: bake again and replace it below.
        }
    }
    auto tile = std::make_shared<const Tile>(bake());
    if (folder) {
        try {
            fs::create_directories(*folder);
            writeTileExr(*tile, file);
        } catch (const std::exception&) {
            // A cache that cannot be written is no cache; the tile is still good.
        }
    }
    return tile;
}

}  // namespace distile
