// What cli/provenance.h declares: a tile's provenance back to its procedural options.
#include "cli/provenance.h"

#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "common/error.h"

namespace distile::cli {

namespace {

using nlohmann::json;

}  // namespace

ProceduralOptions proceduralFromProvenance(const TileProvenance& provenance,
                                           const std::string& file) {
    auto fail = [&](const std::string& message) -> void {
        throw FormatError(file + ": distile:params " + message);
    };
    ProceduralOptions options;
    if (provenance.source == "chainmail") {
        options.kind = ProceduralKind::Chainmail;
    } else if (provenance.source == "grating") {
        options.kind = ProceduralKind::Grating;
    } else {
        throw InputError(
            file + ": distile:source '" + provenance.source +
            "' has no analytic truth (chainmail, grating); use --against MESH or LEVEL.vdb");
    }
    json params;
    try {
        params = json::parse(provenance.params);
    } catch (const json::exception&) {
        throw FormatError(file + ": distile:params is not valid JSON: '" + provenance.params + "'");
    }
    if (!params.is_object()) fail("must be a JSON object");
    std::set<std::string> used;
    auto number = [&](const char* key, double& target) {
        if (!params.contains(key)) return;
        used.insert(key);
        if (!params[key].is_number()) fail(std::string(key) + " must be a number");
        target = params[key].get<double>();
    };
    auto integer = [&](const char* key, int& target) {
        double value = target;
        number(key, value);
        if (value != std::floor(value) || std::abs(value) > 1e6)
            fail(std::string(key) + " must be a whole number");
        target = int(value);
    };
    if (options.kind == ProceduralKind::Chainmail) {
        ChainmailOptions& chainmail = options.chainmail;
        if (params.contains("weave")) {
            used.insert("weave");
            const std::string weave =
                params["weave"].is_string() ? params["weave"].get<std::string>() : "";
            if (weave == "japanese4in1") {
                chainmail = japanese4in1Defaults();
            } else if (weave != "european4in1") {
                fail("weave '" + params["weave"].dump() +
                     "' is not accepted; accepted: european4in1, japanese4in1");
            }
        }
        integer("rings_per_row", chainmail.ringsPerRow);
        integer("rows_per_tile", chainmail.rowsPerTile);
        number("ring_radius_spacings", chainmail.ringRadiusSpacings);
        number("wire_radius_spacings", chainmail.wireRadiusSpacings);
        number("tilt_deg", chainmail.tiltDeg);
        number("small_ring_radius_spacings", chainmail.smallRingRadiusSpacings);
        number("small_wire_radius_spacings", chainmail.smallWireRadiusSpacings);
    } else {
        GratingOptions& grating = options.grating;
        integer("bars_per_tile", grating.barsPerTile);
        number("bar_width_texels", grating.barWidthTexels);
        number("bar_height_texels", grating.barHeightTexels);
        number("edge_radius_texels", grating.edgeRadiusTexels);
        number("layer_gap_texels", grating.layerGapTexels);
    }
    for (const auto& [key, unused] : params.items()) {
        if (!used.count(key)) fail("has an unknown field '" + key + "' for " + provenance.source);
    }
    return options;
}

}  // namespace distile::cli
