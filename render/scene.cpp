#include "render/scene.h"

#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <string>

#include "common/error.h"

namespace distile {

namespace {

bool finite(const glm::vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void requireFinite(const glm::vec3& v, const std::string& field) {
    if (!finite(v)) throw InputError::inField(field, "must be three finite numbers");
}

/// A colour's components in [0, kMaxColorComponent]; the first one outside is named.
void requireColor(const glm::vec3& color, const std::string& field) {
    requireFinite(color, field);
    for (int i = 0; i < 3; ++i) {
        if (!acceptedColorComponent(color[i])) {
            throw InputError::inField(
                field + "[" + std::to_string(i) + "]",
                numberText(color[i]) + " is not accepted; " + kColorComponentRule);
        }
    }
}

}  // namespace

void applyTransform(BaseMesh& mesh, const Transform& transform) {
    requireFinite(transform.translate, "transform.translate");
    requireFinite(transform.rotateDeg, "transform.rotateDeg");
    if (!(std::isfinite(transform.scale) && transform.scale > 0.0f)) {
        throw InputError::inField("transform.scale", numberText(transform.scale) +
                                                         " is not accepted; it must be a positive "
                                                         "number");
    }
    glm::mat4 matrix(1.0f);
    matrix = glm::translate(matrix, transform.translate);
    matrix = glm::rotate(matrix, glm::radians(transform.rotateDeg.z), glm::vec3(0, 0, 1));
    matrix = glm::rotate(matrix, glm::radians(transform.rotateDeg.y), glm::vec3(0, 1, 0));
    matrix = glm::rotate(matrix, glm::radians(transform.rotateDeg.x), glm::vec3(1, 0, 0));
    matrix = glm::scale(matrix, glm::vec3(transform.scale));
    // Rotation and uniform scale: directions transform with the rotation alone.
    const glm::mat3 rotation(matrix / transform.scale);
    for (auto& position : mesh.positions) position = glm::vec3(matrix * glm::vec4(position, 1.0f));
    for (auto& normal : mesh.normals) normal = glm::normalize(rotation * normal);
    for (auto& tangent : mesh.tangents) {
        tangent = glm::vec4(glm::normalize(rotation * glm::vec3(tangent)), tangent.w);
    }
}

glm::vec3 textureAlbedoAt(const Image& colorTexture, const glm::vec2& uv) {
    // Texel centres at (i + 0.5) / width, row 0 at the top (v = 1), wrapping in both directions.
    const float x = uv.x * float(colorTexture.width) - 0.5f;
    const float y = (1.0f - uv.y) * float(colorTexture.height) - 0.5f;
    const float x0 = std::floor(x);
    const float y0 = std::floor(y);
    const float fx = x - x0;
    const float fy = y - y0;
    auto wrap = [](float index, int extent) {
        const int wrapped = int(std::fmod(index, float(extent)));
        return wrapped < 0 ? wrapped + extent : wrapped;
    };
    const int ix0 = wrap(x0, colorTexture.width), ix1 = wrap(x0 + 1.0f, colorTexture.width);
    const int iy0 = wrap(y0, colorTexture.height), iy1 = wrap(y0 + 1.0f, colorTexture.height);
    const glm::vec3 top = glm::mix(colorTexture.at(ix0, iy0), colorTexture.at(ix1, iy0), fx);
    const glm::vec3 bottom = glm::mix(colorTexture.at(ix0, iy1), colorTexture.at(ix1, iy1), fx);
    return glm::mix(top, bottom, fy);
}

glm::vec3 unitDirection(const glm::vec3& direction) {
    const float lengthSquared = glm::dot(direction, direction);
    if (lengthSquared >= 1e-30f && lengthSquared <= 1e30f) return glm::normalize(direction);
    const glm::dvec3 exact(direction);
    const double length = glm::length(exact);
    return length > 0.0 ? glm::vec3(exact / length) : glm::vec3(0.0f);
}

void requireSceneTriangleBudget(std::size_t index, std::size_t trianglesSoFar) {
    if (trianglesSoFar <= kMaxSceneTriangles) return;
    throw InputError::inField(
        "objects[" + std::to_string(index) + "].mesh",
        "brings the scene's base meshes to " + std::to_string(trianglesSoFar) +
            " triangles; a scene may have at most " + std::to_string(kMaxSceneTriangles) +
            " in all its objects (about 5 GB to render)");
}

void validateScene(const Scene& scene) {
    const Camera& camera = scene.camera;
    requireFinite(camera.eye, "camera.eye");
    requireFinite(camera.target, "camera.target");
    requireFinite(camera.up, "camera.up");
    const glm::vec3 forward = camera.target - camera.eye;
    if (glm::length(forward) <= 0.0f)
        throw InputError::inField("camera.target",
                                  "equals camera.eye; the camera needs a view direction");
    if (!std::isfinite(glm::length(forward))) {  // its square overflows single precision
        throw InputError::inField("camera.target",
                                  "too far from camera.eye for single precision; they must be "
                                  "within 1e18 world units of each other");
    }
    if (glm::length(glm::cross(glm::normalize(forward), unitDirection(camera.up))) < 1e-6f) {
        throw InputError::inField(
            "camera.up", "parallel to the view direction (or zero); it must point sideways of it");
    }
    if (!(camera.fovDeg > 0.0f && camera.fovDeg < 180.0f)) {
        throw InputError::inField("camera.fovDeg", numberText(camera.fovDeg) +
                                                       " is not accepted; it must be in (0, 180)");
    }
    for (std::size_t i = 0; i < scene.lights.size(); ++i) {
        const std::string field = "lights[" + std::to_string(i) + "]";
        requireFinite(scene.lights[i].direction, field + ".direction");
        requireColor(scene.lights[i].color, field + ".color");
        if (unitDirection(scene.lights[i].direction) == glm::vec3(0.0f))
            throw InputError::inField(field + ".direction", "must not be zero");
        if (!(scene.lights[i].angleDeg >= 0.0f && scene.lights[i].angleDeg < 90.0f)) {
            throw InputError::inField(field + ".angleDeg", "must be in [0, 90)");
        }
    }
    if (scene.objects.empty())
        throw InputError::inField("objects", "the scene has no objects; at least one is needed");
    std::size_t triangles = 0;
    for (std::size_t i = 0; i < scene.objects.size(); ++i) {
        const std::string field = "objects[" + std::to_string(i) + "]";
        const SceneObject& object = scene.objects[i];
        triangles += object.mesh.triangles.size();
        requireSceneTriangleBudget(i, triangles);
        if (object.mesh.triangles.empty())
            throw InputError::inField(field + ".mesh", "has no triangles");
        const Material& material = object.material;
        if (!(std::isfinite(material.depthWorld) && material.depthWorld > 0.0f)) {
            throw InputError::inField(field + ".material.depthWorld",
                                      numberText(material.depthWorld) +
                                          " is not accepted; it must be a positive number of "
                                          "world units");
        }
        if (!(std::isfinite(material.uvScale.x) && std::isfinite(material.uvScale.y) &&
              material.uvScale.x > 0.0f && material.uvScale.y > 0.0f)) {
            throw InputError::inField(field + ".material.uvScale", "must be two positive numbers");
        }
        requireColor(material.color, field + ".material.color");
    }
}

glm::vec2 texelsPerWorldUv(const BaseMesh& mesh, const glm::uvec3& triangle,
                           const glm::vec2& uvScale, const Size3& tileSize) {
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
    if (!(worldPerU > 0.0f && worldPerV > 0.0f) || !std::isfinite(worldPerU) ||
        !std::isfinite(worldPerV)) {
        return glm::vec2(0.0f);
    }
    return {tileSize.width * uvScale.x / worldPerU, tileSize.height * uvScale.y / worldPerV};
}

}  // namespace distile
