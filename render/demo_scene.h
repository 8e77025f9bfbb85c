/// @file
/// The built-in demo scene: chain mail on a torus (curved) lying on a plane (flat), lit by one
/// soft directional light. One definition, used by the command (`distile render` without a
/// scene) and by the benchmarks. World units; the camera frames the torus.
#pragma once

#include <memory>

#include "mesh/base_mesh.h"
#include "render/scene.h"

namespace distile {

/// The demo scene's base meshes, with their tangent frames: apart from the tile, so that they can
/// be built while it is read.
struct DemoMeshes {
    BaseMesh floor;  ///< the plane
    BaseMesh torus;  ///< placed on the plane
};
/// Builds the demo's meshes (some 10 ms, most of it the torus's tangent frames).
DemoMeshes demoMeshes();

/// The demo scene with `chainmail` as the detail of both objects on `meshes`; the shell depths
/// make its texels cubes on the plane and on the torus's crown. Throws InputError if `chainmail`
/// is null.
Scene demoScene(std::shared_ptr<const Tile> chainmail, DemoMeshes meshes = demoMeshes());

}  // namespace distile
