#include "render/renderer.h"

#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>

#include <glm/geometric.hpp>

#include "common/error.h"

namespace distile {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kSpecularStrength = 0.35f;
constexpr float kShininess = 48.0f;
constexpr float kAmbientStrength = 0.18f;

/// Visibility in [0, 1] of a light of angular radius atan(tanHalfAngle) from a texel-space
/// point, by sphere tracing toward it until the ray leaves the top of the tile; the nearest miss
/// relative to the distance travelled estimates how much of the light's disk is covered.
template <class Filter>
float lightVisibility(const Filter& filter, const glm::vec3& start, const glm::vec3& toLight, float depthTexels,
                      float tanHalfAngle, const RenderOptions& options, std::uint64_t& steps) {
    if (toLight.z <= 0.0f) return 0.0f;
    float visibility = 1.0f;
    float travel = 0.1f;
    for (int i = 0; i < options.shadowIterations; ++i) {
        const glm::vec3 position = start + toLight * travel;
        if (position.z >= depthTexels) break;
        ++steps;
        const float distance = filter.distanceTexels(position);
        if (distance < 0.5f * options.epsilonTexels) return 0.0f;
        visibility = std::min(visibility, distance / (travel * tanHalfAngle));
        travel += std::max(distance, 0.05f);
    }
    visibility = std::clamp(visibility, 0.0f, 1.0f);
    return visibility * visibility * (3.0f - 2.0f * visibility);
}

glm::vec3 skyColor(const glm::vec3& direction) {
    const float t = 0.5f + 0.5f * direction.z;
    return glm::mix(glm::vec3(0.18f, 0.19f, 0.21f), glm::vec3(0.55f, 0.62f, 0.72f), t);
}

glm::vec3 directLight(const glm::vec3& normal, const glm::vec3& toLight, const glm::vec3& view, const glm::vec3& albedo) {
    const float diffuse = std::max(glm::dot(normal, toLight), 0.0f);
    if (diffuse <= 0.0f) return glm::vec3(0.0f);
    const glm::vec3 halfway = glm::normalize(toLight - view);
    const float specular = std::pow(std::max(glm::dot(normal, halfway), 0.0f), kShininess);
    return albedo * diffuse + glm::vec3(kSpecularStrength * specular);
}

/// Position of sample `index` of `count` inside the pixel: the centre for one sample, else the
/// R2 low-discrepancy sequence (Roberts 2018), the same for every pixel.
glm::vec2 sampleOffset(int index, int count) {
    if (count == 1) return glm::vec2(0.5f);
    constexpr double kG = 1.32471795724474602596;  // plastic number
    const double x = 0.5 + (index + 1) / kG;
    const double y = 0.5 + (index + 1) / (kG * kG);
    return {float(x - std::floor(x)), float(y - std::floor(y))};
}

/// What one camera ray produced.
struct Sample {
    glm::vec3 color{0.0f};
    float depth = 0.0f;
    glm::vec3 normal{0.0f};
    int iterations = 0;
    std::uint64_t shadowSteps = 0;
};

class Renderer {
public:
    Renderer(const Scene& scene, const RenderOptions& options)
        : scene_(scene),
          options_(options),
          tracer_(scene, TraceOptions{options.maxIterations, options.epsilonTexels, options.filter}) {
        const Camera& camera = scene.camera;
        forward_ = glm::normalize(camera.target - camera.eye);
        right_ = glm::normalize(glm::cross(forward_, camera.up));
        up_ = glm::cross(right_, forward_);
        tanHalfFov_ = std::tan(0.5f * camera.fovDeg * kPi / 180.0f);
    }

    Ray cameraRay(float x, float y) const {
        const float aspect = float(options_.width) / float(options_.height);
        const float ndcX = (2.0f * x / options_.width - 1.0f) * tanHalfFov_ * aspect;
        const float ndcY = (1.0f - 2.0f * y / options_.height) * tanHalfFov_;
        return {scene_.camera.eye, glm::normalize(forward_ + ndcX * right_ + ndcY * up_)};
    }

    /// All samples of pixel (x, y): the mean colour, and the first sample's AOV values.
    Sample renderPixel(int x, int y, RenderStats& stats) const {
        Sample pixel;
        glm::vec3 sum(0.0f);
        for (int index = 0; index < options_.samplesPerPixel; ++index) {
            const glm::vec2 offset = sampleOffset(index, options_.samplesPerPixel);
            const Sample sample = renderSample(cameraRay(x + offset.x, y + offset.y), stats);
            if (index == 0) pixel = sample;
            sum += sample.color;
        }
        pixel.color = sum / float(options_.samplesPerPixel);
        return pixel;
    }

private:
    Sample renderSample(const Ray& ray, RenderStats& stats) const {
        ++stats.rays;
        Sample sample;
        SurfaceHit hit;
        TraceCounters counters;
        const bool found = tracer_.traceNearest(ray, 0.0f, hit, counters);
        stats.marchIterations += counters.marchIterations;
        stats.converged += counters.converged;
        if (!found) {
            sample.color = skyColor(ray.direction);
            return sample;
        }
        ++stats.baseHits;
        sample.depth = hit.distanceWorld;
        sample.normal = hit.normal;
        sample.iterations = int(counters.marchIterations);
        const Material& material = scene_.objects[hit.object].material;
        if (!hit.entry.frontFacing) {
            sample.color = material.color * 0.05f;  // inside of a closed mesh, or a plane from below
        } else if (!hit.onDetail) {
            sample.color = shadeBase(hit, material, ray.direction);
        } else {
            withFilter(options_.filter, *material.tile, [&](const auto& filter) {
                sample.color = shadeDetail(filter, hit, material, ray.direction, sample.shadowSteps);
            });
        }
        stats.shadowSteps += sample.shadowSteps;
        return sample;
    }

    glm::vec3 shadeBase(const SurfaceHit& hit, const Material& material, const glm::vec3& view) const {
        glm::vec3 color = material.color * kAmbientStrength;
        for (const DirectionalLight& light : scene_.lights) {
            color += directLight(hit.normal, -glm::normalize(light.direction), view, material.color) * light.color;
        }
        return color;
    }

    template <class Filter>
    glm::vec3 shadeDetail(const Filter& filter, const SurfaceHit& hit, const Material& material, const glm::vec3& view,
                          std::uint64_t& shadowSteps) const {
        const float depthTexels = float(material.tile->size().depth);
        const glm::vec3 texelPosition = hit.march.texelPosition;
        // Cavities (low in the shell) see less of the sky.
        const float openness = 0.35f + 0.65f * std::clamp(texelPosition.z / depthTexels, 0.0f, 1.0f);
        glm::vec3 color = material.color * (kAmbientStrength * openness);
        for (const DirectionalLight& light : scene_.lights) {
            const glm::vec3 toLight = -glm::normalize(light.direction);
            // A base surface facing away from the light is in its own shadow: no work.
            if (glm::dot(hit.entry.normal, toLight) <= 0.0f) continue;
            float visibility = 1.0f;
            if (options_.selfShadows) {
                glm::vec3 texelNormal(0.0f, 0.0f, 1.0f);
                if (!hit.march.onFloor) {
                    const glm::vec3 gradient = filter.gradient(texelPosition);
                    if (glm::length(gradient) > 1e-6f) texelNormal = glm::normalize(gradient);
                }
                const glm::vec3 toLightTexel = glm::normalize(hit.entry.toTexel(toLight));
                const float tanHalfAngle = std::max(std::tan(0.5f * light.angleDeg * kPi / 180.0f), 1e-3f);
                const glm::vec3 start = texelPosition + texelNormal * (2.0f * options_.epsilonTexels);
                visibility = lightVisibility(filter, start, toLightTexel, depthTexels, tanHalfAngle, options_, shadowSteps);
                if (visibility <= 0.0f) continue;
            }
            color += directLight(hit.normal, toLight, view, material.color) * light.color * visibility;
        }
        return color;
    }

    const Scene& scene_;
    const RenderOptions& options_;
    SceneTracer tracer_;
    glm::vec3 forward_, right_, up_;
    float tanHalfFov_;
};

void validateOptions(const RenderOptions& options) {
    auto reject = [](const std::string& what, const std::string& value, const std::string& accepted) {
        throw InputError(what + ": " + value + " is not accepted; " + accepted);
    };
    if (options.width < 1 || options.width > 16384) reject("--width", std::to_string(options.width), "it must be in [1, 16384]");
    if (options.height < 1 || options.height > 16384) reject("--height", std::to_string(options.height), "it must be in [1, 16384]");
    if (options.maxIterations < 1 || options.maxIterations > 4096) {
        reject("--iterations", std::to_string(options.maxIterations), "it must be in [1, 4096]");
    }
    if (!(options.epsilonTexels > 0.0f && options.epsilonTexels <= 1.0f)) {
        reject("--epsilon", std::to_string(options.epsilonTexels), "it must be in (0, 1] texels");
    }
    if (options.shadowIterations < 1 || options.shadowIterations > 4096) {
        reject("shadow iterations", std::to_string(options.shadowIterations), "it must be in [1, 4096]");
    }
    if (options.samplesPerPixel < 1 || options.samplesPerPixel > 256) {
        reject("--spp", std::to_string(options.samplesPerPixel), "it must be in [1, 256]");
    }
}

}  // namespace

glm::vec3 heatColor(float value) {
    const float t = std::clamp(value, 0.0f, 1.0f) * 4.0f;
    const glm::vec3 stops[5] = {{0, 0, 1}, {0, 1, 1}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}};
    const int lower = std::min(int(t), 3);
    return glm::mix(stops[lower], stops[lower + 1], t - float(lower));
}

RenderResult renderScene(const Scene& scene, const RenderOptions& options, const ProgressCallback& progress) {
    validateOptions(options);
    validateScene(scene);
    const Renderer renderer(scene, options);
    RenderResult result;
    result.image = Image(options.width, options.height);
    if (options.outputAovs) {
        result.aovs.emplace(RenderAovs{Image(options.width, options.height), Image(options.width, options.height),
                                       Image(options.width, options.height), Image(options.width, options.height)});
    }
    const float shadowBudget = float(options.shadowIterations * std::max<std::size_t>(scene.lights.size(), 1));
    std::atomic<std::uint64_t> rays{0}, baseHits{0}, iterations{0}, converged{0}, shadowSteps{0};
    // Bands of rows, so progress can be reported from this thread between them; inside a band,
    // 16 x 16 pixel blocks are shared among the threads. Every pixel is computed on its own.
    constexpr int kBlock = 16;
    constexpr int kBandRows = 64;
    for (int bandStart = 0; bandStart < options.height; bandStart += kBandRows) {
        const int bandEnd = std::min(bandStart + kBandRows, options.height);
        tbb::parallel_for(tbb::blocked_range2d<int>(bandStart, bandEnd, kBlock, 0, options.width, kBlock),
                          [&](const tbb::blocked_range2d<int>& block) {
                              RenderStats local;
                              for (int y = block.rows().begin(); y != block.rows().end(); ++y) {
                                  for (int x = block.cols().begin(); x != block.cols().end(); ++x) {
                                      const Sample pixel = renderer.renderPixel(x, y, local);
                                      result.image.at(x, y) = pixel.color;
                                      if (!result.aovs) continue;
                                      result.aovs->depth.at(x, y) = glm::vec3(pixel.depth);
                                      result.aovs->normal.at(x, y) =
                                          pixel.depth > 0.0f ? pixel.normal * 0.5f + 0.5f : glm::vec3(0.0f);
                                      result.aovs->iterations.at(x, y) =
                                          heatColor(float(pixel.iterations) / float(options.maxIterations));
                                      result.aovs->shadowSamples.at(x, y) =
                                          heatColor(float(pixel.shadowSteps) / shadowBudget);
                                  }
                              }
                              rays += local.rays;
                              baseHits += local.baseHits;
                              iterations += local.marchIterations;
                              converged += local.converged;
                              shadowSteps += local.shadowSteps;
                          });
        if (progress) progress(double(bandEnd) / options.height);
    }
    result.stats = {rays, baseHits, iterations, converged, shadowSteps};
    return result;
}

}  // namespace distile
