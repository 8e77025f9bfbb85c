/// @file
/// Scene files (DESIGN.md, Scene files): JSON to the renderer's structs. Every field but
/// `objects` has a default; unknown fields are errors; relative paths resolve from the scene's
/// folder. Errors are InputError (FormatError for unparsable JSON) naming the file and the JSON
/// path of the bad field, e.g. "scene.json: objects[0].material.depth: -1 is not accepted; ...".
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "common/triangle_soup.h"
#include "render/scene.h"

namespace distile::cli {

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

SceneFile loadSceneFile(const std::filesystem::path& file, TileCache& tiles);

/// The built-in demo: chain mail on a torus (curved) lying on a plane (flat).
SceneFile demoScene(TileCache& tiles);

/// Gives each tiled object the exact truth of its detail, for reference renders and peers:
/// - a tile baked from procedural detail: its procedural options and analytic distance
///   (Material::procedural, analyticDistance), from the tile's provenance;
/// - a `"bake": "mesh"` tile: the mesh truth (truth/mesh_truth.h, periodic over the tile) as
///   Material::exactHit (CGAL first ray hits and triangle normals) and analyticDistance (exact
///   signed distance).
/// Others (tile files baked from meshes or height maps) are left as they are: the renderer
/// rejects a reference render of them. Throws FormatError for a procedural tile whose params
/// cannot be read.
void attachTruth(SceneFile& sceneFile);

}  // namespace distile::cli
