// The mission experiment behind `optinav mission` (also run by `optinav demo`): seeded runs over
// a map database, a table on stdout, summary.json, pictures and GIS files in the output folder.
#pragma once

#include <string>

#include "optinav/nav/mission.h"

namespace optinav {

struct MissionExperiment {
  std::string map, start, target, frames_from, ortho, out, weather = "none", pictures = "all";
  double min_distance_m = 3000, margin_m = 300;
  int runs = 1;
  bool force = false, no_odometry = false, save_frames = false;
  nav::MissionOptions o;
};

// Returns 0 when every run reached the target, 3 when some did not; throws Error on bad input
// (before anything is written).
int RunMissionExperiment(MissionExperiment& experiment);

}  // namespace optinav
