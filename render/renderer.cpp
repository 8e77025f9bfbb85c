#include "render/renderer.h"

#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>

#include <glm/geometric.hpp>

#include "common/error.h"
#include "render/bvh.h"
#include "render/march.h"
#include "sampler/filters.h"

namespace distile {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kSpecularStrength = 0.35f;
constexpr float kShininess = 48.0f;
constexpr float kAmbientStrength = 0.18f;

/// Per base-mesh triangle of the whole scene.
struct ShellTriangle {
    std::uint32_t object;
    std::uint32_t localTriangle;
    glm::vec2 texelsPerWorldUv;  ///< texels per world unit along T and B (0 if UVs are degenerate)
};

/// The base surface where a camera ray enters an object's detail shell.
struct SurfacePoint {
    glm::vec3 position;
    glm::vec3 normal;     ///< N, unit, outward
    glm::vec3 tangent;    ///< T, unit, along +u
    glm::vec3 bitangent;  ///< B, unit, along +v
    glm::vec2 uv;
    glm::vec3 texelsPerWorld;  ///< scale of T, B, N components into texel units
    bool frontFacing;

    glm::vec3 toTexel(const glm::vec3& world) const {
        return {glm::dot(world, tangent) * texelsPerWorld.x, glm::dot(world, bitangent) * texelsPerWorld.y,
                glm::dot(world, normal) * texelsPerWorld.z};
    }
    /// A texel-space gradient as a world-space normal (gradients transform with the transpose).
    glm::vec3 gradientToWorld(const glm::vec3& gradient) const {
        return tangent * (gradient.x * texelsPerWorld.x) + bitangent * (gradient.y * texelsPerWorld.y) +
               normal * (gradient.z * texelsPerWorld.z);
    }
};

/// Visibility in [0, 1] of a light of angular radius `tanHalfAngle` from a texel-space point,
/// by tracing toward it until the ray leaves the top of the tile; the nearest miss relative to
/// the distance travelled estimates how much of the light's disk is covered.
template <class Filter>
float lightVisibility(const Filter& filter, const glm::vec3& start, const glm::vec3& toLight, float depthTexels,
                      float tanHalfAngle, const RenderOptions& options) {
    if (toLight.z <= 0.0f) return 0.0f;
    float visibility = 1.0f;
    float travel = 0.1f;
    for (int i = 0; i < options.shadowIterations; ++i) {
        const glm::vec3 position = start + toLight * travel;
        if (position.z >= depthTexels) break;
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

/// Position of sample `index` of `count` inside the pixel: the centre for one sample, else the
/// R2 low-discrepancy sequence (Roberts 2018), the same for every pixel.
glm::vec2 sampleOffset(int index, int count) {
    if (count == 1) return glm::vec2(0.5f);
    constexpr double kG = 1.32471795724474602596;  // plastic number
    const double x = 0.5 + (index + 1) / kG;
    const double y = 0.5 + (index + 1) / (kG * kG);
    return {float(x - std::floor(x)), float(y - std::floor(y))};
}

class Renderer {
public:
    Renderer(const Scene& scene, const RenderOptions& options) : scene_(scene), options_(options) {
        std::vector<glm::vec3> corners;
        for (std::uint32_t objectIndex = 0; objectIndex < scene.objects.size(); ++objectIndex) {
            const SceneObject& object = scene.objects[objectIndex];
            const BaseMesh& mesh = object.mesh;
            const Tile* tile = object.material.tile.get();
            for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
                const glm::uvec3 triangle = mesh.triangles[t];
                for (int corner = 0; corner < 3; ++corner) corners.push_back(mesh.positions[triangle[corner]]);
                glm::vec2 texelsPerWorld(0.0f);
                if (tile) {
                    texelsPerWorld = texelsPerWorldUv(mesh, triangle, object.material.uvScale, tile->size());
                }
                triangles_.push_back({objectIndex, t, texelsPerWorld});
            }
        }
        bvh_ = TriangleBvh(std::move(corners));

        const Camera& camera = scene.camera;
        forward_ = glm::normalize(camera.target - camera.eye);
        right_ = glm::normalize(glm::cross(forward_, camera.up));
        up_ = glm::cross(right_, forward_);
        tanHalfFov_ = std::tan(0.5f * camera.fovDeg * kPi / 180.0f);
    }

    glm::vec3 shadePixel(int x, int y, RenderStats& stats) const {
        const float aspect = float(options_.width) / float(options_.height);
        glm::vec3 sum(0.0f);
        for (int sample = 0; sample < options_.samplesPerPixel; ++sample) {
            const glm::vec2 offset = sampleOffset(sample, options_.samplesPerPixel);
            const float ndcX = (2.0f * (x + offset.x) / options_.width - 1.0f) * tanHalfFov_ * aspect;
            const float ndcY = (1.0f - 2.0f * (y + offset.y) / options_.height) * tanHalfFov_;
            const Ray ray{scene_.camera.eye, glm::normalize(forward_ + ndcX * right_ + ndcY * up_)};
            sum += traceRay(ray, stats);
        }
        return sum / float(options_.samplesPerPixel);
    }

private:
    /// Texels per world unit along the triangle's u and v directions: the tile spans 1/uvScale in
    /// uv, and |dP/du|, |dP/dv| convert uv to world units.
    static glm::vec2 texelsPerWorldUv(const BaseMesh& mesh, const glm::uvec3& triangle, const glm::vec2& uvScale,
                                      const Size3& tileSize) {
        const glm::vec3 edge1 = mesh.positions[triangle[1]] - mesh.positions[triangle[0]];
        const glm::vec3 edge2 = mesh.positions[triangle[2]] - mesh.positions[triangle[0]];
        const glm::vec2 duv1 = mesh.uvs[triangle[1]] - mesh.uvs[triangle[0]];
        const glm::vec2 duv2 = mesh.uvs[triangle[2]] - mesh.uvs[triangle[0]];
        const float determinant = duv1.x * duv2.y - duv2.x * duv1.y;
        if (std::abs(determinant) < 1e-12f) return glm::vec2(0.0f);
        const glm::vec3 dPdu = (edge1 * duv2.y - edge2 * duv1.y) / determinant;
        const glm::vec3 dPdv = (edge2 * duv1.x - edge1 * duv2.x) / determinant;
        const float worldPerU = glm::length(dPdu);
        const float worldPerV = glm::length(dPdv);
        if (!(worldPerU > 0.0f && worldPerV > 0.0f) || !std::isfinite(worldPerU) || !std::isfinite(worldPerV)) {
            return glm::vec2(0.0f);
        }
        return {tileSize.width * uvScale.x / worldPerU, tileSize.height * uvScale.y / worldPerV};
    }

    SurfacePoint surfacePoint(const TriangleHit& hit, const Ray& ray) const {
        const ShellTriangle& shell = triangles_[hit.triangle];
        const SceneObject& object = scene_.objects[shell.object];
        const BaseMesh& mesh = object.mesh;
        const glm::uvec3 triangle = mesh.triangles[shell.localTriangle];
        const float b0 = 1.0f - hit.b1 - hit.b2;
        auto interpolate = [&](const auto& values) {
            return values[triangle[0]] * b0 + values[triangle[1]] * hit.b1 + values[triangle[2]] * hit.b2;
        };
        SurfacePoint point;
        point.position = ray.origin + ray.direction * hit.distanceWorld;
        point.normal = glm::normalize(interpolate(mesh.normals));
        const glm::vec4 tangent = interpolate(mesh.tangents);
        const glm::vec3 tangentInPlane = glm::vec3(tangent) - point.normal * glm::dot(glm::vec3(tangent), point.normal);
        const float tangentLength = glm::length(tangentInPlane);
        point.tangent = tangentLength > 1e-6f ? tangentInPlane / tangentLength
                                              : glm::normalize(glm::cross(point.normal, std::abs(point.normal.x) < 0.9f
                                                                                            ? glm::vec3(1, 0, 0)
                                                                                            : glm::vec3(0, 1, 0)));
        point.bitangent = glm::cross(point.normal, point.tangent) * (tangent.w < 0.0f ? -1.0f : 1.0f);
        point.uv = interpolate(mesh.uvs);
        const glm::vec3 geometricNormal = glm::cross(mesh.positions[triangle[1]] - mesh.positions[triangle[0]],
                                                     mesh.positions[triangle[2]] - mesh.positions[triangle[0]]);
        point.frontFacing = glm::dot(geometricNormal, ray.direction) < 0.0f;
        const Tile* tile = object.material.tile.get();
        const float depthTexels = tile ? float(tile->size().depth) : 1.0f;
        point.texelsPerWorld = {shell.texelsPerWorldUv.x, shell.texelsPerWorldUv.y,
                                depthTexels / object.material.depthWorld};
        return point;
    }

    glm::vec3 traceRay(Ray ray, RenderStats& stats) const {
        float minDistance = 0.0f;
        // An open floor lets the ray leave a shell through a hole and go on; bounded by the
        // object count so a ray cannot loop.
        for (std::size_t pass = 0; pass <= scene_.objects.size() + 1; ++pass) {
            TriangleHit hit;
            if (!bvh_.intersect(ray, minDistance, std::numeric_limits<float>::max(), hit)) {
                return skyColor(ray.direction);
            }
            if (pass == 0) ++stats.baseHits;
            const ShellTriangle& shell = triangles_[hit.triangle];
            const Material& material = scene_.objects[shell.object].material;
            const SurfacePoint point = surfacePoint(hit, ray);
            if (!point.frontFacing) {
                return material.color * 0.05f;  // inside of a closed mesh, or a plane from below
            }
            if (!material.tile || shell.texelsPerWorldUv.x == 0.0f) {
                return shadeBase(point, material, ray.direction);
            }
            const TrilinearFilter filter(*material.tile);
            const Size3& size = material.tile->size();
            glm::vec3 direction = point.toTexel(ray.direction);
            // Silhouettes of smooth-shaded meshes can tilt the interpolated frame until the ray
            // no longer descends; keep it descending so the march stays in the shell.
            direction.z = std::min(direction.z, -1e-3f * glm::length(direction));
            const float texelsPerWorldAlongRay = glm::length(direction);
            direction /= texelsPerWorldAlongRay;
            // Wrap the entry point into the tile in double precision: far repeats keep their
            // sub-texel position.
            const double u = double(point.uv.x) * material.uvScale.x;
            const double v = double(point.uv.y) * material.uvScale.y;
            const glm::vec3 entry(float((u - std::floor(u)) * size.width), float((v - std::floor(v)) * size.height),
                                  float(size.depth));
            const MarchResult result = march(filter, entry, direction, material.floor, options_.maxIterations, options_.epsilonTexels);
            stats.marchIterations += std::uint64_t(result.iterations);
            if (result.converged) ++stats.converged;
            if (result.exitedFloor) {
                minDistance = hit.distanceWorld + result.travelTexels / texelsPerWorldAlongRay;
                continue;
            }
            return shadeDetail(filter, point, material, result, ray.direction);
        }
        return skyColor(ray.direction);
    }

    glm::vec3 shadeBase(const SurfacePoint& point, const Material& material, const glm::vec3& view) const {
        glm::vec3 color = material.color * kAmbientStrength;
        for (const DirectionalLight& light : scene_.lights) {
            const glm::vec3 toLight = -glm::normalize(light.direction);
            color += directLight(point.normal, toLight, view, material.color) * light.color;
        }
        return color;
    }

    template <class Filter>
    glm::vec3 shadeDetail(const Filter& filter, const SurfacePoint& point, const Material& material,
                          const MarchResult& result, const glm::vec3& view) const {
        const float depthTexels = float(material.tile->size().depth);
        glm::vec3 texelNormal(0.0f, 0.0f, 1.0f);
        glm::vec3 normal = point.normal;
        if (!result.onFloor) {
            const glm::vec3 gradient = filter.gradient(result.texelPosition);
            const float length = glm::length(gradient);
            if (length > 1e-6f) {
                texelNormal = gradient / length;
                normal = glm::normalize(point.gradientToWorld(gradient));
            }
        }
        // Cavities (low in the shell) see less of the sky.
        const float openness = 0.35f + 0.65f * std::clamp(result.texelPosition.z / depthTexels, 0.0f, 1.0f);
        glm::vec3 color = material.color * (kAmbientStrength * openness);
        for (const DirectionalLight& light : scene_.lights) {
            const glm::vec3 toLight = -glm::normalize(light.direction);
            // A base surface facing away from the light is in its own shadow: no work.
            if (glm::dot(point.normal, toLight) <= 0.0f) continue;
            float visibility = 1.0f;
            if (options_.selfShadows) {
                glm::vec3 toLightTexel = point.toTexel(toLight);
                toLightTexel /= glm::length(toLightTexel);
                const float tanHalfAngle = std::max(std::tan(0.5f * light.angleDeg * kPi / 180.0f), 1e-3f);
                const glm::vec3 start = result.texelPosition + texelNormal * (2.0f * options_.epsilonTexels);
                visibility = lightVisibility(filter, start, toLightTexel, depthTexels, tanHalfAngle, options_);
                if (visibility <= 0.0f) continue;
            }
            color += directLight(normal, toLight, view, material.color) * light.color * visibility;
        }
        return color;
    }

    static glm::vec3 directLight(const glm::vec3& normal, const glm::vec3& toLight, const glm::vec3& view,
                                 const glm::vec3& albedo) {
        const float diffuse = std::max(glm::dot(normal, toLight), 0.0f);
        if (diffuse <= 0.0f) return glm::vec3(0.0f);
        const glm::vec3 halfway = glm::normalize(toLight - view);
        const float specular = std::pow(std::max(glm::dot(normal, halfway), 0.0f), kShininess);
        return albedo * diffuse + glm::vec3(kSpecularStrength * specular);
    }

    const Scene& scene_;
    const RenderOptions& options_;
    std::vector<ShellTriangle> triangles_;
    TriangleBvh bvh_;
    glm::vec3 forward_, right_, up_;
    float tanHalfFov_;
};

void validateOptions(const RenderOptions& options) {
    if (options.width < 1 || options.width > 16384 || options.height < 1 || options.height > 16384) {
        throw InputError("image size " + std::to_string(options.width) + "x" + std::to_string(options.height) +
                         " is not accepted; width and height must be in [1, 16384]");
    }
    if (options.maxIterations < 1 || options.maxIterations > 4096) {
        throw InputError("iterations: " + std::to_string(options.maxIterations) + " is not accepted; it must be in [1, 4096]");
    }
    if (!(options.epsilonTexels > 0.0f && options.epsilonTexels <= 1.0f)) {
        throw InputError("epsilon: " + std::to_string(options.epsilonTexels) + " texels is not accepted; it must be in (0, 1]");
    }
    if (options.shadowIterations < 1 || options.shadowIterations > 4096) {
        throw InputError("shadow iterations: must be in [1, 4096]");
    }
    if (options.samplesPerPixel < 1 || options.samplesPerPixel > 256) {
        throw InputError("samples per pixel: " + std::to_string(options.samplesPerPixel) + " is not accepted; it must be in [1, 256]");
    }
}

}  // namespace

Image renderScene(const Scene& scene, const RenderOptions& options, RenderStats* stats,
                  const ProgressCallback& progress) {
    validateOptions(options);
    validateScene(scene);
    const Renderer renderer(scene, options);
    Image image(options.width, options.height);
    std::atomic<std::uint64_t> baseHits{0}, iterations{0}, converged{0};
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
                                      image.at(x, y) = renderer.shadePixel(x, y, local);
                                  }
                              }
                              baseHits += local.baseHits;
                              iterations += local.marchIterations;
                              converged += local.converged;
                          });
        if (progress) progress(double(bandEnd) / options.height);
    }
    if (stats) {
        stats->rays = std::uint64_t(options.width) * std::uint64_t(options.height) * std::uint64_t(options.samplesPerPixel);
        stats->baseHits = baseHits;
        stats->marchIterations = iterations;
        stats->converged = converged;
    }
    return image;
}

}  // namespace distile
