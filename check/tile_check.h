/// @file
/// How far a tile is from its truth: the analytic distance of procedural detail, the exact
/// distance to a detail mesh, or a level set (docs/reports.md), sampled at uniform random points
/// (sampler/tile_error.h) and judged against tolerances.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <glm/vec3.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sampler/tile.h"
#include "sampler/tile_error.h"

namespace distile {

struct TileCheckOptions {
    /// The truth: empty for the tile's own (the analytic truth of procedural detail, or the
    /// mesh, height map or .vdb file a tile records as its source, placed or triangulated as it
    /// was baked); "analytic"; a
    /// detail mesh file (OBJ, PLY, OFF, STL; placed as `bake mesh` places it, or by meshScale
    /// and meshOffsetTexels); or a level set (.vdb).
    std::string against;
    int samples = 100000;  ///< uniform random points, in [1, 10^7]
    std::uint64_t seed = 1;
    double maxOverestimateTexels = 0.05;  ///< tile - truth above it is an overestimate
    double maxOverestimateShare = 0.001;  ///< largest accepted share of overestimates
    double maxRmsTexels = 0.1;
    /// Largest accepted tile - max(truth, 0): how far a sphere tracer can step past the surface.
    /// The share above catches spread error; this catches a local one, such as a few damaged
    /// texels (good tiles stay near maxOverestimateTexels).
    double maxTracerOverestimateTexels = 1.0;
    std::optional<double>
        maxNearErrorTexels;  ///< within 2 texels of the surface; unchecked if unset
    bool allowSignErrors = false;
    /// Mesh truth, explicit placement: texels per file unit and where the file's origin goes
    /// (texels); either given means explicit placement (scale 1, offset 0 by default).
    std::optional<double> meshScale;
    std::optional<std::array<double, 3>> meshOffsetTexels;
};

struct TileCheck {
    std::string against;  ///< which truth, in words ("analytic chainmail {...}", "mesh ...")
    TileErrorReport report;
    double bandTexels = 0.0;            ///< the truth is clamped to +-this (the tile's band)
    bool bandDeclared = false;          ///< the tile declares its band (else: its depth)
    std::vector<std::string> failures;  ///< one sentence per tolerance exceeded
    /// The truth measured against: signed distance in texels at a texel position, unclamped;
    /// owns what it needs (`check --plot` draws tile - truth with it). Thread-safe.
    std::function<double(const glm::dvec3&)> truth;
    bool passed() const { return failures.empty(); }
};

/// Measures `tile` against its truth and judges the figures by `options`' tolerances.
/// `tileName` names the tile in messages; `tileFile`, when the tile was read from a file, is that
/// file (recorded source files are relative to it). Throws InputError::inField naming
/// "against" (the truth cannot be found, or does not fit the tile), "samples",
/// "maxOverestimateTexels", "meshScale" or "meshOffsetTexels"; FormatError when the tile's
/// params do not describe a valid pattern; as the mesh and level-set readers do.
TileCheck checkTile(const Tile& tile, const std::string& tileName,
                    const std::filesystem::path& tileFile, const TileCheckOptions& options);

/// Checks a tile of procedural detail (chain mail, grating) against its analytic truth as
/// `distile check` does by default, and records the verdict in tile.provenance.check
/// (distile:check), so the figures travel with the tile: to a file, to the bake cache, to whoever
/// renders it. Throws as checkTile (InputError for a tile without analytic truth).
TileCheck recordAnalyticCheck(Tile& tile);

/// For a tile whose recorded check (TileProvenance::check) found it beyond the tolerances: a
/// warning naming the tile `tileName`, the figures, and what a tile holds poorly (callers add
/// the remedy in their own terms). Empty for any other tile.
std::string recordedCheckWarning(const Tile& tile, const std::string& tileName);

}  // namespace distile
