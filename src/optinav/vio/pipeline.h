// The data provider and the run loop: reads a EuRoC/ASL dataset (or an AirSim recording) through
// the io layer, pairs
// left/right images (same stamp within 1 ms; unpaired frames are skipped with a warning), feeds
// the IMU up to each frame and runs the estimator.
//   sequential mode: one thread, deterministic (tests, benchmarks);
//   threaded mode:   a loader thread (csv + image decoding) feeds the estimator thread through a
//                    bounded ThreadSafeQueue; results are identical (the estimator itself is
//                    sequential), only faster.
// The IMU (imu0 T_BS) is rotated into the body frame; body = IMU in EuRoC.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "optinav/geometry/trajectory.h"
#include "optinav/util/timer.h"
#include "optinav/vio/estimator.h"

namespace optinav::vio {

struct VioRunOptions {
  VioOptions vio;
  // GNSS fusion (stereo-imu only): the options and the samples (ENU), fed in time order.
  std::optional<GnssFusionOptions> gnss;
  std::vector<GnssSample> gnss_samples;
  bool threaded = false;
  size_t max_frames = 0;  // 0: all
  // false: a listed but missing image is an Error; true: the frame is skipped with a warning.
  bool skip_missing_images = true;
  // AirSim recordings carry no calibration: the weather document's rig (rectified pinhole).
  double airsim_hfov_deg = 90.0;
  double airsim_baseline_m = 0.52;
};

struct VioRunResult {
  std::vector<FrameEstimate> estimates;
  std::vector<LostInterval> lost;
  std::map<std::string, TimingSummary> timing;  // per module, seconds per frame
  size_t frames_total = 0, frames_processed = 0, frames_unpaired = 0;
  int initializations = 0;
  std::string first_init_kind;
  Rigid3d body_from_cam0;
  // With GNSS.
  std::vector<RejectedGnss> gnss_rejected;
  GnssFusionStats gnss_stats;
};

// Throws Error (naming file/line/field) on bad input: layout, calibration, unreadable images or
// images of the wrong size.
VioRunResult RunVioOnEuroc(const std::string& dataset_dir, const VioRunOptions& options);
// An AirSim recording (io/airsim_recording.h), stereo-only (it has no IMU): left/right images by
// name, the rig from airsim_hfov_deg / airsim_baseline_m, the camera mounting from
// camera_info.csv when present (else looking along the body x axis).
VioRunResult RunVioOnAirsim(const std::string& dataset_dir, const VioRunOptions& options);

// The estimates as a trajectory of the body frame, or of the left camera with body_from_cam.
Trajectory EstimatesToTrajectory(const std::vector<FrameEstimate>& estimates,
                                 const std::optional<Rigid3d>& body_from_cam = std::nullopt);
// With GNSS: the estimates in ENU, each through the alignment known right after its frame (what
// a live system outputs); frames before the first alignment use the first one. Empty when no
// alignment was ever made.
Trajectory EstimatesToEnuTrajectory(const std::vector<FrameEstimate>& estimates,
                                    const std::optional<Rigid3d>& body_from_cam = std::nullopt);

}  // namespace optinav::vio
