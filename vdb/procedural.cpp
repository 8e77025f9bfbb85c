#include "vdb/procedural.h"

#include <memory>

namespace distile {

const char* proceduralSourceName(ProceduralKind kind) {
    return kind == ProceduralKind::Grating ? "grating" : "chainmail";
}

ProceduralDistance proceduralDistance(const ProceduralOptions& options, const Size3& tile) {
    ProceduralDistance result;
    result.source = proceduralSourceName(options.kind);
    if (options.kind == ProceduralKind::Grating) {
        auto grating = std::make_shared<const Grating>(options.grating, tile);
        result.paramsJson = grating->paramsJson();
        result.signedDistanceTexels = [grating](const glm::dvec3& p) {
            return grating->signedDistanceTexels(p);
        };
    } else {
        auto chainmail = std::make_shared<const Chainmail>(options.chainmail, tile);
        result.paramsJson = chainmail->paramsJson();
        result.signedDistanceTexels = [chainmail](const glm::dvec3& p) {
            return chainmail->signedDistanceTexels(p);
        };
    }
    return result;
}

}  // namespace distile
