#include "render/world_reference.h"

#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <glm/geometric.hpp>
#include <limits>
#include <optional>
#include <string>

#include "common/error.h"
#include "render/coverage.h"
#include "sampler/filters.h"

namespace distile {

namespace {

DisplacedLevelSet::DistanceFunction detailDistance(const Material& material) {
    if (material.analyticDistance) return material.analyticDistance;
    const std::shared_ptr<const Tile> tile = material.tile;
    return [tile](const glm::dvec3& texel) {
        return double(TrilinearFilter(*tile).distanceTexels(glm::vec3(texel)));
    };
}

/// Lambert under the scene's lights plus a little ambient: enough to see the detail's shape.
glm::vec3 shadeNormal(const Scene& scene, const glm::vec3& albedo, const glm::vec3& normal) {
    glm::vec3 radiance = 0.1f * albedo;
    for (const DirectionalLight& light : scene.lights) {
        const float cosine = std::max(0.0f, glm::dot(normal, -glm::normalize(light.direction)));
        radiance += albedo * light.color * cosine;
    }
    return radiance;
}

}  // namespace

WorldReferenceResult renderWorldReference(const Scene& scene, const WorldReferenceOptions& options,
                                          const ProgressCallback& progress) {
    validateScene(scene);
    if (options.width < 1 || options.width > 16384 || options.height < 1 ||
        options.height > 16384) {
        throw InputError("world reference: image size " + std::to_string(options.width) + "x" +
                         std::to_string(options.height) +
                         " is not accepted; each side must be in [1, 16384] pixels");
    }
    WorldReferenceResult result;

    const auto start = std::chrono::steady_clock::now();
    std::vector<std::optional<DisplacedLevelSet>> levelSets(scene.objects.size());
    Scene bareScene;  // the objects without a tile, traced as their base meshes
    bareScene.camera = scene.camera;
    std::vector<std::uint32_t> bareObjects;
    for (std::size_t index = 0; index < scene.objects.size(); ++index) {
        const SceneObject& object = scene.objects[index];
        const Material& material = object.material;
        if (!material.tile) {
            bareScene.objects.push_back(object);
            bareObjects.push_back(std::uint32_t(index));
            continue;
        }
        const DisplacementShell shell{object.mesh.positions,
                                      object.mesh.normals,
                                      object.mesh.uvs,
                                      object.mesh.triangles,
                                      glm::dvec2(material.uvScale),
                                      double(material.depthWorld),
                                      material.floor == Floor::Solid};
        levelSets[index] = DisplacedLevelSet::build(detailDistance(material), material.tile->size(),
                                                    shell, options.levelSet);
        result.levelSets.push_back(levelSets[index]->stats());
    }
    result.buildSeconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::optional<SceneTracer> bareTracer;
    if (!bareScene.objects.empty()) bareTracer.emplace(bareScene, TraceOptions{});

    const PinholeProjection projection(scene.camera, options.width, options.height);
    RenderResult& render = result.render;
    render.image = Image(options.width, options.height);
    if (options.outputAovs) {
        render.aovs.emplace(RenderAovs::blank(options.width, options.height));
    }
    std::atomic<std::uint64_t> hits{0};
    constexpr int kBlock = 16;
    constexpr int kBandRows = 64;
    for (int bandStart = 0; bandStart < options.height; bandStart += kBandRows) {
        const int bandEnd = std::min(bandStart + kBandRows, options.height);
        tbb::parallel_for(
            tbb::blocked_range2d<int>(bandStart, bandEnd, kBlock, 0, options.width, kBlock),
            [&](const tbb::blocked_range2d<int>& block) {
                std::uint64_t localHits = 0;
                TraceCounters counters;
                for (int y = block.rows().begin(); y != block.rows().end(); ++y) {
                    for (int x = block.cols().begin(); x != block.cols().end(); ++x) {
                        const Ray ray = projection.ray(float(x) + 0.5f, float(y) + 0.5f);
                        double nearest = std::numeric_limits<double>::infinity();
                        glm::dvec3 normal(0.0);
                        std::uint32_t hitObject = 0;
                        for (std::size_t index = 0; index < levelSets.size(); ++index) {
                            double distance = 0.0;
                            glm::dvec3 objectNormal;
                            if (levelSets[index] &&
                                levelSets[index]->intersect(
                                    glm::dvec3(ray.origin), glm::dvec3(ray.direction),
                                    std::numeric_limits<double>::max(), distance, objectNormal) &&
                                distance < nearest) {
                                nearest = distance;
                                normal = objectNormal;
                                hitObject = std::uint32_t(index);
                            }
                        }
                        SurfaceHit bareHit;
                        if (bareTracer && bareTracer->traceNearest(ray, 0.0f, bareHit, counters) &&
                            bareHit.distanceWorld < nearest) {
                            nearest = bareHit.distanceWorld;
                            normal = glm::dvec3(bareHit.normal);
                            hitObject = bareObjects[bareHit.object];
                        }
                        if (!std::isfinite(nearest)) continue;
                        ++localHits;
                        const Material& material = scene.objects[hitObject].material;
                        render.image.at(x, y) =
                            shadeNormal(scene, material.color, glm::vec3(normal));
                        if (!render.aovs) continue;
                        render.aovs->depth.at(x, y) = glm::vec3(float(nearest));
                        render.aovs->normal.at(x, y) = glm::vec3(normal) * 0.5f + 0.5f;
                    }
                }
                hits += localHits;
            });
        if (progress) progress(double(bandEnd) / options.height);
    }
    render.stats.rays = std::uint64_t(options.width) * std::uint64_t(options.height);
    render.stats.baseHits = hits;
    render.stats.converged = hits;
    return result;
}

}  // namespace distile
