/// @file
/// A tile's provenance (distile:source, distile:params, distile:source_file, distile:source_hash)
/// back to what it was baked from: the procedural options, or the source file and its placement,
/// for whoever needs the exact truth of a tile (checks, reference renders) or wants to rebuild the
/// same detail its own way.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "common/triangle_soup.h"
#include "sampler/tile.h"
#include "vdb/procedural.h"
#include "vdb/vdb_volume.h"

namespace distile {

/// The procedural options recorded in a tile's distile:source and distile:params (written by
/// vdb/procedural.h's paramsJson). Throws InputError, naming `file`, for a source without
/// analytic truth (anything but chainmail, grating); FormatError for params that are not JSON or
/// hold unknown or ill-typed fields.
ProceduralOptions proceduralFromProvenance(const TileProvenance& provenance,
                                           const std::string& file);

/// Records `file` (made absolute) and the FNV-1a 64 hash of its bytes (bake/bake_cache.h
/// contentHash) as the source file of `provenance`. Throws InputError if it cannot be read.
void recordSourceFile(TileProvenance& provenance, const std::filesystem::path& file);

/// The source file a tile records (distile:source_file), checked: it exists and its bytes still
/// have the recorded hash. `tileName` names the tile in messages; `tileFile`, when known, is the
/// file the tile was read from, so messages show the source as recorded (relative to it).
/// @throws InputError the tile records no source file (baked by an older distile, or from
///   procedural detail), the file is not found, or its bytes no longer have the recorded hash.
std::filesystem::path recordedSourceFile(const Tile& tile, const std::string& tileName,
                                         const std::filesystem::path& tileFile = {});

/// The detail mesh of a tile baked from a mesh (distile:source "mesh"), read from its recorded
/// source file and placed as the bake placed it (the scale and offset_texels in distile:params),
/// positions in texels. `tileName` names the tile in messages; `tileFile`, when known, is the file
/// the tile was read from, so messages show the source file as recorded (relative to it).
/// @throws InputError the tile is not a mesh tile or does not record its source file (baked by an
///   older distile), the recorded file is not found, or its bytes no longer have the recorded hash.
/// @throws FormatError the params do not hold a placement, or the file is not a mesh.
TriangleSoup sourceMeshPlaced(const Tile& tile, const std::string& tileName,
                              const std::filesystem::path& tileFile = {});

/// What a tile baked from a .vdb file (distile:source "vdb", bake/vdb_bake.h) records in its
/// distile:params: the grid, the iso value when one was given, and the placement as used.
struct VdbProvenance {
    std::string gridName;
    std::optional<double> iso;
    TexelPlacement placement;
};
/// @throws FormatError naming `tileName` when the params are not JSON or lack grid, scale or
///   offset.
VdbProvenance vdbFromProvenance(const TileProvenance& provenance, const std::string& tileName);

}  // namespace distile
