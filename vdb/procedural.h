/// @file
/// The procedural detail distile can bake, under one name each, with uniform access to their
/// exact signed distance (texels, texel space, periodic in x and y) for baking and for checking
/// a tile against its analytic truth. The options structs are filled by the caller (the command
/// line or the JSON in a tile's distile:params, parsed in cli/); this module never parses text.
#pragma once

#include <functional>
#include <glm/vec3.hpp>
#include <string>

#include "common/size3.h"
#include "vdb/chainmail.h"
#include "vdb/grating.h"

namespace distile {

/// Which pattern; the tile's distile:source is proceduralSourceName() of it.
enum class ProceduralKind { Chainmail, Grating };

struct ProceduralOptions {
    ProceduralKind kind = ProceduralKind::Chainmail;
    ChainmailOptions chainmail;  ///< used when kind == Chainmail (weave included)
    GratingOptions grating;      ///< used when kind == Grating
};

/// "chainmail" or "grating": the distile:source of tiles baked from the pattern.
const char* proceduralSourceName(ProceduralKind kind);

/// An exact signed distance (texels) of a validated pattern, safe to call from several threads.
struct ProceduralDistance {
    std::function<double(const glm::dvec3& texelPosition)> signedDistanceTexels;
    std::string source;      ///< proceduralSourceName(kind)
    std::string paramsJson;  ///< the pattern's options as one-line JSON (provenance)
};

/// Builds the pattern for `tile`. Throws InputError as the pattern's constructor does
/// (vdb/chainmail.h, vdb/grating.h).
ProceduralDistance proceduralDistance(const ProceduralOptions& options, const Size3& tile);

}  // namespace distile
