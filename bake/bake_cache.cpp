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

std::shared_ptr<const Tile> cachedBake(const std::string& recipe, const std::function<Tile()>& bake,
                                       const std::string& sourceHash) {
    const std::string fullRecipe = "revision " + std::to_string(kBakeRevision) + "\n" + recipe;
    const std::string recipeHash = contentHash(fullRecipe);
    const std::optional<fs::path> folder = bakeCacheFolder();
    const fs::path file = folder ? *folder / ("tile-" + recipeHash + ".exr") : fs::path();
    std::error_code error;
    if (folder && fs::is_regular_file(file, error)) {
        try {
            Tile cached = readTileExr(file);
            // A sound tile of another recipe (a file copied over this one) is foreign too.
            if (cached.provenance.recipeHash == recipeHash) {
                cached.provenance.recipeHash.clear();
                return std::make_shared<const Tile>(std::move(cached));
            }
        } catch (const std::exception&) {
            // Damaged or foreign: bake again and replace it below.
        }
    }
    Tile baked = bake();
    // Stored only when the bake read the bytes the recipe names: a source file replaced while
    // it was baked gave the tile of its new bytes.
    if (folder && (sourceHash.empty() || baked.provenance.sourceHash == sourceHash)) {
        try {
            fs::create_directories(*folder);
            baked.provenance.recipeHash = recipeHash;
            writeTileExr(baked, file);
        } catch (const std::exception&) {
            // A cache that cannot be written is no cache; the tile is still good.
        }
        baked.provenance.recipeHash.clear();
    }
    return std::make_shared<const Tile>(std::move(baked));
}

}  // namespace distile
