// The visual-inertial estimator: frontend + initialisation + backend + failure handling, fed
// one IMU sample or stereo frame at a time (sequential and deterministic: same input, same
// output). The data provider in pipeline.h drives it.
//
// A frame goes through two steps that may run in two threads (pipeline.h, threaded mode):
//   RunFrontend (frontend side: feature tracking, stereo matching, frame/IMU gap checks, the IMU
//     preintegration since the previous frame) -> a FramePacket;
//   RunBackend (backend side: initialisation, the sliding window, failure handling, GNSS) on it.
// ProcessFrame runs both in order. The backend's feedback to the frontend (whether it is
// initialised, its newest bias for the gyro prediction and the preintegration, the track ids it
// rejected) is numbered by packet: the frontend step of packet n uses the backend's state after
// packet n - feedback_lag_frames, waiting for it when the backend is behind. What the frontend
// sees therefore depends on packet numbers only, never on how busy the threads are: the threaded
// pipeline gives exactly the sequential result, whatever the load (a slow backend makes the
// frontend wait instead of tracking with stale feedback). The backend re-preintegrates the IMU
// when the packet's bias is not its current one (with a lag above 1).
// Thread use: RunFrontend and AddImu from one thread, RunBackend, AddGnss and Finish from one
// (possibly other) thread; the accessors below after both stopped.
//
// Initialisation (stereo-imu): when the IMU window before a frame is still (standard deviations
// of the 0.1 s block means of gyro and accel under thresholds), gravity is the mean specific force,
// the gyro bias the mean angular rate, velocity zero ("static"). Otherwise ("in motion", when
// motion_init_window_s > 0) a stereo-only odometry (a second backend without IMU) runs for
// motion_init_window_s; its poses and the IMU preintegrated between them give the gyro bias,
// gravity and the velocities in closed form (vi_alignment.h). The window then starts at the first
// frame of that run with those values as priors ("in-motion-aligned") and the run's frames are
// re-run through it with the IMU (so the odometry's own errors do not become priors); their
// estimates are output once the alignment succeeds (TakeDelayedEstimates).
// A run whose alignment fails slides on (its oldest half dropped). One that passes starts only
// when the next window, slid by half, agrees with it on gravity (motion_init_agreement_*); both
// are then aligned together. With motion_init_window_s = 0
// ("in-motion-priors"): attitude from the mean specific force over the window, velocity left to
// the window to estimate, with loose priors on tilt and velocity and a tight one on the
// accelerometer bias.
// In stereo mode the first pose is the identity (the world is the first body frame) and the pose
// prior is tight.
// Failure handling: a frame-time jump, an IMU gap, too few constrained landmarks for too long, or
// a diverging estimate (speed, biases, non-finite values) ends the current track: the lost
// interval is recorded with its reason, the backend restarts, and the estimator re-initialises
// at the next usable frame, continuing from the last good position and yaw.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "optinav/camera/camera.h"
#include "optinav/util/queue.h"
#include "optinav/util/timer.h"
#include "optinav/vio/backend.h"
#include "optinav/vio/gnss_fusion.h"
#include "optinav/vio/internal/frontend.h"
#include "optinav/vio/internal/loop_closure.h"
#include "optinav/vio/internal/vi_alignment.h"

namespace optinav::vio {

enum class VioMode { kStereoImu, kStereo };
std::optional<VioMode> ParseVioMode(const std::string& name);  // "stereo-imu" | "stereo"
std::string VioModeName(VioMode mode);

struct VioOptions {
  VioMode mode = VioMode::kStereoImu;
  FrontendOptions frontend;
  BackendOptions backend;
  LoopClosureOptions loop_closure;  // run by the pipeline (vio/pipeline.h)
  // Stereo-only mode: the backend's outlier threshold (pixels; YAML backend.
  // stereo_only_outlier_pixels; 0: backend.outlier_pixels). At 400x300 KLT tracks drift by a few
  // pixels without failing the forward-backward check, and without IMU nothing else holds the
  // poses against them; the frontend replaces the rejected tracks (simulated car route: 4 px ->
  // 2 px, docs/VIO.md).
  double stereo_only_outlier_pixels = 2.0;
  // Stereo-only mode: BackendOptions::stereo_only_pnp_gate_pixels and ..._median_factor (YAML
  // backend.stereo_only_pnp_gate_pixels, backend.stereo_only_pnp_gate_median_factor; 0: off,
  // the default). Landmarks are gated before the solve on a RANSAC PnP pose of the new frame.
  // Off: on the car routes it did not change what the stereo odometry does in leaves, fog or
  // dust (docs/VIO.md weather, 2026-12-05 night).
  double stereo_only_pnp_gate_pixels = 0.0;
  double stereo_only_pnp_gate_median_factor = 0.0;
  // Stereo-only mode: the solver's first trust-region radius and function tolerance (YAML
  // backend.stereo_only_*). The stereo-inertial defaults (1e6, 1e-4) make the window converge
  // with the IMU; without it the car route drifts more with them (mean 4.5 m against 2.9 m with
  // Ceres' 1e4 and 1e-6, docs/VIO.md).
  double stereo_only_initial_trust_region_radius = 1e4;
  double stereo_only_function_tolerance = 1e-6;
  // Stereo-only mode: BackendOptions::marginalize_tracked_landmarks (YAML backend.
  // stereo_only_marginalize_tracked_landmarks; backend.marginalize_tracked_landmarks is the
  // stereo-inertial one). Off: on the weather suite in stereo mode (seed 1) it made 26 of 36
  // routes better (urban within 1.71 m 14 -> 17 of 24), but the 21 s clear segment of
  // vio/sim_accuracy CarStereoOnly worse (0.35 -> 0.58 m, past its guard); with the IMU the yaw
  // drifted more (fog 100 % 1.74 -> 4.09 m). docs/VIO.md weather 2026-12-04 (later).
  bool stereo_only_marginalize_tracked_landmarks = false;
  // Stereo-only mode: BackendOptions::anchored_observations_per_landmark (YAML backend.
  // stereo_only_anchored_observations_per_landmark; backend.anchored_observations_per_landmark
  // is the stereo-inertial one). 0 when the split above is on (it keeps the same information in
  // the prior instead). docs/VIO.md weather 2026-12-04 (night).
  int stereo_only_anchored_observations_per_landmark = 1;
  // Stereo-inertial (YAML backend.lowcontrast_gyro_walk_scale, in (0, 1]; 1: as modelled): on
  // frames the frontend measures low in contrast (FrontendStats::low_contrast: the
  // frontend.clahe_below_std state, when it is > 0 and CLAHE, the stretch or the corner check is
  // on), the gyro bias random walk from the previous frame is this times the IMU's: the bias held
  // while the vision is weak, as an INS holds its bias estimates through an aiding outage. In
  // dust the vision of faint texture pulls the vertical gyro bias and the yaw drifts with it;
  // held at 0.3, the urban route's six dust 75-100 % runs (seeds 1-3) went from 3.43 to 2.49 m
  // mean error (5 of 6 better), clear and fog unchanged: no low-contrast frames (docs/VIO.md,
  // weather, 2026-12-02). The IMU factor's 1e-12 regulariser on its covariance's diagonal is a
  // floor under the held walk: over one 33 ms frame of the car's IMU, 0.3 acts as about 0.41,
  // and 0.1 and 0.03 as 0.30 and 0.29.
  double lowcontrast_gyro_walk_scale = 0.3;
  // Initialisation.
  double init_window_s = 0.5;  // IMU window checked for stillness, s
  // Stillness: standard deviation of the 0.1 s block means over the window.
  double still_max_gyro_std = 0.02;   // rad/s
  double still_max_accel_std = 0.25;  // m/s^2
  // ... and, by vision, the left camera's tracks moved at most this much (median over the
  // tracks seen at the window's start and now, px; <= 0: the IMU alone decides, as it does
  // when no tracks span the window: a recording's or a re-start's first frame). A vehicle
  // cruising at constant velocity is still to the IMU: a drone flying straight at 5 m/s at 10 m
  // was taken as parked (velocity 0) and its estimate ran 225 m off over 205 m (bench gnss's
  // outdoor flight at 226x144); a parked car's tracks move 0.1 px.
  double still_max_image_motion_px = 1.0;
  // Prior on the gyro bias after a static start: the still window's mean rate measures the bias
  // to the standard error of its 0.1 s block means; the prior is this many standard errors
  // (at least static_gyro_bias_min_sigma, at most backend.prior_gyro_bias_sigma; <= 0: the
  // backend's prior). With the backend's 0.01 rad/s the window let the vision pull the bias: on
  // the foggy car route (near points only) the yaw then drifted 0.08 deg/s, 9.9 m mean error
  // against 2.5 m with the measured prior (docs/VIO.md, weather). One standard error, the
  // measurement's own uncertainty (the parked car: 0.31 mrad/s): at three (0.93 mrad/s) the
  // vision of fog and dust still pulled the bias by about one standard deviation of the prior;
  // at one, the urban car route's mean error over three seeds in clear, fog and dust fell from
  // 4.67 to 2.60 m (11 of 12 runs better or equal; docs/VIO.md, 2026-12-01).
  // Only when the window is still to the sensor's own noise: its block means spread at most
  // this many times the white noise's (a parked car: 1.3). A vibrating or slightly moving
  // vehicle keeps the backend's prior (EuRoC V1_01's start: 10; with the measured prior there
  // a 0.5 s IMU fault of 100x the noise moved the still clip 0.30 m instead of 0.03 m).
  double static_gyro_bias_standard_errors = 1.0;
  double static_gyro_bias_min_sigma = 2e-4;  // rad/s
  double static_gyro_bias_max_noise_ratio = 3.0;
  int min_init_stereo_features = 15;  // stereo matches needed to start
  double motion_init_tilt_sigma_rad = 0.5;
  double motion_init_velocity_sigma_m_s = 5.0;
  // In motion, tilt and accelerometer bias are confounded at first: a tight bias prior.
  double motion_init_accel_bias_sigma = 0.05;
  // Closed-form in-motion initialisation: seconds of stereo odometry aligned with the IMU
  // (0: the loose-prior initialisation above). At most 2.5 s (the IMU kept for it).
  double motion_init_window_s = 1.0;
  // Floor of the tilt prior after the alignment (its own estimate is used when larger), rad.
  double motion_init_aligned_tilt_sigma_rad = 0.005;
  double motion_init_aligned_velocity_sigma_m_s = 0.1;
  // An alignment starts the window only when the next one, over the window slid by half its
  // length, finds the same gravity direction: within the larger of motion_init_agreement_rad and
  // motion_init_agreement_sigmas x their combined tilt sigma. Both windows are then aligned
  // together and the start takes the earlier one's first frame. Both <= 0: the first alignment
  // that passes its residual test starts (before 2026-12-07).
  double motion_init_agreement_rad = 0.035;
  double motion_init_agreement_sigmas = 3.0;
  // Largest single whitened residual an alignment accepts (its RMS must stay within 3).
  double motion_init_max_whitened_residual = 12.0;
  // Failure detection.
  double max_frame_gap_s = 0.5;      // larger jumps between frames end the track
  double max_imu_gap_s = 0.05;       // larger gaps between IMU samples end the track
  int min_tracked_landmarks = 8;     // constrained landmarks in the newest frame ...
  double max_weak_tracking_s = 1.0;  // ... below which for this long ends the track
  double max_speed_m_s = 60.0;
  double max_gyro_bias = 0.3;   // rad/s
  double max_accel_bias = 1.5;  // m/s^2
  // Pipeline (YAML pipeline.feedback_lag_frames): the frontend step of packet n uses the
  // backend's feedback after packet n - this (>= 1). 1 is one sequential loop (in threaded mode
  // the frontend of a frame then waits for the backend of the previous one); 2 lets the frontend
  // of frame n run while the backend solves frame n - 1, with a one-frame older bias and rejected
  // tracks. Either way, threaded and sequential runs give the same result (docs/VIO.md).
  int feedback_lag_frames = 1;

  std::string Check() const;
};

// The frontend options `mode` runs with: in stereo-only mode the stereo_only_* keyframe
// thresholds, and the stereo_only_* fog treatment when set (>= 0).
FrontendOptions FrontendOptionsForMode(FrontendOptions f, VioMode mode);

// Reads a YAML config (every key optional, defaults above; see config/vio_euroc.yaml).
// Throws Error naming the file, line and key on unknown keys or bad values.
VioOptions LoadVioOptions(const std::string& path);
// Every option LoadVioOptions reads, as a YAML config that loads back to `options` (doubles in
// their shortest exact form): the effective configuration of a run.
std::string VioOptionsYaml(const VioOptions& options);

struct LostInterval {
  int64_t start_ns = 0, end_ns = 0;  // last good frame, first frame of the new track
  std::string reason;
};

struct FrameEstimate {
  StateEstimate state;  // world frame
  bool keyframe = false;
  // With GNSS: enu_from_world after this frame's solve (nullopt before the first alignment).
  std::optional<WorldAlignment> enu_from_world;
};

// The frontend step's result: what the backend step needs of a frame.
struct FramePacket {
  uint64_t number = 0;  // the frontend's packet count before this one (feedback numbering)
  int64_t t_ns = 0;
  FrontendOutput features;
  std::optional<int64_t> prev_t_ns;    // the previous frame's time (the frontend's)
  std::optional<std::string> problem;  // frame-time jump or IMU gap since the previous frame
  // Stereo-imu, no problem: the IMU preintegrated from the previous frame at `pre_bias`.
  std::optional<ImuPreintegration> pre;
  ImuBias pre_bias;
  // The IMU samples accepted by AddImu since the previous packet (the backend's own copy).
  std::vector<TimedImuSample> imu;
  double frontend_s = 0;  // the frontend step's work time (for the "total" timing)
};

// Backend -> frontend feedback (the mailbox message).
struct BackendFeedback {
  bool initialized = false;
  ImuBias bias;  // the newest state's (zero when not initialised)
  // The backend's rejected track ids (cumulative since its last reset) when they changed.
  std::optional<std::set<uint64_t>> rejected_tracks;
};

class VioEstimator {
 public:
  // `body_from_cam0`, `body_from_cam1`: extrinsics; the IMU is the body frame.
  VioEstimator(const camera::StereoRig& rig, const Rigid3d& body_from_cam0,
               const ImuNoise& imu_noise, const VioOptions& options);
  ~VioEstimator();

  // IMU samples in time order; out-of-order or non-finite samples are dropped with a warning.
  void AddImu(const TimedImuSample& sample);
  // Processes a stereo pair (8-bit grey). Returns the frame's estimate, or nullopt while not
  // initialised / lost.
  std::optional<FrameEstimate> ProcessFrame(int64_t t_ns, const cv::Mat& left,
                                            const cv::Mat& right);
  // The two halves of ProcessFrame (see the top of the file). RunFrontend returns nullopt for a
  // frame that is not after the previous one (skipped).
  std::optional<FramePacket> RunFrontend(int64_t t_ns, const cv::Mat& left, const cv::Mat& right);
  std::optional<FrameEstimate> RunBackend(FramePacket packet);
  // Closes an open lost interval at the end of the data.
  void Finish();
  // Wakes a RunFrontend waiting for feedback that will never come (the backend thread failed or
  // stopped); RunFrontend then throws. Call from any thread.
  void CancelFeedbackWait() { feedback_mailbox_.Cancel(); }
  // Estimates of earlier frames made available by the last RunBackend (the frames of a
  // successful in-motion alignment window, in time order, all before that call's frame); the
  // caller takes them once (backend thread).
  std::vector<FrameEstimate> TakeDelayedEstimates() { return std::exchange(delayed_, {}); }

  // GNSS fusion (stereo-imu mode only): enable before the first frame, then feed samples in
  // time order, interleaved with the frames (a sample is used once a frame covers its time).
  void EnableGnss(const GnssFusionOptions& options);
  void AddGnss(const GnssSample& sample);
  const GnssFusion* gnss() const { return gnss_.get(); }

  const std::vector<LostInterval>& lost_intervals() const { return lost_; }
  TimingStats& timing() { return timing_; }
  int initializations() const { return initializations_; }
  const std::string& last_init_kind() const { return last_init_kind_; }
  // Frames skipped because both images were identical to the previous frame's: a camera (or
  // driver) that repeats its last buffer. The IMU bridges them like a dropped frame.
  int frozen_frames() const { return frozen_frames_; }
  // Frames whose IMU interval the backend's PnP check found faulty (noise inflated;
  // backend.imu_pnp_check_pixels). Read after Finish().
  int imu_inflations() const { return backend_.imu_inflations(); }

 private:
  bool TryInitialize(const FramePacket& packet);
  // One frame of the closed-form in-motion initialisation; true when it initialised the window.
  // On success the window is initialised at the first frame of the odometry run and every later
  // frame of the run (up to this one) is re-run through it with the IMU.
  // The frame's preintegration with the gyro bias held (lowcontrast_gyro_walk_scale) when the
  // frontend measured it low in contrast.
  void HoldGyroBiasIf(bool low_contrast, ImuPreintegration* pre) const;
  bool MotionInitStep(const FramePacket& packet);
  void ResetMotionInit();
  void Lose(int64_t t_ns, const std::string& reason);
  // Updates the feedback message of the packet being processed (sent at the end of RunBackend).
  void PostFeedback(bool with_rejected_tracks);
  // The IMU buffers: one per side, fed with the same samples in the same order.
  static void AppendImu(const TimedImuSample& sample, double keep_s,
                        std::deque<TimedImuSample>* imu);
  std::optional<std::string> ImuProblem(const std::deque<TimedImuSample>& imu, int64_t t0_ns,
                                        int64_t t1_ns) const;
  ImuPreintegration Preintegrate(const std::deque<TimedImuSample>& imu, int64_t t0_ns,
                                 int64_t t1_ns, const ImuBias& bias) const;

  camera::StereoRig rig_;
  Rigid3d body_from_cam0_;
  ImuNoise imu_noise_;
  VioOptions options_;
  TimingStats timing_;  // thread-safe, written by both sides
  NumberedMailbox<BackendFeedback> feedback_mailbox_;
  // Frontend side.
  StereoFrontend frontend_;
  std::deque<TimedImuSample> imu_;
  std::vector<TimedImuSample> imu_for_backend_;  // accepted since the last packet
  std::optional<int64_t> prev_frame_ns_;
  cv::Mat prev_left_, prev_right_;  // the previous frame's images (frozen-camera check)
  int frozen_frames_ = 0;
  BackendFeedback feedback_;  // the latest taken from the mailbox (rejected ids not kept)
  uint64_t packets_ = 0;      // packets made
  // Backend side.
  SlidingWindowBackend backend_;
  std::deque<TimedImuSample> backend_imu_;
  size_t posted_rejected_ = 0;        // size of the rejected-track set last posted
  BackendFeedback pending_feedback_;  // this packet's message, posted at the end of RunBackend
  std::vector<LostInterval> lost_;
  std::optional<int64_t> lost_since_ns_;
  std::optional<std::string> lost_reason_;
  std::optional<int64_t> last_frame_ns_;  // the last frame the backend step saw
  std::optional<StateEstimate> last_good_;
  double weak_since_s_ = -1;
  int initializations_ = 0;
  std::string last_init_kind_;
  std::unique_ptr<GnssFusion> gnss_;
  // Closed-form in-motion initialisation: the stereo odometry and its frames.
  struct MotionInitFrame {
    int64_t t_ns = 0;
    Rigid3d vo_from_body;
    std::vector<StereoObservation> observations;
    bool keyframe = false;
    bool low_contrast = false;  // FrontendStats::low_contrast
  };
  std::unique_ptr<SlidingWindowBackend> init_odometry_;
  std::vector<MotionInitFrame> init_frames_;
  // An alignment awaiting its confirmation (motion_init_agreement_*), from init_frames_'s
  // first frame; the next window starts at init_frames_[init_attempt_front_].
  std::optional<ViAlignmentResult> pending_alignment_;
  size_t init_attempt_front_ = 0;
  // Stillness by vision: the observations of the frames TryInitialize saw over the IMU window
  // (the first one at or before its start), and their tracks' median motion in px since then
  // (nullopt without a frame at the window's start or with fewer than 10 tracks in common).
  std::deque<std::pair<int64_t, std::vector<StereoObservation>>> still_frames_;
  std::optional<double> ImageMotionSinceWindowStartPx(
      int64_t t0_ns, int64_t t_ns, const std::vector<StereoObservation>& now) const;
  std::vector<FrameEstimate> delayed_;
};

}  // namespace optinav::vio
