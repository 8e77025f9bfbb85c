/// @file
/// Internal to distile_peers: the one kind of scene the peers render (a "sheet", see peers.h)
/// and the affine map between its world space and its texel space.
#pragma once

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <string>
#include <variant>

#include "bench/peers/peers.h"
#include "common/size3.h"
#include "render/scene.h"
#include "vdb/chainmail.h"

namespace distile::detail {

/// A planar base mesh with chain mail. "Sheet texel space" spans all tile repeats: the texel
/// space of tile repeat (i, j) shifted by (i W, j H), i.e. x = u uvScale.x W, y = v uvScale.y H,
/// z = D on the base surface and 0 on the floor (the tracer's convention, render/tracer.cpp).
struct SheetPlacement {
    ChainmailOptions chainmail;
    Size3 tile{0, 0, 0};
    glm::dvec3 originWorld{0.0};       ///< the base surface at uv (0, 0)
    glm::dvec3 worldPerU{0.0};         ///< dP/du, world units (orthogonal to worldPerV)
    glm::dvec3 worldPerV{0.0};         ///< dP/dv
    glm::dvec3 normal{0.0, 0.0, 1.0};  ///< unit, outward; (dP/du, dP/dv, N) is right-handed
    glm::dvec2 uvScale{1.0};
    double depthWorld = 0.0;
    glm::dvec2 uvMin{0.0}, uvMax{0.0};  ///< the base mesh's uv bounding rectangle
    glm::dvec3 texelsPerWorld{0.0};     ///< along dP/du, dP/dv and N

    glm::dvec3 worldFromTexel(const glm::dvec3& sheetTexel) const;
    glm::dvec3 texelFromWorld(const glm::dvec3& world) const;
    /// A world direction (or normal: the map is a rotation times a scale per axis) in texel space.
    glm::dvec3 texelDirection(const glm::dvec3& world) const;
    /// True when the point's uv (projected on the base plane) lies in [uvMin, uvMax].
    bool inFootprint(const glm::dvec3& world) const;
};

/// The sheet of `scene`, or why the scene is not one ("not available: ...").
std::variant<SheetPlacement, std::string> findSheet(const Scene& scene);

/// Throws InputError unless width and height are in [1, 16384] and threads in [1, 256].
void validatePeerRequest(int width, int height, int threads);

/// A PeerRender named `name`, not available for `reason`.
PeerRender unavailablePeer(const std::string& name, const std::string& reason);

}  // namespace distile::detail
