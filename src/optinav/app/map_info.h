// Summary of a map database (`optinav map info`): size, extent, CRS, tile grid and features.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "optinav/maploc/map_db.h"

namespace optinav::app {

// Keys: format_version, ortho, crs, width_px, height_px, map_gsd_m, extent_m [w, h],
// upper_left and lower_right [lat, lon], tiles {cols, rows, count, padded, side_px, step_px},
// features {type, total, min_per_tile, max_per_tile}, feature_gsd_m.
nlohmann::json MapInfoJson(const maploc::MapDatabase& db);

// The same as a few aligned lines, headed by the database's `path`.
std::string MapInfoText(const std::string& path, const maploc::MapDatabase& db);

// `map info --check`: what was verified, one line ("check: ok, ...").
std::string MapCheckText(const maploc::MapCheckReport& report);
nlohmann::json MapCheckJson(const maploc::MapCheckReport& report);

}  // namespace optinav::app
