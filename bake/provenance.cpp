#include "bake/provenance.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <span>
#include <vector>

#include "bake/bake.h"
#include "bake/bake_cache.h"
#include "common/error.h"
#include "common/fnv1a.h"
#include "mesh/detail_mesh.h"

namespace distile {

using nlohmann::json;

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
        throw InputError(file + ": distile:source '" + provenance.source +
                         "' has no analytic truth (chainmail, grating)");
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

namespace {

/// FNV-1a 64 of the bytes of `file` as contentHash gives it, read in chunks (a source mesh may
/// be a gigabyte), or nothing if it cannot be read.
std::optional<std::string> fileContentHash(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) return std::nullopt;
    Fnv1a64 hash;
    std::vector<char> chunk(std::size_t(1) << 20);
    while (in.read(chunk.data(), std::streamsize(chunk.size())) || in.gcount() > 0) {
        hash.update(std::as_bytes(std::span(chunk.data(), std::size_t(in.gcount()))));
    }
    if (in.bad()) return std::nullopt;
    return hexDigits(hash.value());
}

}  // namespace

void recordSourceFile(TileProvenance& provenance, const std::filesystem::path& file) {
    const std::optional<std::string> hash = fileContentHash(file);
    if (!hash) throw InputError(file.string() + ": cannot be read");
    provenance.sourceFile = std::filesystem::absolute(file).lexically_normal();
    provenance.sourceHash = *hash;
}

std::filesystem::path recordedSourceFile(const Tile& tile, const std::string& tileName,
                                         const std::filesystem::path& tileFile) {
    const TileProvenance& provenance = tile.provenance;
    const std::string what = "its source " + provenance.source;
    if (provenance.sourceFile.empty()) {
        throw InputError(tileName + ": does not record " + what +
                         " file (baked before tiles recorded it)");
    }
    const std::filesystem::path& file = provenance.sourceFile;
    // As recorded: relative to the tile's folder.
    const std::string recorded =
        tileFile.empty()
            ? file.string()
            : file.lexically_relative(
                      std::filesystem::absolute(tileFile).parent_path().lexically_normal())
                  .generic_string();
    std::error_code status;
    if (!std::filesystem::exists(file, status)) {
        throw InputError(tileName + ": " + what + " " + recorded + " (recorded) is not found");
    }
    if (!std::filesystem::is_regular_file(file, status)) {
        throw InputError(tileName + ": " + what + " " + recorded +
                         " (recorded) is not a regular file");
    }
    if (provenance.sourceHash.empty()) {
        throw InputError(tileName + ": records " + what + " " + recorded +
                         " without its content hash (distile:source_hash), so whether it changed "
                         "since the bake is unknown; the file was modified");
    }
    const std::optional<std::string> hash = fileContentHash(file);
    if (!hash) throw InputError(tileName + ": " + what + " " + recorded + " cannot be read");
    if (*hash != provenance.sourceHash) {
        throw InputError(tileName + ": " + what + " " + recorded +
                         " has changed since the bake (content hash " + *hash + ", recorded " +
                         provenance.sourceHash + "); bake the tile again from it");
    }
    return file;
}

TriangleSoup sourceMeshPlaced(const Tile& tile, const std::string& tileName,
                              const std::filesystem::path& tileFile) {
    const TileProvenance& provenance = tile.provenance;
    if (provenance.source != "mesh") {
        throw InputError(tileName + ": distile:source '" + provenance.source + "' is not a mesh");
    }
    const std::filesystem::path file = recordedSourceFile(tile, tileName, tileFile);
    json params;
    try {
        params = json::parse(provenance.params);
    } catch (const json::exception&) {
        throw FormatError(tileName + ": distile:params is not valid JSON: '" + provenance.params +
                          "'");
    }
    const auto isNumber = [&](const char* key) {
        return params.is_object() && params.contains(key) && params[key].is_number();
    };
    if (!isNumber("scale") || !params.contains("offset_texels") ||
        !params["offset_texels"].is_array() || params["offset_texels"].size() != 3) {
        throw FormatError(tileName +
                          ": distile:params do not record the mesh's placement (scale, "
                          "offset_texels): '" +
                          provenance.params + "'");
    }
    MeshPlacement placement;
    placement.fit = false;
    placement.scale = params["scale"].get<double>();
    for (int axis = 0; axis < 3; ++axis) {
        const json& value = params["offset_texels"][std::size_t(axis)];
        if (!value.is_number()) {
            throw FormatError(tileName + ": distile:params offset_texels must be three numbers");
        }
        placement.offsetTexels[axis] = value.get<double>();
    }
    TriangleSoup mesh;
    try {
        mesh = loadDetailMesh(file);
    } catch (const FormatError& error) {
        throw FormatError(tileName + ": its source mesh: " + error.what());
    }
    return placeMesh(mesh, placement, tile.size());
}

VdbProvenance vdbFromProvenance(const TileProvenance& provenance, const std::string& tileName) {
    VdbProvenance vdb;
    try {
        const json params = json::parse(provenance.params);
        vdb.gridName = params.at("grid").get<std::string>();
        vdb.placement.scale = params.at("scale").get<double>();
        const auto offset = params.at("offset").get<std::vector<double>>();
        vdb.placement.offsetTexels = {offset.at(0), offset.at(1), offset.at(2)};
        if (params.contains("iso")) vdb.iso = params.at("iso").get<double>();
    } catch (const std::exception& error) {
        throw FormatError(tileName + ": distile:params do not describe a vdb placement (" +
                          error.what() + ")");
    }
    return vdb;
}

}  // namespace distile
