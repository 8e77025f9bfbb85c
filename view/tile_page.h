/// @file
/// The tile's web page: one self-contained HTML file (the tile embedded as base64 half floats,
/// the reference shader shaders/distile_march.glsl inlined) that draws the tile on a plane and a
/// sphere with WebGL2, orbitable with the mouse. The query string of the page's address sets the
/// view (docs/shader.md): ?object=plane|sphere, eye=X,Y,Z, target=..., up=..., fov=DEGREES,
/// plane_size, uv_scale=U,V, depth, sphere_uv_scale, sphere_depth, light, color, floor=solid|open,
/// and output=depth to write the hit depth instead of the colour (24 bits over depth_range world
/// units, 16 by default), the picture a test compares with the CPU renderer's depth.
#pragma once

#include <filesystem>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <string>

#include "sampler/tile.h"

namespace distile {

/// The view the page opens with (world units, z up; the plane is the square z = 0 centred at the
/// origin, the sphere has radius 1 at the origin). The defaults are data/scenes/sheet.json's.
struct TilePageView {
    std::string object = "plane";  ///< "plane" or "sphere"
    glm::vec3 eye{0.0f, -2.1f, 1.47f};
    glm::vec3 target{0.0f, 0.0f, 0.0f};
    glm::vec3 up{0.0f, 0.0f, 1.0f};
    float fovDeg = 40.0f;  ///< vertical
    float planeSizeWorld = 4.0f;
    glm::vec2 uvScale{4.0f, 4.0f};  ///< tile repeats over the plane
    float depthWorld = 0.0625f;     ///< the plane's detail shell
    glm::vec2 sphereUvScale{8.0f, 4.0f};
    float sphereDepthWorld = 0.03f;
    glm::vec3 lightDirection{-0.4f, 0.3f, -1.0f};  ///< the direction the light travels
    glm::vec3 color{0.8f, 0.8f, 0.85f};            ///< linear RGB albedo
    bool solidFloor = true;
};

/// The page for `tile`, titled `title` (HTML-escaped here). The march skips the empty space above
/// the tile's highest detail as the CPU renderer does (sampler/occupancy.h). Throws InputError
/// (naming the TilePageView member) for an object other than plane or sphere, non-finite vectors,
/// sizes or depths <= 0, uv scales over 2^16 repeats, a plane depth over the plane's size, a
/// sphere depth over its radius, a field of view outside (0, 180), and for a distance beyond
/// half-float range (65504 texels).
std::string tilePageHtml(const Tile& tile, const std::string& title, const TilePageView& view = {});

/// tilePageHtml() written to `file` through writeAtomically. Throws as tilePageHtml, and
/// InputError when the folder of `file` does not exist.
void writeTilePage(const Tile& tile, const std::string& title, const TilePageView& view,
                   const std::filesystem::path& file);

/// The reference shader's source (shaders/distile_march.glsl) and the page's template
/// (shaders/view.html), as built into the library.
const std::string& referenceShaderSource();
const std::string& tilePageTemplate();

}  // namespace distile
