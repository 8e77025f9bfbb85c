#include "bake/bake_cache.h"

#include <cstdlib>
#include <span>

#include "common/error.h"
#include "common/fnv1a.h"
#include "sampler/tile_io.h"

namespace distile {

namespace fs = std::filesystem;

std::string contentHash(std::string_view bytes) {
    Fnv1a64 hash;
    hash.update(std::as_bytes(std::span(bytes)));
    return hexDigits(hash.value());
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
