// KITTI trajectories (12 numbers per line) with an optional times file: the input is
// "POSES@@times@@\nTIMES" (no separator: no times file).
#include "fuzz/fuzz_target.h"
#include "optinav/io/trajectory_io.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(traj_kitti) {
  fuzz::QuietLibraries();
  const auto [poses, times] = fuzz::SplitInput(data, size, "@@times@@\n");
  const std::string path = fuzz::WriteScratch("traj_kitti.txt", poses);
  io::TrajectoryReadOptions options{.format = io::TrajectoryFormat::kKitti};
  if (times.data() != nullptr)
    options.kitti_times_path = fuzz::WriteScratch("kitti_times.txt", times);
  try {
    io::ReadTrajectory(path, options);
  } catch (const Error&) {
  }
  return 0;
}
