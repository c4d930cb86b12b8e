// Drone waypoint files (`optinav sim --route drone:FILE`).
#include "fuzz/fuzz_target.h"
#include "optinav/io/waypoints.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(waypoints) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("waypoints.txt", data, size);
  try {
    io::ReadWaypointsFile(path);
  } catch (const Error&) {
  }
  return 0;
}
