// Map-aided inertial navigation (`optinav nav`): IMU + nadir camera + barometer + map fixes in one
// sliding-window estimator (the VIO backend: IMU preintegration, Schur marginalisation and its
// timed-factor hook; SEEDS.md parts 2 and 3 joined).
//
// World frame: east-north-up about an origin given by the caller (the map's centre for `optinav
// nav`), z = height above the map plane. Body frame: the IMU (x nose, y left, z up). States sit
// at the nadir frames' times; every state is a keyframe of the window. Factors:
//   - IMU preintegration + bias random walk between consecutive states;
//   - barometer: z(t) + bias - altitude at every sample's own time, the bias a global block of the
//     window with a prior and a random walk (BaroOptions);
//   - visual odometry: the frame-to-frame homography of consecutive nadir frames as a
//     relative-pose factor: matched pixels, through both states' attitudes and heights above
//     the ground plane, give the horizontal displacement between the frames (plane-induced,
//     metric through the altitude; the attitudes inside the residual);
//   - map fixes: `maploc::Locator` on the nadir frame with the prediction as its prior (position,
//     radius from the covariance, heading, attitude, altitude), the fix's horizontal position
//     (and its altitude when the features method estimated it) as an absolute factor weighted by
//     the fix's position_sigma_m, behind a chi-square gate on the innovation (prediction
//     covariance + fix sigma) and the selected robust norm; the GNSS fusion's norms.
// Initialisation: a given start (position, heading) or the first map fix found by a global search
// and confirmed by a second one near it. Without fixes (water, cloud, dust) the estimate runs on
// IMU + baro + odometry and its covariance grows; a long run of rejections widens the gate, and
// a prediction too uncertain for a local search falls back to a global one.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "optinav/camera/camera.h"
#include "optinav/geo/geo.h"
#include "optinav/geometry/lie.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/maploc/locator.h"

namespace optinav::nav {

struct NavStart {
  geo::LatLon position;
  double heading_deg = 0;  // yaw, clockwise from north
  double position_sigma_m = 10;
  double heading_sigma_deg = 5;
  // The attitude at the start (an autopilot's AHRS; level when unknown), known to
  // NavOptions::init_tilt_sigma_deg.
  double roll_deg = 0, pitch_deg = 0;
  // The velocity at the start (ENU m/s; e.g. the air speed along the heading, the wind unknown)
  // and its sigma per axis; unset: at rest, known to NavOptions::init_velocity_sigma_m_s.
  std::optional<Eigen::Vector3d> velocity;
  double velocity_sigma_m_s = 5;
};

struct NavOptions {
  int window_states = 10;  // states in the sliding window (nadir frames)
  // IMU noise (continuous time, as in sensor.yaml); the defaults are a MEMS IMU.
  double gyro_noise_density = 1.7e-4, accel_noise_density = 2.0e-3;
  double gyro_random_walk = 2.0e-5, accel_random_walk = 3.0e-3;
  // The biases' prior at the start (per axis): what is left after the autopilot's calibration
  // at rest before take-off (the simulator's IMU draws 0.002 rad/s and 0.02 m/s^2). The VIO's
  // looser defaults (0.01, 0.2) let the window trade a gyro bias for a tilt that the fixes,
  // computed with the estimated tilt, then confirm (docs/NAV.md).
  double gyro_bias_prior_sigma = 0.003;  // rad/s
  double accel_bias_prior_sigma = 0.05;  // m/s^2
  // Barometer: white noise per sample, the bias's prior (the baro is referenced to the map
  // plane, e.g. zeroed at take-off at the map's ground height) and its random walk.
  double baro_sigma_m = 0.5;
  double baro_bias_sigma_m = 3.0;
  double baro_bias_walk_m_per_sqrt_s = 0.05;
  // Rotor drag (multirotors; 0: off): the accelerometer feels the air drag, so its horizontal
  // specific force in the body frame is -K (R^T (v - wind))_xy with K the drone's calibrated
  // drag per second. With K > 0 every frame interval adds a factor: the interval's mean specific
  // force minus the accelerometer bias against the drag of the velocity and the wind (a global
  // block, horizontal, with a prior and a random walk) at the interval's middle. A velocity that
  // needs no ground texture: what carries a gap (docs/NAV.md).
  double drag_per_s = 0.0;
  // The interval's mean, m/s^2: the accelerometer's white noise over 0.2 s (2e-3 / sqrt(0.2) =
  // 0.0045) plus a little; on bench nav's flight 3 through its gap 0.02 / 0.01 / 0.005 gave
  // 30.3 / 34.3 / 23.8 m at the gap's end (one run each).
  double drag_sigma_m_s2 = 0.005;
  double wind_prior_sigma_m_s = 10.0;
  double wind_walk_m_s_per_sqrt_s = 0.05;
  // Visual odometry: homography error in pixels (1 sigma, per point; measured about 0.07 px on
  // the simulator's 640x480 frames at 450 m) and the floor of the displacement's sigma as a
  // speed (times the frame interval). On `bench nav`'s flights 2 and 3 the displacement's
  // velocity errors are 0.60-0.64 m/s per axis (std over 669-852 frame pairs, lag-1
  // autocorrelation under 0.1) where 0.2 px claims 2.5 m/s; 0.1 px (1.2 m/s) lowered the
  // clear, fog and 60 s gap errors on all three flights; 0.07 px pulled the altitude (RMSE
  // 3.2-3.5 m on two flights) through the displacement's scale (docs/NAV.md).
  bool use_odometry = true;
  double odometry_pixel_sigma = 0.1;
  double odometry_min_velocity_sigma = 0.3;  // m/s
  // The homography is taken at the centre and near the four corners (12 % in). Their mean is the
  // displacement; each corner's difference from the centre (zero for a translation) carries the
  // rotation between the frames, with this times the displacement's sigma (0: not used). The
  // mean alone leaves that rotation to the gyro, so a gyro-bias error biased the velocity
  // (0.15 mrad per frame at 470 m: 0.35 m/s) and tilted the IMU-only drift of a gap. Measured on
  // `bench nav`'s flights (docs/NAV.md): 4 took the clear RMSE from 5.89 to about 5.6 m and
  // flight 2's 60 s gap from 464 to 186 m max; 2 pulled the altitude (4.2 m RMSE on flight 2).
  double odometry_rotation_sigma_scale = 4.0;
  // Map fixes.
  bool use_map = true;
  double fix_rate_hz = 1.0;        // fixes tried at most this often (0: every frame)
  std::string map_norm = "huber";  // l2 | huber | tukey (vio::GnssNorm)
  double map_norm_parameter = -1;  // <= 0: the norm's default (sigmas)
  double fix_sigma_floor_m = 2.0;  // a fix's sigma is at least this
  // A fix's sigma is the locator's position_sigma_m times this. That sigma is calibrated on
  // 256x256 frames; on the simulator's 640x480 nadir frames at 350-600 m the errors are 3-4x
  // smaller (median 4.3 m for a median sigma of 16 m); with 0.5, 98.9 % of 181 fixes of a
  // 3.9 km flight are within 2 sigma (docs/NAV.md).
  double fix_sigma_scale = 0.5;
  double fix_altitude_sigma_rel = 0.05;  // altitude from a features fix: sigma = this x altitude
  // A fix's heading (orientation correlation searches it; features estimate it) enters as a yaw
  // factor with this sigma (degrees; <= 0: not used).
  double fix_yaw_sigma_deg = 1.5;
  double gate_chi2 = 13.8;       // 2 DoF, 99.9 %; <= 0 disables the gate
  double reopen_after_s = 10.0;  // rejections for this long widen the gate (x2 sigma each time)
  // After this long without an accepted fix (a gap: water, cloud, a blanked camera), a fix
  // that passes the gate but lies more than 3 sigma + 30 m from the prediction is not fused:
  // the state drifted further than its covariance says (60 s of IMU only: 455 m against a
  // 3-sigma of 433 m), the robust norm would move it only a few metres, and the next searches
  // around it found wrong places that agreed with it. Such a fix waits (3 s, or 2.5 fix
  // intervals) for a second one that puts the vehicle at the same offset from the estimate
  // (3 sigma + 20 m), from a search holding both the estimate and the candidate's place (the
  // correlation chooses between them); then the window restarts at the fix with the estimate's
  // attitude and biases and a loosened velocity. A far fix the gate refuses after a gap waits
  // the same way (with the 0.1 px odometry the covariance after a gap is tighter, and the
  // relocalisation's path, five agreeing refusals, took 4 s where the confirmation takes 1 s).
  double confirm_after_gap_s = 10.0;
  double max_local_radius_m = 1500;  // a prior radius beyond this: global search
  // A global search (no position to search around: take-off, after a relocalisation) costs 1-6 s
  // on one core (640x480 frames over the NAIP tile: ~5 s), so at most one per this many seconds
  // of flight, as a locator on one core could keep up in real time; local fixes keep the fix
  // rate. At 1 Hz, bench flight 1 (no fix possible for its first 32 s) ran at 1.1x real time.
  double global_search_interval_s = 3.0;
  double min_prior_radius_m = 100;
  // Initialisation from map fixes: the first fix found globally must be confirmed by a second
  // one within this distance plus 40 m/s times the time between them.
  double init_confirm_m = 60;
  std::optional<NavStart> start;  // initialise from this instead
  // GNSS positions (AddGnss), gated like map fixes (optional: GNSS-free is the point).
  double gnss_gate_chi2 = 16.3;  // 3 DoF, 99.9 %
  // Testing and benchmarks (the robustness acceptance): this fraction of the found map fixes is
  // replaced by a wrong position between outlier_min_m and outlier_max_m away in a random
  // direction, seeded (what a repetitive or changed landscape can make the locator return).
  double inject_outlier_fraction = 0;
  double outlier_min_m = 300, outlier_max_m = 1500;
  uint64_t outlier_seed = 1;
  double init_velocity_sigma_m_s = 30;
  double init_tilt_sigma_deg = 3;
  // Alignment after a start from map fixes: the start's attitude is level (a vehicle tilted
  // 2.5 deg puts a fix 22 m off at 500 m), so no pose is output until the window's tilt sigma is
  // under this (or align_max_s has passed); then the window restarts at the next accepted fix
  // with the attitude, velocity and biases it learnt, and poses follow after two more accepted
  // fixes (one fix's error is the restart's). 0: off (poses from the first fix). On `bench
  // nav`'s flight 3 (tilted 2.5 deg at its first fix) the first 10 s were 16-23 m off without it.
  double align_tilt_sigma_deg = 0.5;
  double align_max_s = 10.0;
  std::string Check() const;  // "" when valid, else names the field
};

struct NavSensors {
  camera::PinholeCamera camera;  // the nadir camera
  Rigid3d body_from_cam;         // its mount (EuRoC T_BS)
};

// One estimated state (a nadir frame's time).
struct NavPose {
  int64_t t_ns = 0;
  Rigid3d world_from_body;  // world = ENU about the origin
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Matrix3d position_covariance = Eigen::Matrix3d::Identity();  // m^2
  double yaw_sigma_deg = 0;
  double baro_bias_m = 0;
};

struct FixLog {
  int64_t t_ns = 0;
  bool global = false;    // searched without a prior
  bool found = false;     // the locator returned a position
  bool accepted = false;  // and it entered the estimate
  bool injected = false;  // a wrong position put in place of the fix (testing)
  std::string method;     // features | orientation-correlation
  std::string reason;     // the locator's reason, or why it was rejected
  Eigen::Vector3d enu = Eigen::Vector3d::Zero();  // the fix (z: its altitude when estimated)
  double sigma_m = 0;
  double innovation_m = -1;  // horizontal distance to the prediction (-1 before initialisation)
  Eigen::Vector2d innovation = Eigen::Vector2d::Zero();  // the fix minus the prediction (m)
  double chi2 = -1;
  double locate_ms = 0;
};

struct NavStats {
  size_t frames = 0, states = 0;
  size_t fixes_tried = 0, fixes_found = 0, fixes_accepted = 0, fixes_rejected = 0;
  size_t odometry_factors = 0, odometry_rejected = 0, baro_factors = 0;
  size_t fix_yaws = 0;  // fixes whose heading entered the estimate
  size_t gnss_received = 0, gnss_accepted = 0;
  size_t outliers_injected = 0, outliers_accepted = 0;  // inject_outlier_fraction
  size_t resets = 0;
  std::optional<int64_t> initialized_at_ns;
  double locate_ms = 0, odometry_ms = 0, solve_ms = 0;  // totals
};

class MapAidedNavigator {
 public:
  // `db` may be null (no map: IMU + baro + odometry from `options.start`). `origin`: the world
  // frame's ENU origin. The database must outlive the navigator. Throws Error on bad options.
  MapAidedNavigator(const NavOptions& options, const NavSensors& sensors,
                    const maploc::MapDatabase* db, const maploc::LocateOptions& locate_options,
                    const geo::LatLon& origin);
  ~MapAidedNavigator();

  // Sensor samples in time order, before the frame that follows them.
  void AddImu(const io::ImuSample& sample);
  void AddBaro(const io::BaroSample& sample);
  // A GNSS position (world ENU, metres) with its sigma per axis.
  void AddGnss(int64_t t_ns, const Eigen::Vector3d& enu, double sigma_m);
  // A nadir frame (8-bit grey or BGR). Returns the estimate at its time once initialised.
  std::optional<NavPose> AddFrame(int64_t t_ns, const cv::Mat& frame);

  const std::vector<FixLog>& fixes() const;
  const NavStats& stats() const;
  const geo::LocalEnu& enu() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Between ENU (x east, y north, z up) + FLU body and the attitude convention of
// maploc/aerial_camera.h (NED, yaw clockwise from north, body x nose, y right wing, z down).
Eigen::Matrix3d EnuFromBodyOfAttitude(double roll_deg, double pitch_deg, double heading_deg);
void AttitudeOfEnuFromBody(const Eigen::Matrix3d& enu_from_body, double* roll_deg,
                           double* pitch_deg, double* heading_deg);

}  // namespace optinav::nav
