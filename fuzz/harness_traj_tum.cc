// TUM trajectories ("t x y z qx qy qz qw"): the explicit reader and format detection.
#include "fuzz/fuzz_target.h"
#include "optinav/io/trajectory_io.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(traj_tum) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("traj_tum.txt", data, size);
  try {
    io::ReadTrajectory(path, {.format = io::TrajectoryFormat::kTum});
  } catch (const Error&) {
  }
  try {
    io::ReadTrajectory(path);  // auto: detection, then whichever reader it picks
  } catch (const Error&) {
  }
  return 0;
}
