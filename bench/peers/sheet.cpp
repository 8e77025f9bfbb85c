#include "bench/peers/sheet.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <optional>

#include "bake/provenance.h"
#include "common/error.h"

namespace distile::detail {

glm::dvec3 SheetPlacement::worldFromTexel(const glm::dvec3& sheetTexel) const {
    const double u = sheetTexel.x / (uvScale.x * tile.width);
    const double v = sheetTexel.y / (uvScale.y * tile.height);
    return originWorld + worldPerU * u + worldPerV * v -
           normal * (depthWorld * (1.0 - sheetTexel.z / tile.depth));
}

glm::dvec3 SheetPlacement::texelFromWorld(const glm::dvec3& world) const {
    const glm::dvec3 relative = world - originWorld;
    const double u = glm::dot(relative, worldPerU) / glm::dot(worldPerU, worldPerU);
    const double v = glm::dot(relative, worldPerV) / glm::dot(worldPerV, worldPerV);
    return {u * uvScale.x * tile.width, v * uvScale.y * tile.height,
            tile.depth + glm::dot(relative, normal) * texelsPerWorld.z};
}

glm::dvec3 SheetPlacement::texelDirection(const glm::dvec3& world) const {
    return {glm::dot(world, glm::normalize(worldPerU)) * texelsPerWorld.x,
            glm::dot(world, glm::normalize(worldPerV)) * texelsPerWorld.y,
            glm::dot(world, normal) * texelsPerWorld.z};
}

bool SheetPlacement::inFootprint(const glm::dvec3& world) const {
    const glm::dvec3 relative = world - originWorld;
    const double u = glm::dot(relative, worldPerU) / glm::dot(worldPerU, worldPerU);
    const double v = glm::dot(relative, worldPerV) / glm::dot(worldPerV, worldPerV);
    return u >= uvMin.x && u <= uvMax.x && v >= uvMin.y && v <= uvMax.y;
}

std::variant<SheetPlacement, std::string> findSheet(const Scene& scene) {
    if (scene.objects.size() != 1) {
        return "not available: the peers render scenes of exactly one object (this one has " +
               std::to_string(scene.objects.size()) + ")";
    }
    const SceneObject& object = scene.objects.front();
    const Material& material = object.material;
    if (!material.tile) return std::string("not available: objects[0] has no tile");
    // The chain-mail options the tile was baked with, from its provenance.
    std::optional<ProceduralOptions> procedural;
    try {
        procedural =
            proceduralFromProvenance(material.tile->provenance, "objects[0].material.tile");
    } catch (const std::exception&) {
        // Not procedural, or params that cannot be read: not chain mail the peers can rebuild.
    }
    if (!procedural || procedural->kind != ProceduralKind::Chainmail ||
        procedural->chainmail.weave != ChainmailWeave::European4in1) {
        return std::string(
            "not available: objects[0].material.tile is not procedural European 4-in-1 chain "
            "mail (its provenance)");
    }
    const BaseMesh& mesh = object.mesh;
    if (mesh.triangles.empty()) return std::string("not available: objects[0] has no triangles");

    SheetPlacement sheet;
    sheet.chainmail = procedural->chainmail;
    sheet.tile = material.tile->size();
    sheet.uvScale = glm::dvec2(material.uvScale);
    sheet.depthWorld = material.depthWorld;
    // The affine uv -> world map of the first triangle; every vertex must follow it.
    const glm::uvec3 first = mesh.triangles.front();
    const glm::dvec3 p0(mesh.positions[first[0]]);
    const glm::dvec3 edge1 = glm::dvec3(mesh.positions[first[1]]) - p0;
    const glm::dvec3 edge2 = glm::dvec3(mesh.positions[first[2]]) - p0;
    const glm::dvec2 uv0(mesh.uvs[first[0]]);
    const glm::dvec2 duv1 = glm::dvec2(mesh.uvs[first[1]]) - uv0;
    const glm::dvec2 duv2 = glm::dvec2(mesh.uvs[first[2]]) - uv0;
    const double determinant = duv1.x * duv2.y - duv2.x * duv1.y;
    if (std::abs(determinant) < 1e-12) return std::string("not available: degenerate uvs");
    sheet.worldPerU = (edge1 * duv2.y - edge2 * duv1.y) / determinant;
    sheet.worldPerV = (edge2 * duv1.x - edge1 * duv2.x) / determinant;
    sheet.originWorld = p0 - sheet.worldPerU * uv0.x - sheet.worldPerV * uv0.y;
    const double lengthU = glm::length(sheet.worldPerU);
    const double lengthV = glm::length(sheet.worldPerV);
    sheet.normal = glm::normalize(glm::cross(sheet.worldPerU, sheet.worldPerV));
    if (std::abs(glm::dot(sheet.worldPerU, sheet.worldPerV)) > 1e-5 * lengthU * lengthV)
        return std::string("not available: the uv axes of objects[0] are not orthogonal");
    const double tolerance = 1e-5 * std::max(lengthU, lengthV);
    sheet.uvMin = glm::dvec2(mesh.uvs.front());
    sheet.uvMax = sheet.uvMin;
    for (std::size_t vertex = 0; vertex < mesh.positions.size(); ++vertex) {
        const glm::dvec2 uv(mesh.uvs[vertex]);
        const glm::dvec3 expected =
            sheet.originWorld + sheet.worldPerU * uv.x + sheet.worldPerV * uv.y;
        if (glm::length(glm::dvec3(mesh.positions[vertex]) - expected) > tolerance)
            return std::string(
                "not available: objects[0] is not a planar, affinely uv-mapped mesh");
        if (glm::dot(glm::dvec3(mesh.normals[vertex]), sheet.normal) < 1.0 - 1e-6) {
            return std::string(
                "not available: the normals of objects[0] are not those of a plane with "
                "right-handed uvs");
        }
        sheet.uvMin = glm::min(sheet.uvMin, uv);
        sheet.uvMax = glm::max(sheet.uvMax, uv);
    }
    sheet.texelsPerWorld = {sheet.tile.width * sheet.uvScale.x / lengthU,
                            sheet.tile.height * sheet.uvScale.y / lengthV,
                            sheet.tile.depth / sheet.depthWorld};
    return sheet;
}

void validatePeerRequest(int width, int height, int threads) {
    auto reject = [](const std::string& what, int value, const std::string& accepted) {
        throw InputError(what + ": " + std::to_string(value) + " is not accepted; " + accepted);
    };
    if (width < 1 || width > 16384) reject("width", width, "it must be in [1, 16384]");
    if (height < 1 || height > 16384) reject("height", height, "it must be in [1, 16384]");
    if (threads < 1 || threads > 256) reject("threads", threads, "it must be in [1, 256]");
}

PeerRender unavailablePeer(const std::string& name, const std::string& reason) {
    PeerRender peer;
    peer.name = name;
    peer.unavailableReason = reason;
    return peer;
}

}  // namespace distile::detail
