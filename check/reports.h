/// @file
/// The JSON reports of `distile check --json` and `distile compare --json` (docs/reports.md):
/// one object each, the same for the command and the Python module.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "check/tile_check.h"
#include "render/compare.h"

namespace distile {

/// The report of `check`: the figures of `check`, the options it was judged by and `tileName`.
nlohmann::json tileCheckJson(const TileCheck& check, const TileCheckOptions& options,
                             const std::string& tileName);

/// How `compare` splits the pixels where both renders hit into silhouette and interior pixels.
extern const char* const kSilhouetteRule;

/// The figures of `comparison`: coverage, hit error per class (interior, silhouette, all),
/// PSNR (null when infinite: the images are identical).
nlohmann::json renderComparisonJson(const RenderComparison& comparison);

/// `report` as one line of JSON text. Bytes of a file name that are not UTF-8 (Linux names are
/// any bytes) become U+FFFD rather than an exception.
inline std::string reportText(const nlohmann::json& report) {
    return report.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace distile
