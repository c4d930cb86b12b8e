// GNSS fusion in the sliding window: position-only GNSS factors at their own timestamps, tying
// the VIO world (gravity-aligned, free yaw and origin) to the local ENU frame of the GNSS origin
// through an estimated yaw + translation (SlidingWindowBackend's alignment block).
//
//   - A sample at time t becomes a factor on the newest window state at or before t, with the
//     IMU preintegrated from that state to t (not snapped to a frame):
//       r = (Rz(yaw) (p_i + v_i dt + g dt^2 / 2 + R_i dp + R_i dR lever) + t_enu - z) / sigma
//     with first-order bias corrections of dp and dR. The baseline of the Kimera-VIO GNSS study
//     (SEEDS.md part 2), the sample linearly interpolated to frame times, is kept as
//     TimeMode::kFrameInterpolated.
//   - The alignment is initialised once the trajectory spans init_min_distance_m horizontally and
//     the yaw is known to init_max_yaw_sigma_rad or init_max_yaw_effect_m (RANSAC over pairs of
//     samples, then weighted least squares on the inliers; the samples older than the window become
//     its prior, the others factors), then refined in the window, with a random walk per metre
//     travelled that models the VIO drift; its yaw is held while the horizontal speed is below
//     yaw_hold_speed_m_s. Frames before the alignment are output through the first one.
//   - Gross outliers are gated before they enter: chi-square test of the innovation against the
//     sample sigma plus a model of the VIO position uncertainty (grows with the distance and time
//     since the last accepted sample, shrinks with each accepted one); survivors are re-weighted
//     by the selected norm (L2, Huber or Tukey). A long run of rejections (e.g. after an outage
//     longer than the model foresaw) widens the gate step by step.
//   - Outages: no factors, pure VIO; the gate widens with the distance flown.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "optinav/vio/backend.h"

namespace optinav::vio {

enum class GnssNorm { kL2, kHuber, kTukey };
std::optional<GnssNorm> ParseGnssNorm(const std::string& name);  // l2 | huber | tukey
std::string GnssNormName(GnssNorm norm);
// The default parameter of a norm, in units of the whitened residual (sigma).
double DefaultGnssNormParameter(GnssNorm norm);
// The norm as a Ceres loss on the whitened residual (nullptr for L2); parameter <= 0: the default.
std::unique_ptr<ceres::LossFunction> MakeGnssLoss(GnssNorm norm, double parameter);

enum class GnssTimeMode { kExact, kFrameInterpolated };
std::optional<GnssTimeMode> ParseGnssTimeMode(const std::string& name);  // exact | frame
std::string GnssTimeModeName(GnssTimeMode mode);

struct GnssSample {
  int64_t t_ns = 0;
  Eigen::Vector3d position_enu_m = Eigen::Vector3d::Zero();  // antenna, local ENU
  double sigma_m = 1.0;                                      // per axis
};

struct GnssFusionOptions {
  GnssNorm norm = GnssNorm::kHuber;
  double norm_parameter = -1;  // <= 0: DefaultGnssNormParameter(norm)
  Eigen::Vector3d lever_arm_in_body = Eigen::Vector3d::Zero();  // antenna in the body frame
  GnssTimeMode time_mode = GnssTimeMode::kExact;
  // The alignment is initialised once the trajectory spans init_min_distance_m horizontally and
  // the least-squares yaw sigma is below init_max_yaw_sigma_rad (a poorly known yaw, relinearised
  // later across hundreds of metres, would bias the window's priors; and as it converges after
  // the alignment, the output trajectory bends: with 3 m GNSS and a 1 deg start the outdoor
  // flight's ATE doubled from its VIO's).
  double init_min_distance_m = 5.0;
  double init_max_yaw_sigma_rad = 0.005;  // 0.3 deg
  // ... or when the yaw sigma times the track's horizontal span is below this (precise GNSS over
  // a small area: the yaw error moves no position by more).
  double init_max_yaw_effect_m = 0.1;
  int init_min_samples = 10;
  // The initialisation also waits until the VIO track agrees with the GNSS: at least this
  // fraction of the samples are inliers and their mean chi-square per axis is at most
  // init_max_chi2_per_axis (right after an in-motion VIO start, the first metres are off by
  // more than precise GNSS allows); otherwise the older half of the evidence is dropped.
  double init_min_inlier_fraction = 0.8;
  // After a loose-prior in-motion VIO start (OnTrackStarted(true)), samples within this time of the
  // track's first frame are not used for the initialisation: the VIO's start-up transient
  // (velocity and attitude converging) would bias the alignment.
  double init_settle_s = 5.0;
  double init_max_chi2_per_axis = 2.0;
  double gate_chi2 = 16.27;  // 3 DoF, 99.9 %; <= 0 disables the gate
  double yaw_hold_speed_m_s = 1.0;
  double drift_fraction = 0.01;      // VIO position sigma growth per metre travelled
  double drift_m_per_sqrt_s = 0.05;  // ... and per sqrt(second)
  double min_state_sigma_m = 0.25;   // floor of the modelled VIO position sigma
  // Added in quadrature to every sample's sigma (factors, gate, initialisation): what the GNSS
  // sigma does not cover (VIO interpolation between states, time sync, linearisation).
  double model_sigma_m = 0.15;
  // The factor's sigma (the innovation sigma) times this; the gate is not scaled. Above 1, the
  // window weighs GNSS less than its sigma says: with 3 m white noise at 5 Hz the samples'
  // full weight moves the trajectory's shape (see docs/VIO.md, GNSS limits).
  double factor_sigma_scale = 1.0;
  // Rejections for this long widen the gate (x2 sigma); the widened floor then halves with
  // each accepted sample, so a VIO that drifted more than modelled is pulled back smoothly.
  double reopen_after_s = 5.0;
  double reopen_yaw_sigma_rad = 0.01;    // yaw process noise added to the alignment at a widening
  double max_interpolation_gap_s = 1.0;  // frame-interpolated mode: larger gaps are outages
  // VIO drift relative to ENU as a random walk of the alignment per metre travelled (see
  // SlidingWindowBackend::SetAlignmentRandomWalk).
  double alignment_walk_m_per_sqrt_m = 0.003;
  double alignment_walk_rad_per_sqrt_m = 0.0002;
  // Drift detection: the exponential mean of the accepted innovations (over about
  // drift_window_samples) is tested against its expected spread; beyond drift_test_chi2
  // (3 DoF) the VIO has drifted more than the random walk allows, and the alignment's prior is
  // loosened by the mean offset. This adapts the fusion to the VIO's actual drift: a small walk
  // keeps a precise VIO precise under noisy GNSS, the test lets a drifting one follow.
  int drift_window_samples = 50;
  double drift_test_chi2 = 40.0;
  double relock_sigma_m = 10.0;  // after a VIO re-initialisation: translation prior, gate sigma
  double relock_yaw_sigma_rad = 0.1;

  // The output is smoothed over the whole run (SmoothGnssAlignment): the alignment at every frame
  // re-estimated from all the samples the fusion accepted, before and after it. false: the
  // alignment known right after each frame (the live estimate) only.
  bool smooth = true;
  // The smoother's random walk: the alignment's (alignment_walk_*) times this, plus a small one
  // per second (for hovering). Raise it for a VIO that drifts more than the alignment walk.
  double smooth_walk_scale = 1.0;
  double smooth_walk_m_per_sqrt_s = 0.002;
  double smooth_walk_rad_per_sqrt_s = 0.0001;

  std::string Check() const;  // empty when valid
};

// What the fusion loosened the alignment by at a time (drift test, widened gate): the smoother
// allows the same extra drift there.
struct AlignmentInflation {
  int64_t t_ns = 0;
  Eigen::Vector4d sigma = Eigen::Vector4d::Zero();  // [tx, ty, tz, yaw]
};

struct RejectedGnss {
  int64_t t_ns = 0;
  Eigen::Vector3d position_enu_m = Eigen::Vector3d::Zero();
  std::string reason;
  double innovation_m = -1;  // -1 when not evaluated
};

struct GnssFusionStats {
  size_t received = 0, factors = 0, rejected = 0;
  std::optional<int64_t> aligned_at_ns;  // first alignment
  int alignments = 0;                    // including re-locks after VIO re-initialisation
  int drift_inflations = 0;              // the drift test loosened the alignment
};

class GnssFusion {
 public:
  explicit GnssFusion(const GnssFusionOptions& options);
  ~GnssFusion();

  // Samples in time order (a repeated or earlier stamp is rejected with that reason).
  void AddSample(const GnssSample& sample);
  // After the backend has taken the frame whose estimate (world frame) is `estimate`: turns the
  // samples up to the frame's time into factors (or alignment evidence) for the next solve.
  void OnFrame(const StateEstimate& estimate, SlidingWindowBackend* backend);
  // The VIO track was lost and the backend reset: the alignment is re-locked (loose prior) at
  // the first frame of the next track.
  void OnTrackLost();
  // The VIO (re)initialised; `in_motion`: a loose-prior in-motion start, whose start-up
  // transient the alignment waits out (init_settle_s); a static or closed-form start has none.
  void OnTrackStarted(bool in_motion) { settle_s_ = in_motion ? options_.init_settle_s : 0.0; }

  // The current estimate of enu_from_world, once initialised.
  std::optional<WorldAlignment> alignment() const { return alignment_; }
  const std::vector<RejectedGnss>& rejected() const { return rejected_; }
  // The samples that entered the estimate (factors and the alignment's initial evidence), with
  // the sample's sigma and model_sigma_m in quadrature (not the factor's: that adds the modelled
  // VIO uncertainty and factor_sigma_scale).
  const std::vector<GnssSample>& used() const { return used_; }
  const std::vector<AlignmentInflation>& inflations() const { return inflations_; }
  const GnssFusionStats& stats() const { return stats_; }
  const GnssFusionOptions& options() const { return options_; }

 private:
  struct Evidence;
  void Reject(const GnssSample& s, const std::string& reason, double innovation_m = -1);
  std::optional<Rigid3d> WorldPoseAt(int64_t t_ns) const;
  void Use(const GnssSample& s, SlidingWindowBackend* backend);
  void TryInitialize(SlidingWindowBackend* backend);
  void AddFactor(const GnssSample& s, double state_var_m2, SlidingWindowBackend* backend);

  GnssFusionOptions options_;
  std::unique_ptr<ceres::LossFunction> loss_;
  std::deque<GnssSample> pending_;     // not yet covered by a frame
  std::deque<StateEstimate> history_;  // recent frame estimates (world), for interpolation
  std::vector<Evidence> evidence_;     // before the alignment: (sample, world antenna)
  size_t evidence_tried_ = 0;          // evidence count at the last initialisation attempt
  std::optional<WorldAlignment> alignment_;
  bool relock_ = false;
  double state_var_m2_ = 0;  // modelled VIO position variance (per axis)
  double state_var_floor_m2_ = 0;
  Eigen::Vector3d innovation_mean_ = Eigen::Vector3d::Zero();  // drift detection
  double innovation_mean_var_ = 0;  // its expected variance per axis  // after a widening of the
                                    // gate; halves per accepted sample
  std::optional<int64_t> rejecting_since_ns_;
  std::optional<int64_t> track_start_ns_;  // first frame of the current VIO track
  double settle_s_ = 0;
  std::optional<int64_t> last_sample_ns_;
  std::optional<GnssSample> last_ready_;  // frame-interpolated mode
  std::deque<int64_t> frames_waiting_;    // frame-interpolated mode
  std::vector<RejectedGnss> rejected_;
  std::vector<GnssSample> used_;
  std::vector<AlignmentInflation> inflations_;
  GnssFusionStats stats_;
  int64_t next_debug_ns_ = 0;  // the next periodic debug line
};

}  // namespace optinav::vio
