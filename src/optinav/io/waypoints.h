// Drone waypoint files for `optinav sim --route drone:FILE`.
//
// One waypoint per line: "x, y, altitude[, yaw_deg]" (commas or blanks), x east and y north in
// metres in the simulator's world frame, altitude in metres above the ground below, yaw in
// degrees counter-clockwise from east (omitted: face along the path). '#' starts a comment.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "optinav/util/error.h"

namespace optinav::io {

struct WaypointRow {
  double x_m = 0, y_m = 0, altitude_m = 0;
  std::optional<double> yaw_deg;
};

// Throws Error naming file, line and field; needs at least 2 waypoints.
std::vector<WaypointRow> ReadWaypointsFile(const std::string& path);

}  // namespace optinav::io
