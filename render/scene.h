/// @file
/// What the renderer draws: a camera, directional lights and base meshes carrying distance
/// tiles. Plain structs with defaults (docs/scene.md); scene files (scene/scene_file.h) and
/// programs fill them, the renderer never parses text. World units throughout, angles in degrees.
#pragma once

#include <cstddef>
#include <functional>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <optional>
#include <vector>

#include "mesh/base_mesh.h"
#include "render/image.h"
#include "sampler/tile.h"

namespace distile {

struct Camera {
    glm::vec3 eye{0.0f, -3.0f, 2.0f};
    glm::vec3 target{0.0f, 0.0f, 0.0f};
    glm::vec3 up{0.0f, 0.0f, 1.0f};
    float fovDeg = 40.0f;  ///< vertical field of view
};

struct DirectionalLight {
    glm::vec3 direction{-0.4f, -0.3f, -1.0f};  ///< direction the light travels (need not be unit)
    glm::vec3 color{1.0f, 1.0f, 1.0f};         ///< linear RGB radiance scale
    float angleDeg = 2.0f;                     ///< angular diameter: softness of shadows
};

enum class Floor { Solid, Open };

/// Where a ray first meets a material's detail, from Material::exactHit.
struct DetailHit {
    double travelTexels = 0.0;  ///< along the ray from its origin, texels
    /// Unit surface normal at the hit in texel space, facing the ray (outward for a ray that
    /// arrives from outside the detail).
    glm::dvec3 normalTexels{0.0, 0.0, 1.0};
};

struct Material {
    std::shared_ptr<const Tile> tile;  ///< null: the bare base surface, no detail
    glm::vec2 uvScale{1.0f, 1.0f};     ///< tile repeats per unit of u and v
    float depthWorld = 0.05f;          ///< thickness of the detail shell below the surface
    Floor floor = Floor::Solid;
    glm::vec3 color{0.8f, 0.8f, 0.85f};  ///< linear RGB albedo (when there is no colour texture)
    /// Optional albedo texture (linear RGB, see render/image.h readImage), looked up bilinearly at
    /// the base mesh's uv (not scaled by uvScale: it paints the whole mesh), repeating outside
    /// [0,1].
    std::shared_ptr<const Image> colorTexture;
    /// Optional exact signed distance of the detail the tile was made from (texels, texel space,
    /// periodic in x and y; safe to call from several threads): the truth a reference render
    /// (RenderOptions::reference) traces instead of the tile. Empty: no analytic truth.
    std::function<double(const glm::dvec3& texelPosition)> analyticDistance;
    /// Optional exact first hit of the same detail (texel space, double precision, periodic in x
    /// and y; safe to call from several threads): the ray from `originTexels` along the unit
    /// texel-space `direction`, hits with travel in [0, maxTravelTexels] only; nothing for a
    /// miss. A reference render takes the hits and normals of camera and shadow-map rays from it
    /// instead of sphere tracing analyticDistance, which it still needs for self-shadows. Empty:
    /// the reference render sphere traces analyticDistance.
    std::function<std::optional<DetailHit>(const glm::dvec3& originTexels,
                                           const glm::dvec3& direction, double maxTravelTexels)>
        exactHit;
};

/// A colour texture's bilinear albedo at base-mesh uv (texel centres at (i + 0.5) / size, row 0
/// at v = 1, wrapping in both directions).
glm::vec3 textureAlbedoAt(const Image& colorTexture, const glm::vec2& uv);

/// The material's albedo at base-mesh uv: the colour texture there, else the constant colour.
inline glm::vec3 albedoAt(const Material& material, const glm::vec2& uv) {
    return material.colorTexture ? textureAlbedoAt(*material.colorTexture, uv) : material.color;
}

struct SceneObject {
    BaseMesh mesh;  ///< in world space (transforms already applied)
    Material material;
};

struct Scene {
    Camera camera;
    std::vector<DirectionalLight> lights{DirectionalLight{}};
    std::vector<SceneObject> objects;
};

/// Placement of an object: scale about the origin, then rotate about x, y, z (degrees, in that
/// order), then translate.
struct Transform {
    glm::vec3 translate{0.0f};
    glm::vec3 rotateDeg{0.0f};
    float scale = 1.0f;
};

/// Applies `transform` to positions, normals and tangents (frames stay unit and orthogonal).
/// Throws InputError::inField ("transform.scale", ...) for a non-finite transform or a scale <= 0.
void applyTransform(BaseMesh& mesh, const Transform& transform);

/// Texels per world unit along `triangle`'s u and v directions, for a tile of `tileSize` repeated
/// `uvScale` times per unit of uv (|dP/du|, |dP/dv| convert uv to world units). Zero when the
/// triangle's uvs are degenerate (their triangle has no area, or its world lengths per uv are
/// not finite): such a triangle carries no detail, and shows its bare base surface.
glm::vec2 texelsPerWorldUv(const BaseMesh& mesh, const glm::uvec3& triangle,
                           const glm::vec2& uvScale, const Size3& tileSize);

/// `direction` at unit length (a light's direction, the camera's up: only their direction
/// counts): glm::normalize where single precision can square it, in double precision beyond
/// (lengths from about 1e15 or below 1e-15), so that any finite length keeps its direction.
/// Zero stays zero.
glm::vec3 unitDirection(const glm::vec3& direction);

/// The most base-mesh triangles a scene may have in all objects together: 2^23. Rendering takes
/// about 500-650 bytes a triangle (the mesh, its BVH, the shells' prisms; measured on spheres and
/// a 1 M triangle torus), so about 5 GB at the most.
inline constexpr std::size_t kMaxSceneTriangles = std::size_t(1) << 23;

/// Throws InputError::inField("objects[index].mesh", ...) when `trianglesSoFar` (the triangles of
/// objects 0..index) exceed kMaxSceneTriangles: checked as objects are added, before the next
/// one is built.
void requireSceneTriangleBudget(std::size_t index, std::size_t trianglesSoFar);

/// The largest colour component of a scene (a light's colour, an albedo, a colour texture's
/// pixel). A pixel sums albedo x light colour over the lights and its samples: at most 1e18 x
/// 1.35 x 256 per light, finite in single precision for any number of lights that fits in memory
/// (at 1e30 each, one light gave an infinite pixel).
inline constexpr float kMaxColorComponent = 1e9f;

/// Whether `component` is an accepted colour component: in [0, kMaxColorComponent].
inline bool acceptedColorComponent(float component) {
    return component >= 0.0f && component <= kMaxColorComponent;
}
/// What acceptedColorComponent accepts, in words, for messages.
inline constexpr const char* kColorComponentRule =
    "colour components must be at least 0 and at most 1e9";

/// Throws InputError::inField, naming the Scene member ("camera.up",
/// "objects[1].material.depthWorld", ...), when the
/// scene cannot be rendered: non-finite vectors, eye == target, up parallel to the view, field of
/// view outside (0, 180), no objects, an empty mesh, depth <= 0, uv scale <= 0, a zero light
/// direction, a colour component (light or material, as "lights[0].color[1]") outside [0,
/// kMaxColorComponent], more than kMaxSceneTriangles triangles in all.
void validateScene(const Scene& scene);

}  // namespace distile
