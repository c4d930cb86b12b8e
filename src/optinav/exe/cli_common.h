// Parsing helpers shared by the subcommands.
#pragma once

#include <string>

#include "optinav/geo/geo.h"

namespace optinav {

// "LAT,LON" (degrees) -> LatLon; throws Error naming `option` when malformed or out of range.
geo::LatLon ParseLatLon(const std::string& text, const std::string& option);
// "A,B,C" -> three finite numbers; throws Error naming `option` when malformed.
Eigen::Vector3d ParseTriple(const std::string& text, const std::string& option);

}  // namespace optinav
