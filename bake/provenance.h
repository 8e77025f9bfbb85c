/// @file
/// A tile's provenance (distile:source, distile:params) back to the procedural options it was
/// baked with, for whoever needs the analytic truth of a tile (checks, reference renders) or
/// wants to rebuild the same detail its own way.
#pragma once

#include <string>

#include "sampler/tile.h"
#include "vdb/procedural.h"

namespace distile {

/// The procedural options recorded in a tile's distile:source and distile:params (written by
/// vdb/procedural.h's paramsJson). Throws InputError, naming `file`, for a source without
/// analytic truth (anything but chainmail, grating); FormatError for params that are not JSON or
/// hold unknown or ill-typed fields.
ProceduralOptions proceduralFromProvenance(const TileProvenance& provenance,
                                           const std::string& file);

}  // namespace distile
