#include "render/demo_scene.h"

#include <utility>

#include "common/error.h"

namespace distile {

namespace {
constexpr float kTorusMinorRadius = 0.32f;
}  // namespace

DemoMeshes demoMeshes() {
    DemoMeshes meshes;
    meshes.floor = makePlane(4.0f, 1);
    meshes.torus = makeTorus(0.75f, kTorusMinorRadius, 192, 64);
    applyTransform(meshes.torus,
                   {{0.0f, 0.2f, kTorusMinorRadius + 0.02f}, {0.0f, 0.0f, 0.0f}, 1.0f});
    return meshes;
}

Scene demoScene(std::shared_ptr<const Tile> chainmail, DemoMeshes meshes) {
    if (!chainmail)
        throw InputError("demo scene: no chain-mail tile was given; a baked tile is required");
    // Texels are cubes when depth = (world size of one tile) * D / W.
    auto cubicDepth = [&](float tileWorldSize) {
        return tileWorldSize * float(chainmail->size().depth) / float(chainmail->size().width);
    };

    Scene scene;
    scene.camera = {{0.0f, -3.4f, 2.3f}, {0.0f, 0.1f, 0.25f}, {0.0f, 0.0f, 1.0f}, 38.0f};
    scene.lights = {DirectionalLight{{-0.45f, 0.35f, -1.0f}, {1.0f, 0.97f, 0.92f}, 3.0f}};

    SceneObject floor;
    floor.mesh = std::move(meshes.floor);
    floor.material.tile = chainmail;
    floor.material.uvScale = {4.0f, 4.0f};
    floor.material.depthWorld = cubicDepth(1.0f);
    floor.material.color = {0.62f, 0.63f, 0.66f};
    scene.objects.push_back(std::move(floor));

    SceneObject torus;
    torus.mesh = std::move(meshes.torus);
    // 10 tiles around, 4 around the tube: tiles of about 0.5 world units on the tube's crown.
    const glm::vec2 uvScale(10.0f, 4.0f);
    torus.material.tile = chainmail;
    torus.material.uvScale = uvScale;
    torus.material.depthWorld = cubicDepth(2.0f * 3.14159265f * kTorusMinorRadius / uvScale.y);
    torus.material.color = {0.85f, 0.72f, 0.45f};
    scene.objects.push_back(std::move(torus));
    return scene;
}

}  // namespace distile
