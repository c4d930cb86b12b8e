// Parsing helpers shared by the subcommands.
#pragma once

#include <string>

#include "optinav/geo/geo.h"

namespace optinav {

// "LAT,LON" (degrees) -> LatLon; throws Error naming `option` when malformed or out of range.
geo::LatLon ParseLatLon(const std::string& text, const std::string& option);

// Makes `dir` ready for a command's outputs: creates it, or refuses (Error) when it exists and
// is not empty unless `force`.
void PrepareOutputDir(const std::string& dir, bool force, const std::string& option = "--out");

}  // namespace optinav
