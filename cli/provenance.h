/// @file
/// A tile's provenance (distile:source, distile:params) back to the procedural options it was
/// baked with, for commands that need the analytic truth (check, render --reference).
#pragma once

#include <string>

#include "sampler/tile.h"
#include "vdb/procedural.h"

namespace distile::cli {

/// The procedural options recorded in a tile's distile:source and distile:params (written by
/// vdb/procedural.h's paramsJson). Throws InputError, naming `file`, for a source without
/// analytic truth (anything but chainmail, grating); FormatError for params that are not JSON or
/// hold unknown or ill-typed fields.
ProceduralOptions proceduralFromProvenance(const TileProvenance& provenance,
                                           const std::string& file);

}  // namespace distile::cli
