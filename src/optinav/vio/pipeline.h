// The data provider and the run loop: reads a EuRoC/ASL dataset (or an AirSim recording) through
// the io layer, pairs
// left/right images (same stamp within 1 ms; unpaired frames are skipped with a warning), feeds
// the IMU up to each frame and runs the estimator.
//   sequential mode: one thread, deterministic (same input, same output; tests, benchmarks):
//                    load a frame, VioEstimator::ProcessFrame (frontend step then backend step);
//   threaded mode:   three threads joined by bounded ThreadSafeQueues (8 packets each):
//                    loader (csv + image decoding) -> frontend (VioEstimator::RunFrontend:
//                    tracking, stereo matching, IMU preintegration) -> backend
//                    (VioEstimator::RunBackend: initialisation, sliding window, failure handling,
//                    GNSS; GNSS samples travel with the frames, in time order). The backend's
//                    feedback (initialised or not, newest bias, rejected tracks) reaches the
//                    frontend through a mailbox read when a message is there, so the frontend
//                    may use feedback a few frames old: results are close to the sequential
//                    ones but not identical, and may vary from run to run.
//                    An exception in any thread stops all three (queues closed), they are joined
//                    and it is rethrown to the caller.
// Timing ("frontend", "backend", "backend_keyframe", "total"): "total" is the work of both
// steps on a frame (in threaded mode their sum, excluding queue waits), not the latency.
// The IMU (imu0 T_BS) is rotated into the body frame; body = IMU in EuRoC.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "optinav/geometry/trajectory.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/util/timer.h"
#include "optinav/vio/estimator.h"
#include "optinav/vio/gnss_smoother.h"

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
  // AirSim recordings carry no calibration: the rig of the AirSim weather dataset (SEEDS.md
  // part 1: rectified pinhole).
  double airsim_hfov_deg = 90.0;
  double airsim_baseline_m = 0.52;
  // Tests and benchmarks: the backend step sleeps this long on every keyframe (an artificially
  // slow backend; the result must not change, only the latency).
  double injected_backend_delay_ms = 0;
};

struct VioRunResult {
  std::vector<FrameEstimate> estimates;
  std::vector<LostInterval> lost;
  // Index in `estimates` of the first estimate of each VIO track after the first (a
  // re-initialisation starts a new world frame; with an in-motion start its first estimates are
  // dated before the LostInterval's end_ns).
  std::vector<size_t> track_starts;
  // Per module, seconds per frame; "latency": from the frontend step taking the frame to its
  // pose out (waits for feedback and between the threads included; not the time a replayed
  // frame spends queued before the frontend, which a live camera does not have; the delayed
  // estimates of an in-motion start not counted).
  std::map<std::string, TimingSummary> timing;
  size_t frames_total = 0, frames_processed = 0, frames_unpaired = 0;
  int initializations = 0;
  int frozen_frames = 0;  // skipped: identical to the previous frame (VioEstimator::frozen_frames)
  // Frames whose IMU interval the backend's PnP check found faulty (VioEstimator::imu_inflations).
  int imu_inflated_frames = 0;
  std::string first_init_kind;
  Rigid3d body_from_cam0;
  // Loop closure (VioOptions::loop_closure): `estimates` are corrected by the closed loops;
  // `odometry` holds the estimates before the correction (empty when loop closure did not run).
  bool loop_closure_ran = false;
  std::vector<LoopEdge> loops;
  // The closer's keyframes, those of them described again as faded (LoopCloser::faded_keyframes),
  // the verified loops it dropped for want of support (LoopCloser::unsupported_loops) and at
  // places that repeat (LoopCloser::aliased_loops).
  size_t loop_keyframes = 0, loop_faded_keyframes = 0, loops_unsupported = 0, loops_aliased = 0;
  std::vector<FrameEstimate> odometry;
  // With GNSS.
  std::vector<RejectedGnss> gnss_rejected;
  GnssFusionStats gnss_stats;
  // enu_from_world per estimate, smoothed over the run (GnssFusionOptions::smooth; else the live
  // alignments): EstimatesToEnuTrajectory(estimates, gnss_smoothing.enu_from_world) is the fused
  // output, EstimatesToEnuTrajectory(estimates) the live one.
  GnssSmoothing gnss_smoothing;
};

// Throws Error (naming file/line/field) on bad input: layout, calibration, unreadable images or
// images of the wrong size.
VioRunResult RunVioOnEuroc(const std::string& dataset_dir, const VioRunOptions& options);
// An AirSim recording (io/airsim_recording.h), stereo-only (it has no IMU): left/right images by
// name, the rig from airsim_hfov_deg / airsim_baseline_m, the camera mounting from
// camera_info.csv when present (else looking along the body x axis).
VioRunResult RunVioOnAirsim(const std::string& dataset_dir, const VioRunOptions& options);

// imu0 of a EuRoC dataset in the body frame: every sample rotated by its T_BS (a lever arm is
// ignored, with a warning) and the noise densities and random walks of its sensor.yaml. Throws
// Error when the dataset has no imu0 or the csv is malformed.
struct BodyImu {
  ImuNoise noise;
  std::vector<TimedImuSample> samples;
};
BodyImu ReadBodyImu(const io::EurocDataset& ds);

// The estimates as a trajectory of the body frame, or of the left camera with body_from_cam.
Trajectory EstimatesToTrajectory(const std::vector<FrameEstimate>& estimates,
                                 const std::optional<Rigid3d>& body_from_cam = std::nullopt);
// With GNSS: the estimates in ENU, each through the alignment known right after its frame (what
// a live system outputs); frames before the first alignment use the first one. Empty when no
// alignment was ever made.
Trajectory EstimatesToEnuTrajectory(const std::vector<FrameEstimate>& estimates,
                                    const std::optional<Rigid3d>& body_from_cam = std::nullopt);

}  // namespace optinav::vio
