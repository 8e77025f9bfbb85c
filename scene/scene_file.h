/// @file
/// Scene files: JSON to the renderer's structs (render/scene.h). Every field but `objects` has a
/// default; unknown fields are errors; relative paths resolve from the scene's folder. Tiles a
/// scene bakes (`"tile": {"bake": "chainmail" | "grating" | "heightmap" | "mesh" | "vdb", ...}`,
/// with the options of `distile bake` under its flags' names) are baked with distile::bake and kept
/// in its bake cache (bake/bake_cache.h). Errors are InputError (FormatError for unparsable JSON)
/// naming the file and the JSON path of the bad field, e.g. "scene.json: objects[0].material.depth:
/// -1 is not accepted; ...".
///
/// The scene is placed relative to what its camera looks at: positions are read in double
/// precision and the world origin is moved to the multiple of 1024 world units nearest the
/// camera's target before they are rounded to float, so a scene far from the origin (at 1e5,
/// where floats resolve 0.008 units) renders as one near it does; a target within 512 units of
/// the origin moves nothing. The image
/// and its AOVs do not depend on where the origin is; the Scene's positions do.
///
/// Loading and rendering a scene (examples/render_scene.cpp is the whole program):
///
///     distile::TileCache tiles;
///     distile::SceneFile file = distile::loadSceneFile("scene.json", tiles);
///     distile::RenderOptions options;  // render/renderer.h
///     options.width = file.image.width;
///     options.height = file.image.height;
///     options.samplesPerPixel = file.image.samplesPerPixel;
///     distile::writeImage(distile::renderScene(file.scene, options).image, "scene.png");
#pragma once

#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/error.h"
#include "common/progress.h"
#include "common/triangle_soup.h"
#include "render/scene.h"
#include "vdb/level_set.h"

namespace distile {

struct ImageSettings {
    int width = 1280;
    int height = 1024;
    int samplesPerPixel = 1;
};

struct SceneFile {
    Scene scene;
    ImageSettings image;
    /// Per object (same index as scene.objects): the detail mesh of a `"bake": "mesh"` tile,
    /// placed in the tile (texels), from which attachTruth builds the mesh truth; null for
    /// other objects. May be shorter than scene.objects (missing entries are null).
    std::vector<std::shared_ptr<const TriangleSoup>> placedDetailMeshes;
};

/// Tiles shared by the objects of a scene: files by canonical path, bakes by their parameters.
using TileCache = std::map<std::string, std::shared_ptr<const Tile>>;

/// Called with what is odd about a scene's input without stopping the load (a baked detail
/// mesh's degenerate faces or self-intersections, bake/solid_mesh.h), one line naming the file,
/// as soon as it is found: before a later error ends the load. The library prints nothing.
using SceneWarningCallback = std::function<void(const std::string& warning)>;

/// Called as a scene's tile starts to bake, with what is baked (the field that asks for it, e.g.
/// "scene.json: objects[0].material.tile"); returns the callback that bake reports its progress
/// to (common/progress.h), which is destroyed when the bake ends. A tile read from `tiles` or
/// the bake cache makes none.
using BakeProgress = std::function<ProgressCallback(const std::string& what)>;

/// The scene in `file`, its tiles read or baked once through `tiles` (pass the same cache to load
/// several scenes that share tiles); warnings go to `warn` (none: dropped), the progress of each
/// bake to the callback `bakeProgress` makes for it. Throws as the file note says.
SceneFile loadSceneFile(const std::filesystem::path& file, TileCache& tiles,
                        const SceneWarningCallback& warn = {},
                        const BakeProgress& bakeProgress = {});

/// The scene in `sceneJson` (the text of a scene file), named `name` in its errors (as a file's
/// name is), its relative paths resolved from `folder`; otherwise as loadSceneFile.
SceneFile loadSceneJson(const std::string& sceneJson, const std::filesystem::path& folder,
                        const std::string& name, TileCache& tiles,
                        const SceneWarningCallback& warn = {},
                        const BakeProgress& bakeProgress = {});

/// The tile of one bake recipe, as a scene material's `"tile"` writes it (JSON text, e.g.
/// `{"bake": "chainmail", "size": "64x64x8"}`; the keys are `distile bake`'s flags without the
/// dashes, '-' written '_'; docs/scene.md), baked as the command bakes it, once through `tiles`
/// and the bake cache. Errors as loadSceneJson's, the recipe's keys as their paths under `name`;
/// a relative "file" resolves from `folder`. A bake reports to `progress` (common/progress.h),
/// which may throw to end it.
std::shared_ptr<const Tile> bakeRecipeTile(const std::string& recipeJson,
                                           const std::filesystem::path& folder,
                                           const std::string& name, TileCache& tiles,
                                           const SceneWarningCallback& warn = {},
                                           const ProgressCallback& progress = {});

/// A recipe's tile and the level set it was sampled from.
struct RecipeLevelSet {
    std::shared_ptr<const Tile> tile;
    LevelSet levelSet;
};

/// bakeRecipeTile's recipe baked with its level set, as `distile bake --vdb` bakes it (its band's
/// margin above and below the tile included), tiled `repeatX` x `repeatY` times
/// (LevelSet::repeated; repeats it refuses are refused under "repeat" before the bake). The bake
/// cache holds tiles only: this always bakes, and reads and fills no cache; the tile is
/// bakeRecipeTile's.
RecipeLevelSet bakeRecipeLevelSet(const std::string& recipeJson,
                                  const std::filesystem::path& folder, const std::string& name,
                                  int repeatX = 1, int repeatY = 1,
                                  const SceneWarningCallback& warn = {},
                                  const ProgressCallback& progress = {});

/// The built-in demo: chain mail on a torus (curved) lying on a plane (flat); a bake of its tile
/// (when no cache has it) reports as loadSceneFile's do, as "the demo's tile".
SceneFile demoScene(TileCache& tiles, const BakeProgress& bakeProgress = {});

/// Gives each tiled object the exact truth of its detail, for reference renders and peers:
/// - a tile baked from procedural detail: the analytic distance (Material::analyticDistance) of
///   the procedural options in the tile's provenance (bake/provenance.h);
/// - a `"bake": "mesh"` tile: the mesh truth (truth/mesh_truth.h, periodic over the tile) as
///   Material::exactHit (CGAL first ray hits and triangle normals) and analyticDistance (exact
///   signed distance); for a mesh that is not closed or whose parts overlap or nest, the distance
///   to the surface its bake measured (bake/mesh_surface.h: triangles that bound its inside, caps
///   over its holes, signed by its winding number) as analyticDistance only (sphere traced).
/// - a tile file baked from a mesh: the same mesh truth, of its recorded source mesh placed as it
///   was baked (bake/provenance.h sourceMeshPlaced).
/// - a tile baked from a .vdb file (a `"bake": "vdb"` recipe or a tile file that records its
///   source): the source level set placed as recorded (bake/vdb_bake.h VdbDistance, band the tile
///   depth) as analyticDistance, periodic in x and y as the tile is sampled.
/// Others (height maps, tiles that do not record their source) are left as they are: the
/// renderer rejects a reference render of them. Throws FormatError for a procedural or vdb tile
/// whose params cannot be read or a source .vdb that cannot be read; InputError for a mesh or vdb
/// tile whose recorded source file is not found or has changed since the bake.
void attachTruth(SceneFile& sceneFile);

/// A Scene member path as validateScene names it ("objects[0].material.depthWorld") to the
/// scene file's JSON path ("objects[0].material.depth"); other text as it is.
std::string sceneJsonPath(std::string_view field);

/// `error` under the scene file's JSON path of its field (sceneJsonPath); as it is when it names
/// no field.
InputError underSceneJsonPath(const InputError& error);

}  // namespace distile
