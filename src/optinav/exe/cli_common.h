// Parsing helpers shared by the subcommands.
#pragma once

#include <string>
#include <vector>

#include "optinav/geo/geo.h"

namespace optinav {

// "LAT,LON" (degrees) -> LatLon; throws Error naming `option` when malformed or out of range.
geo::LatLon ParseLatLon(const std::string& text, const std::string& option);
// "A,B,..." -> exactly `count` finite numbers; throws Error naming `option` and the expected
// `form` (e.g. "A,B,C") when malformed.
std::vector<double> ParseNumbers(const std::string& text, size_t count, const std::string& form,
                                 const std::string& option);
// "A,B,C" -> three finite numbers; throws Error naming `option` when malformed.
Eigen::Vector3d ParseTriple(const std::string& text, const std::string& option);

}  // namespace optinav
