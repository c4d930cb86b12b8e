// EuRoC/ASL trajectory csv ("timestamp [ns], px, py, pz, qw, qx, qy, qz[, ...]").
#include "fuzz/fuzz_target.h"
#include "optinav/io/trajectory_io.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(traj_euroc) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("traj_euroc.csv", data, size);
  try {
    io::ReadTrajectory(path, {.format = io::TrajectoryFormat::kEuroc});
  } catch (const Error&) {
  }
  try {
    io::DetectTrajectoryFormat(path);
  } catch (const Error&) {
  }
  return 0;
}
