// The Ceres sliding-window backend.
//
// The window holds the last `window_keyframes` keyframe states plus the newest frame. Each state
// has a pose block (world_from_body) and, with IMU, a speed-bias block (velocity, gyro bias,
// accel bias). Factors:
//   - IMU preintegration + bias random walk between consecutive states (factors.h);
//   - stereo reprojection of world landmarks (left and right camera), Huber loss;
//   - a linear prior: first the initial-state prior, then the marginalisation prior;
//   - extra timed factors (TimedFactor): the extension point for absolute measurements at
//     arbitrary timestamps (GNSS positions, map fixes), attached to the state at or before their
//     time with the IMU preintegrated from that state to the measurement time.
// The whole window is optimised when the new frame is a keyframe; otherwise only the new state
// moves (motion-only, previous state and landmarks fixed), which keeps the per-frame cost low.
// When a new frame arrives and the previous newest frame was not a keyframe, that frame is
// dropped (its IMU interval is merged into the next one, its observations discarded). When the
// window holds more than `window_keyframes` keyframes, the oldest is marginalised with a Schur
// complement: its IMU factor, the prior, its timed factors and every observation of the landmarks
// that are no longer tracked become a linear prior on the remaining states; its observations of
// still-tracked landmarks are dropped (information discarded, never double counted).
// Without IMU (stereo-only mode) states have only poses and the new pose is predicted with a
// constant-velocity model.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "optinav/geometry/lie.h"
#include "optinav/vio/factors.h"
#include "optinav/vio/imu_preintegration.h"

namespace optinav::vio {

struct BackendOptions {
  bool use_imu = true;          // false: stereo-only (no speed-bias blocks, no IMU factors)
  int window_keyframes = 8;     // keyframes kept in the window (>= 2)
  double pixel_sigma = 1.0;     // reprojection noise, pixels
  double huber_pixels = 1.5;    // Huber threshold on the whitened residual, pixels
  double outlier_pixels = 4.0;  // observations above this after a solve are removed
  double min_depth_m = 0.1;     // landmarks closer than this to a camera are rejected
  double max_depth_m = 200.0;   // stereo triangulation beyond this is not trusted
  // Stereo-only (use_imu false): observations reprojecting worse than this after a solve are
  // removed instead of outlier_pixels (0: outlier_pixels). The VIO pipeline sets it
  // (VioOptions::stereo_only_outlier_pixels): it relies on the frontend replacing rejected tracks.
  double stereo_only_outlier_pixels = 0.0;
  // When the oldest keyframe leaves: a landmark it observes that the newest frame still tracks
  // is split instead of losing that observation. Its observations by every state but the newest
  // are marginalised with it into the prior (nothing dropped), and it carries on as a new
  // landmark from the newest observation (at its current position). false: the oldest
  // keyframe's observation of it is dropped (information lost; docs/VIO.md, weather).
  bool marginalize_tracked_landmarks = false;
  // ... only those nearer than this to the newest frame's left camera (m; 0: all).
  double marginalize_tracked_max_depth_m = 0.0;
  // When the oldest keyframe leaves: a landmark it observes that the newest frame still tracks
  // keeps up to this many of the observations of keyframes that left, as reprojection residuals
  // against those keyframes' poses held fixed (0: off, the oldest keyframe's observation is
  // dropped). A landmark tracked for seconds then ties the window to where the first keyframes
  // saw it, as a local map's fixed keyframes do in keyframe bundle adjustment, instead of only
  // over the window's span. Not with marginalize_tracked_landmarks (which keeps that
  // information in the prior instead).
  int anchored_observations_per_landmark = 0;
  // ... and drops anchored observations older than this before the newest frame (s; 0: kept as
  // long as the landmark).
  double anchored_max_age_s = 0.0;
  // ... for landmarks nearer than this to the newest frame's left camera (m; 0: all).
  double anchored_max_depth_m = 0.0;
  // ... with the right camera's observation too (false, the default: the left camera's only, a
  // bearing from the fixed pose; the landmark's depth comes from the window's stereo
  // observations). With both, the old keyframe's stereo pair fixes the landmark in 3D and the
  // window is pinned to its depth error: on the car route in stereo mode over three seeds the
  // left camera's alone gave the lower error on every condition tried (docs/VIO.md).
  bool anchored_stereo = false;
  // With IMU, before the solve: a landmark whose newest observation reprojects farther than this
  // from the IMU-predicted pose of the new frame is rejected (with its track) instead of entering
  // the solve (0: off). Falling snow and leaves are tracked like the scene but drift 1-1.5 m/s
  // through it, all the same way (the wind), and bent the stereo-inertial yaw past the Huber
  // loss: on the car route 2 px cut the mean error in snow 7.9 -> 3.3 m and in leaves 15.0 ->
  // 3.3 m, but moved the other conditions both ways (clear 0.86 -> 1.53 m, fog 100 % 2.47 ->
  // 4.90 m), so it is off here; the app turns it on for a ground vehicle (2 px, relative 2x,
  // app::VehicleModel, docs/VIO.md, weather, 2026-12-03 later). Unused without IMU: a
  // constant-velocity prediction rejected the scene in a turn and the estimate diverged.
  double predicted_gate_pixels = 0.0;
  // With predicted_gate_pixels > 0: the gate widens to this many times the median of the new
  // frame's predicted reprojection errors when that is larger (0: the fixed gate only). An IMU
  // prediction that is off moves every landmark the same way and the median with it; particles
  // are a minority moving against the scene, so a relative gate keeps the scene in a turn or a
  // jolt and still rejects them.
  double predicted_gate_median_factor = 0.0;
  // Without IMU: the same gate against a pose measured from the new frame itself instead of a
  // prediction: a RANSAC PnP (P3P hypotheses, left-camera observations of the window's
  // landmarks, inlier threshold this many pixels; 0: off) gives the pose, then a landmark whose
  // newest observation reprojects farther than this, or than stereo_only_pnp_gate_median_factor
  // times the median when that is larger, is rejected with its track. Particles that both
  // cameras see (snow, leaves) are triangulated like the scene and drift with the wind; the
  // frontend's fundamental-matrix RANSAC passes a drift along the epipolar line, PnP does not.
  // Not used when the PnP finds fewer than 12 landmarks, or when its pose keeps fewer than half
  // of them within the gate (a refinement that slid off on a road's repetitive texture once
  // rejected 64 landmarks at once and the pose jumped 9 deg). Off by default (VioOptions): on the
  // car routes the stereo odometry's drift in leaves, fog and dust stayed as it was (docs/VIO.md,
  // weather, 2026-12-05 night).
  double stereo_only_pnp_gate_pixels = 0.0;
  double stereo_only_pnp_gate_median_factor = 0.0;
  // With IMU: an IMU fault check, before the solve (and before predicted_gate_pixels). When the
  // IMU-predicted pose of a new frame reprojects its landmarks (those seen by another state too)
  // a median of more than this many pixels off, a RANSAC PnP of the frame (inlier threshold half
  // of this) is tried; when at least half of the landmarks, and their median, fit the PnP pose
  // within half of this, the interval's IMU white noise is inflated until the PnP pose lies on
  // the 99 % chi-square bound of its preintegrated rotation and position covariance (by at most
  // 1e4x), and the pose starts from PnP (0: off).
  // A burst of 100x the white noise for 0.5 s on the still EuRoC clip moved the estimate a mean
  // 0.20 m over 32 noise draws (24 over 0.1 m, two lost) with the IMU trusted as modelled: the
  // IMU factor pulled the pose away and the vision's observations were then removed as
  // outliers. With the check: 6-9 mm in all 32 (pipeline_test, docs/VIO.md).
  double imu_pnp_check_pixels = 3.0;
  // With IMU: a wheeled ground vehicle's non-holonomic constraint on every state, its body-frame
  // velocity's sideways (y) and vertical (z) components ~ N(0, sigma^2) (m/s; 0: that component
  // unconstrained; both 0: off, the default). For a body frame with x forward and its origin near
  // the rear axle. On a car the IMU cannot tell a slow vertical velocity error from none (no
  // acceleration), and vision with near points only (fog) let the height drift (docs/VIO.md,
  // weather, 2026-12-02). Without IMU (no velocity states) the same sigmas constrain the mean
  // velocity between consecutive states, in the body frame at the arc's middle
  // (CreateGroundVehiclePairFactor): opt-in, off in every default (docs/VIO.md, weather,
  // 2026-12-05 evening: on the car route it cut the yaw error of a foggy turn 4.3 -> 1.2 deg
  // but turned the stereo odometry's 0.1 deg translation-direction bias into a yaw drift).
  double ground_vehicle_lateral_sigma_m_s = 0.0;
  double ground_vehicle_vertical_sigma_m_s = 0.0;
  // Without IMU, with a ground-vehicle sigma: estimate the vehicle's forward axis in the body
  // frame (yaw and pitch, a global block with this prior sigma in rad and this random walk in
  // rad/sqrt(s); 0: the body x axis, fixed). See CreateGroundVehiclePairFactorWithBoresight.
  double ground_vehicle_boresight_sigma_rad = 0.0;
  double ground_vehicle_boresight_walk_rad_per_sqrt_s = 0.0;
  int max_iterations = 8;  // Levenberg-Marquardt iterations per frame
  // Levenberg-Marquardt's first damping is 1 / this radius (Ceres' default 1e4 damps the weakly
  // constrained directions, far landmark depths and the velocity/attitude they couple to, so
  // hard that a window solve never converged in max_iterations; with 1e6 most converge in 3-6).
  // Used by the window and the motion-only solves.
  double initial_trust_region_radius = 1e6;
  // A solve stops when an iteration lowers the cost by less than this fraction (Ceres' default
  // 1e-6 spends the last iterations on changes far below the noise).
  double function_tolerance = 1e-4;
  // Wall-clock limit per solve (0: none, max_iterations alone bounds it). A live system may set
  // it as a safety net; it then makes the result depend on the machine's speed: with 0.01 s, a
  // 10x slowdown (a sanitizer build on a loaded machine), the fog test's 25 s segment gave
  // 0.51 m, and with 0.005 s 0.60 or 1.32 m on two runs, against 0.456 m at 0.02 s and above.
  double max_solver_time_s = 0;
  // Relinearise preintegration when the bias estimate moved more than this from the
  // linearisation bias.
  double relinearize_gyro_bias = 0.005;  // rad / s
  double relinearize_accel_bias = 0.05;  // m / s^2
  // Initial prior sigmas (the gauge: position and yaw are unobservable).
  double prior_position_sigma_m = 1e-3;
  double prior_yaw_sigma_rad = 1e-3;
  double prior_tilt_sigma_rad = 0.02;
  double prior_velocity_sigma_m_s = 0.1;
  double prior_gyro_bias_sigma = 0.01;
  double prior_accel_bias_sigma = 0.2;
  ImuNoise imu_noise;
  Eigen::Vector3d gravity = GravityInWorld();
  // Marginalisation and the prior's factorisation judge gauge directions on the Jacobi-scaled
  // information (vio::Marginalize): needed when weak absolute information (map fixes known to
  // 10 m) shares the window with bias random walks; the VIO keeps the unscaled threshold its
  // figures were tuned with.
  bool jacobi_scaled_marginalization = false;

  // Empty when valid, else a message naming the field and value.
  std::string Check() const;
};

// The rig as the backend needs it: extrinsics and a focal length to express residuals in pixels.
struct RigExtrinsics {
  Rigid3d cam0_from_body, cam1_from_body;
  double focal_px = 450.0;
};

// A feature of a frame: undistorted normalised coordinates in the left (and right) camera.
struct StereoObservation {
  uint64_t track_id = 0;
  Eigen::Vector2d left = Eigen::Vector2d::Zero();
  std::optional<Eigen::Vector2d> right;
};

struct StateEstimate {
  int64_t t_ns = 0;
  Rigid3d world_from_body;
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  ImuBias bias;
};

// The tie between the VIO world (gravity-aligned, free yaw and origin) and a local ENU frame
// (GNSS): enu_from_world = (rotation about z by yaw, translation). Estimated in the window as one
// 4-parameter block [tx, ty, tz, yaw] once enabled (EnableAlignment).
struct WorldAlignment {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double yaw_rad = 0;
  Rigid3d EnuFromWorld() const;
  // As the parameter block [tx, ty, tz, yaw], and back.
  Eigen::Vector4d Block() const {
    return {translation.x(), translation.y(), translation.z(), yaw_rad};
  }
  static WorldAlignment FromBlock(const double* block) {
    return {Eigen::Vector3d(block[0], block[1], block[2]), block[3]};
  }
};
constexpr int kAlignmentSize = 4;

// enu = Rz(yaw) p_world + t for the block [tx, ty, tz, yaw] (templated for autodiff cost
// functions; p_world of doubles or of T).
template <typename T, typename Point>
void ApplyAlignment(const T* block, const Point& p_world, T* enu) {
  using std::cos, std::sin;
  const T c = cos(block[3]), s = sin(block[3]);
  enu[0] = c * p_world.x() - s * p_world.y() + block[0];
  enu[1] = s * p_world.x() + c * p_world.y() + block[1];
  enu[2] = T(p_world.z()) + block[2];
}

// A factor on one state at an arbitrary time (GNSS positions plug in here).
class TimedFactor {
 public:
  virtual ~TimedFactor() = default;
  virtual int64_t t_ns() const = 0;
  // A cost over the blocks (pose, speed_bias) of the anchor state (the newest state at or before
  // t_ns). `anchor_to_t` preintegrates the IMU from the anchor to t_ns (zero duration when they
  // coincide, or without IMU). In stereo-only mode the speed-bias block is absent: the cost must
  // then take the pose block only (uses_speed_bias(false)).
  virtual ceres::CostFunction* Create(const ImuPreintegration& anchor_to_t,
                                      const Eigen::Vector3d& gravity,
                                      bool uses_speed_bias) const = 0;
  // Robust loss (owned by the factor), or nullptr.
  virtual const ceres::LossFunction* loss() const { return nullptr; }
  // True: the cost takes the world alignment block (4 parameters) after the state's blocks. Such
  // factors wait until the alignment is enabled.
  virtual bool uses_alignment() const { return false; }
  // Global blocks (SlidingWindowBackend::AddGlobalBlock ids) the cost takes last, in this order.
  virtual std::vector<int> global_blocks() const { return {}; }
};

struct BackendStats {
  int num_states = 0, num_keyframes = 0, num_landmarks = 0, num_observations = 0;
  int num_outliers_removed = 0;
  double median_reprojection_px = 0;  // over the window's observations after the last solve
  int num_gated = 0;  // landmarks rejected on the predicted pose (predicted_gate_pixels)
  int solver_iterations = 0;
  double initial_cost = 0, final_cost = 0;
  bool solver_usable = false;
  int newest_constrained_landmarks = 0;  // landmarks seen by the newest frame and another state
  // How far the last window solve moved the states older than the newest (largest rotation, deg,
  // and translation, m); 0 after a motion-only solve.
  double window_shift_deg = 0, window_shift_m = 0;
};

class SlidingWindowBackend {
 public:
  SlidingWindowBackend(const BackendOptions& options, const RigExtrinsics& rig);
  ~SlidingWindowBackend();

  // Starts the window with the first state; the prior fixes the gauge around it. Negative
  // sigmas take the options' prior_tilt_sigma_rad / prior_velocity_sigma_m_s /
  // prior_accel_bias_sigma.
  void Initialize(const StateEstimate& state, const std::vector<StereoObservation>& observations,
                  double tilt_sigma_rad = -1, double velocity_sigma_m_s = -1,
                  double accel_bias_sigma = -1, double gyro_bias_sigma = -1);
  bool initialized() const { return !states_.empty(); }
  void Reset();

  // Adds a frame. `preintegration` covers the previous frame's time to t_ns (ignored without
  // IMU). Optimises the window and returns the frame's estimate.
  StateEstimate AddFrame(int64_t t_ns, const ImuPreintegration& preintegration,
                         const std::vector<StereoObservation>& observations, bool keyframe);

  // The extension point: the factor stays until its anchor state is marginalised (then it is
  // part of the marginalisation prior) or dropped with a non-keyframe (then it moves to the
  // previous state).
  void AddTimedFactor(std::unique_ptr<TimedFactor> factor);

  // The world alignment block: enabled with an initial value and a Gaussian prior (upper
  // triangular square root of its information, over [tx, ty, tz, yaw]); from then on it is
  // optimised with the window, carried through marginalisation, and cleared by Reset().
  void EnableAlignment(const WorldAlignment& initial, const Eigen::Matrix4d& prior_sqrt_info);
  bool alignment_enabled() const { return alignment_enabled_; }
  WorldAlignment alignment() const;
  // VIO drift relative to ENU, modelled as a random walk of the alignment with the distance
  // travelled: at each marginalisation its prior forgets sigma^2 = k^2 * distance (translation
  // k in m/sqrt(m), yaw in rad/sqrt(m); the yaw turns about the current position).
  void SetAlignmentRandomWalk(double translation_per_sqrt_m, double yaw_per_sqrt_m) {
    alignment_walk_translation_ = translation_per_sqrt_m;
    alignment_walk_yaw_ = yaw_per_sqrt_m;
  }
  // Forgets part of what the window's prior knows about the alignment now (adds this sigma over
  // [tx, ty, tz, yaw] as process noise): after the VIO drifted more than the random walk models.
  void InflateAlignment(const Eigen::Vector4d& sigma);
  // Holds the alignment yaw constant in the solves (GNSS cannot observe it without motion).
  void SetAlignmentYawHeld(bool held) { alignment_yaw_held_ = held; }
  // A global block: a Euclidean state shared by the whole window (e.g. a barometer's bias), with
  // a Gaussian prior (sigma per value), optimised with the window, carried through
  // marginalisation, and forgetting `walk_per_sqrt_s` (sigma per sqrt(second) per value) as the
  // window moves on. Returns its id for TimedFactor::global_blocks(). Cleared by Reset().
  int AddGlobalBlock(const Eigen::VectorXd& initial, const Eigen::VectorXd& prior_sigma,
                     const Eigen::VectorXd& walk_per_sqrt_s);
  Eigen::VectorXd GlobalBlock(int id) const;
  // The marginal covariance of the newest state (the window's linearisation at its current
  // values): 15x15 over the pose tangent (position, rotation vector in the world frame) and the
  // speed-bias block, or 6x6 without IMU.
  Eigen::MatrixXd NewestCovariance() const;
  // Timed factors waiting for or used by the window (not yet marginalised).
  size_t num_timed_factors() const { return timed_factors_.size(); }

  StateEstimate Newest() const;
  int64_t oldest_t_ns() const;
  const BackendStats& stats() const { return stats_; }
  // Frames whose IMU noise the PnP check inflated (imu_pnp_check_pixels), since construction.
  int imu_inflations() const { return imu_inflations_; }
  // Track ids the backend rejected as outliers (the frontend may stop tracking them).
  const std::set<uint64_t>& rejected_tracks() const { return rejected_tracks_; }

 private:
  struct State;
  struct Landmark;

  void DropNewestIfNotKeyframe(ImuPreintegration* next_preintegration);
  void AddObservations(State* state, const std::vector<StereoObservation>& observations);
  void TriangulateNew(State* state);
  // The reprojection residuals of the states and landmarks the filters pass (blocks: pose, point),
  // then with `with_anchors` those of the passed landmarks' anchored observations (block: point).
  std::vector<std::unique_ptr<ResidualSpec>> BuildResiduals(
      const std::function<bool(const State*)>& state_filter,
      const std::function<bool(const Landmark*)>& landmark_filter, bool with_anchors = true) const;
  void Optimize();
  void OptimizeNewest();
  void RecordSummary(const ceres::Solver::Summary& summary);
  void RemoveOutliers();
  // Before the solve: rejects the landmarks that the predicted pose of `state` (the newest)
  // reprojects farther than predicted_gate_pixels from its observations.
  void GateOnPrediction(const State& state);
  // The reprojection errors (ReprojectionErrorPx) of `state`'s observations at its current pose:
  // of its constrained landmarks, or of all initialised ones.
  std::vector<std::pair<uint64_t, double>> ErrorsAtPose(const State& state,
                                                        bool constrained_only) const;
  // Without IMU, before the solve: the gate against a RANSAC PnP pose of `state` (the newest;
  // BackendOptions::stereo_only_pnp_gate_pixels).
  void GateOnPnp(const State& state);
  // A RANSAC PnP pose of `state` seeded by its pose (the refined pose, or RANSAC's when that
  // keeps more landmarks within `gate` pixels), with every constrained landmark's error (pixels)
  // and how many are within `gate`. None with fewer than 12 constrained landmarks, when RANSAC
  // fails or keeps fewer than half of them, or when the pose keeps fewer than half within `gate`.
  struct PnpFit {
    Rigid3d body_from_world;
    std::vector<std::pair<uint64_t, double>> errors;
    size_t within = 0;
  };
  std::optional<PnpFit> FitPnp(const State& state, double gate) const;
  // With IMU, before the solve: BackendOptions::imu_pnp_check_pixels.
  void CheckImuAgainstPnp(State* state);
  // Rejects the landmarks whose reprojection error in `errors` exceeds `gate` pixels, or
  // `median_factor` times the errors' median when that is larger (0: the fixed gate only).
  void RejectAboveGate(const std::vector<std::pair<uint64_t, double>>& errors, double gate,
                       double median_factor);
  // The larger of the left and right reprojection errors (pixels) of `landmark` (initialized)
  // for `obs`, seen from a state at the inverse of `body_from_world`.
  double ReprojectionErrorPx(const Rigid3d& body_from_world, const Landmark& landmark,
                             const StereoObservation& obs) const;
  // Erases the landmarks with their observations; the frontend will stop tracking them.
  void RejectLandmarks(const std::set<uint64_t>& ids);
  void MarginalizeOldest();
  void RelinearizeBiases();
  void SetInitialPrior(State* state, double tilt_sigma_rad, double velocity_sigma_m_s,
                       double accel_bias_sigma, double gyro_bias_sigma);
  State* AnchorFor(int64_t t_ns, ImuPreintegration* anchor_to_t) const;
  // The blocks of a timed factor anchored at `anchor`, or empty when it cannot be used yet.
  std::vector<double*> TimedFactorBlocks(const TimedFactor& factor, State* anchor) const;
  // The IMU, prior and timed-factor residuals of the whole window (reprojections excluded).
  std::vector<std::unique_ptr<ResidualSpec>> BuildStateResiduals() const;
  // The ground-vehicle constraint of `state` (nullptr when off or without IMU).
  std::unique_ptr<ResidualSpec> GroundVehicleSpec(const State& state) const;
  // Without IMU: the ground-vehicle constraint between consecutive states a and b (nullptr when
  // off, with IMU or when they share a stamp).
  std::unique_ptr<ResidualSpec> GroundVehiclePairSpec(const State& a, const State& b) const;
  bool ground_vehicle() const {
    return options_.ground_vehicle_lateral_sigma_m_s > 0 ||
           options_.ground_vehicle_vertical_sigma_m_s > 0;
  }
  // The prior as a residual (nullptr when there is none).
  std::unique_ptr<ResidualSpec> PriorSpec() const;
  // A timed factor as a residual on its anchor state, or nullptr when it cannot be used yet (or
  // its anchor is not `only`, when given).
  std::unique_ptr<ResidualSpec> TimedFactorSpec(const TimedFactor& factor, const State* only) const;
  const ceres::Manifold* ManifoldOf(const double* block) const;
  int SizeOf(const double* block) const;

  BackendOptions options_;
  RigExtrinsics rig_;
  std::unique_ptr<ceres::LossFunction> huber_;
  int imu_inflations_ = 0;
  std::deque<std::unique_ptr<State>> states_;
  std::map<uint64_t, std::unique_ptr<Landmark>> landmarks_;
  std::vector<std::unique_ptr<TimedFactor>> timed_factors_;
  double alignment_[kAlignmentSize] = {0, 0, 0, 0};
  bool alignment_enabled_ = false;
  bool alignment_yaw_held_ = false;
  double alignment_walk_translation_ = 0, alignment_walk_yaw_ = 0;
  std::unique_ptr<ceres::Manifold> yaw_held_manifold_;
  struct Global {
    std::vector<double> values;
    Eigen::VectorXd walk_per_sqrt_s;
  };
  std::vector<std::unique_ptr<Global>> globals_;
  int boresight_ = -1;  // globals_ index of the ground vehicle's boresight (-1: none)
  LinearPrior prior_;
  std::set<uint64_t> rejected_tracks_;
  BackendStats stats_;
};

}  // namespace optinav::vio
