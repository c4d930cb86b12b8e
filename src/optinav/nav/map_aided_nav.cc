#include "optinav/nav/map_aided_nav.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <deque>
#include <random>
#include <string>

#include <ceres/ceres.h>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "optinav/maploc/aerial_camera.h"
#include "optinav/nav/internal/frame_odometry.h"
#include "optinav/util/error.h"
#include "optinav/vio/backend.h"
#include "optinav/vio/factors.h"
#include "optinav/vio/gnss_fusion.h"

namespace optinav::nav {

namespace {

constexpr double kDeg = M_PI / 180.0;

double Ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since)
      .count();
}

// ENU <-> NED and FLU <-> FRD.
Eigen::Matrix3d NedFromEnu() {
  Eigen::Matrix3d m;
  m << 0, 1, 0, 1, 0, 0, 0, 0, -1;
  return m;
}
Eigen::Matrix3d FrdFromFlu() { return Eigen::Vector3d(1, -1, -1).asDiagonal(); }

// The horizontal position (and optionally the height) at the factor's time, minus the fix.
class PositionFunctor {
 public:
  PositionFunctor(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity,
                  const Eigen::Vector3d& fix, double sigma_m, double altitude_sigma_m)
      : predict_(pre, gravity),
        fix_(fix),
        inv_sigma_(1.0 / sigma_m),
        inv_altitude_sigma_(altitude_sigma_m > 0 ? 1.0 / altitude_sigma_m : 0.0) {}
  template <typename T>
  bool operator()(const T* pose, const T* sb, T* residuals) const {
    Eigen::Matrix<T, 3, 1> p;
    predict_(pose, sb, &p, nullptr, nullptr);
    residuals[0] = (p[0] - T(fix_[0])) * T(inv_sigma_);
    residuals[1] = (p[1] - T(fix_[1])) * T(inv_sigma_);
    residuals[2] = (p[2] - T(fix_[2])) * T(inv_altitude_sigma_);
    return true;
  }

 private:
  vio::TimedStatePredictor predict_;
  Eigen::Vector3d fix_;
  double inv_sigma_, inv_altitude_sigma_;
};

class PositionFactor : public vio::TimedFactor {
 public:
  PositionFactor(int64_t t_ns, const Eigen::Vector3d& fix, double sigma_m, double altitude_sigma_m,
                 const ceres::LossFunction* loss)
      : t_ns_(t_ns), fix_(fix), sigma_(sigma_m), altitude_sigma_(altitude_sigma_m), loss_(loss) {}
  int64_t t_ns() const override { return t_ns_; }
  ceres::CostFunction* Create(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity,
                              bool) const override {
    return new ceres::AutoDiffCostFunction<PositionFunctor, 3, vio::kPoseSize, vio::kSpeedBiasSize>(
        new PositionFunctor(pre, gravity, fix_, sigma_, altitude_sigma_));
  }
  const ceres::LossFunction* loss() const override { return loss_; }

 private:
  int64_t t_ns_;
  Eigen::Vector3d fix_;
  double sigma_, altitude_sigma_;
  const ceres::LossFunction* loss_;
};

// The heading a map fix measured (the frame's up direction, clockwise from north: the yaw of
// the mapping camera's mount, docs/MAPDB.md) minus the state's: the mount's nose axis (image
// up, camera -y) in ENU gives yaw = atan2(east, north), free of roll and pitch (Z-Y-X).
class FixYawFunctor {
 public:
  FixYawFunctor(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity,
                const Eigen::Vector3d& nose_body, double yaw_rad, double sigma_rad)
      : predict_(pre, gravity), nose_body_(nose_body), yaw_(yaw_rad), inv_sigma_(1.0 / sigma_rad) {}
  template <typename T>
  bool operator()(const T* pose, const T* sb, T* residuals) const {
    Eigen::Quaternion<T> q;
    predict_(pose, sb, nullptr, nullptr, &q);  // the attitude only
    const Eigen::Matrix<T, 3, 1> u = q * nose_body_.cast<T>();
    const T d = ceres::atan2(u[0], u[1]) - T(yaw_);
    residuals[0] = ceres::atan2(ceres::sin(d), ceres::cos(d)) * T(inv_sigma_);
    return true;
  }

 private:
  vio::TimedStatePredictor predict_;
  Eigen::Vector3d nose_body_;
  double yaw_, inv_sigma_;
};

class FixYawFactor : public vio::TimedFactor {
 public:
  FixYawFactor(int64_t t_ns, const Eigen::Vector3d& nose_body, double yaw_rad, double sigma_rad,
               const ceres::LossFunction* loss)
      : t_ns_(t_ns), nose_body_(nose_body), yaw_(yaw_rad), sigma_(sigma_rad), loss_(loss) {}
  int64_t t_ns() const override { return t_ns_; }
  ceres::CostFunction* Create(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity,
                              bool) const override {
    return new ceres::AutoDiffCostFunction<FixYawFunctor, 1, vio::kPoseSize, vio::kSpeedBiasSize>(
        new FixYawFunctor(pre, gravity, nose_body_, yaw_, sigma_));
  }
  const ceres::LossFunction* loss() const override { return loss_; }

 private:
  int64_t t_ns_;
  Eigen::Vector3d nose_body_;
  double yaw_, sigma_;
  const ceres::LossFunction* loss_;
};

// z(t) + bias - barometric altitude.
class BaroFunctor {
 public:
  BaroFunctor(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity, double altitude,
              double sigma)
      : predict_(pre, gravity), altitude_(altitude), inv_sigma_(1.0 / sigma) {}
  template <typename T>
  bool operator()(const T* pose, const T* sb, const T* bias, T* residuals) const {
    Eigen::Matrix<T, 3, 1> p;
    predict_(pose, sb, &p, nullptr, nullptr);
    residuals[0] = (p[2] + bias[0] - T(altitude_)) * T(inv_sigma_);
    return true;
  }

 private:
  vio::TimedStatePredictor predict_;
  double altitude_, inv_sigma_;
};

class BaroFactor : public vio::TimedFactor {
 public:
  BaroFactor(const io::BaroSample& s, double sigma, int bias_block, const ceres::LossFunction* loss)
      : sample_(s), sigma_(sigma), bias_block_(bias_block), loss_(loss) {}
  int64_t t_ns() const override { return sample_.t_ns; }
  ceres::CostFunction* Create(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity,
                              bool) const override {
    return new ceres::AutoDiffCostFunction<BaroFunctor, 1, vio::kPoseSize, vio::kSpeedBiasSize, 1>(
        new BaroFunctor(pre, gravity, sample_.altitude_m, sigma_));
  }
  const ceres::LossFunction* loss() const override { return loss_; }
  std::vector<int> global_blocks() const override { return {bias_block_}; }

 private:
  io::BaroSample sample_;
  double sigma_;
  int bias_block_;
  const ceres::LossFunction* loss_;
};

// Rotor drag: the mean specific force of a frame interval (body x and y), minus the
// accelerometer bias, against -K R^T (v - wind) at the interval's middle (NavOptions::drag_per_s).
class DragFunctor {
 public:
  DragFunctor(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity,
              const Eigen::Vector2d& specific_force_xy, double drag_per_s, double sigma)
      : predict_(pre, gravity), f_(specific_force_xy), k_(drag_per_s), inv_sigma_(1.0 / sigma) {}
  template <typename T>
  bool operator()(const T* pose, const T* sb, const T* wind, T* residuals) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    Vec3 v;
    Eigen::Quaternion<T> q;
    predict_(pose, sb, nullptr, &v, &q);
    const Vec3 air = v - Vec3(wind[0], wind[1], T(0));
    const Vec3 drag_body = q.conjugate() * (air * T(-k_));
    residuals[0] = (T(f_.x()) - sb[6] - drag_body[0]) * T(inv_sigma_);
    residuals[1] = (T(f_.y()) - sb[7] - drag_body[1]) * T(inv_sigma_);
    return true;
  }

 private:
  vio::TimedStatePredictor predict_;
  Eigen::Vector2d f_;
  double k_, inv_sigma_;
};

class DragFactor : public vio::TimedFactor {
 public:
  DragFactor(int64_t t_ns, const Eigen::Vector2d& specific_force_xy, double drag_per_s,
             double sigma, int wind_block)
      : t_ns_(t_ns), f_(specific_force_xy), k_(drag_per_s), sigma_(sigma), wind_(wind_block) {}
  int64_t t_ns() const override { return t_ns_; }
  ceres::CostFunction* Create(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity,
                              bool) const override {
    return new ceres::AutoDiffCostFunction<DragFunctor, 2, vio::kPoseSize, vio::kSpeedBiasSize, 2>(
        new DragFunctor(pre, gravity, f_, k_, sigma_));
  }
  std::vector<int> global_blocks() const override { return {wind_}; }

 private:
  int64_t t_ns_;
  Eigen::Vector2d f_;
  double k_, sigma_;
  int wind_;
};

// The plane-induced homography between consecutive nadir frames as a relative-pose factor.
// For each of a few pixels c of the current frame and its match H c in the previous one, the
// horizontal offset from the camera to the ground point (the ray through the pixel, rotated by
// the state's attitude, scaled to the plane by the state's height) gives
//   p_cur - p_prev = offset_prev(H c) - offset_cur(c),
// with both states' attitudes and heights inside the residual: a tilt error changes the
// predicted displacement, so the solver sees it (a displacement precomputed with the predicted
// attitude would pull the tilt towards its own error). The factor is anchored at the previous
// state; the current one is reached through the IMU preintegrated to (just before) its time.
constexpr int kOdometryPoints = 5;

class DisplacementFunctor {
 public:
  DisplacementFunctor(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity,
                      const std::array<Eigen::Vector3d, kOdometryPoints>& rays_prev,
                      const std::array<Eigen::Vector3d, kOdometryPoints>& rays_cur, double sigma,
                      double rotation_sigma)
      : predict_(pre, gravity),
        rays_prev_(rays_prev),
        rays_cur_(rays_cur),
        inv_sigma_(1.0 / sigma),
        inv_rotation_sigma_(rotation_sigma > 0 ? 1.0 / rotation_sigma : 0.0) {}
  template <typename T>
  bool operator()(const T* pose, const T* sb, T* residuals) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Vec3> p_prev(pose);
    const Eigen::Quaternion<T> q_prev = Eigen::Map<const Eigen::Quaternion<T>>(pose + 3);
    Vec3 p_cur;
    Eigen::Quaternion<T> q_cur;
    predict_(pose, sb, &p_cur, nullptr, &q_cur);
    // Per point: the ground offset seen from the previous frame minus the current one's.
    std::array<T, kOdometryPoints> ex, ey;
    T sx(0), sy(0);
    for (int k = 0; k < kOdometryPoints; ++k) {
      const Vec3 d_prev = q_prev * rays_prev_[k].cast<T>();
      const Vec3 d_cur = q_cur * rays_cur_[k].cast<T>();
      // offset = -h d.xy / d.z (d.z < 0 looking down)
      ex[k] = -p_prev[2] * d_prev[0] / d_prev[2] + p_cur[2] * d_cur[0] / d_cur[2];
      ey[k] = -p_prev[2] * d_prev[1] / d_prev[2] + p_cur[2] * d_cur[1] / d_cur[2];
      sx += ex[k];
      sy += ey[k];
    }
    const T n(kOdometryPoints);
    residuals[0] = (sx / n - (p_cur[0] - p_prev[0])) * T(inv_sigma_);
    residuals[1] = (sy / n - (p_cur[1] - p_prev[1])) * T(inv_sigma_);
    // Each outer point against the centre (point 0): zero for a pure translation, so these
    // carry the rotation between the frames (and the climb), which the mean above drops.
    for (int k = 1; k < kOdometryPoints; ++k) {
      residuals[2 * k] = (ex[k] - ex[0]) * T(inv_rotation_sigma_);
      residuals[2 * k + 1] = (ey[k] - ey[0]) * T(inv_rotation_sigma_);
    }
    return true;
  }

 private:
  vio::TimedStatePredictor predict_;
  std::array<Eigen::Vector3d, kOdometryPoints> rays_prev_, rays_cur_;  // in the body frame
  double inv_sigma_, inv_rotation_sigma_;  // 0: the outer points' residuals are off
};

class DisplacementFactor : public vio::TimedFactor {
 public:
  DisplacementFactor(int64_t t_ns, const std::array<Eigen::Vector3d, kOdometryPoints>& rays_prev,
                     const std::array<Eigen::Vector3d, kOdometryPoints>& rays_cur, double sigma,
                     double rotation_sigma, const ceres::LossFunction* loss)
      : t_ns_(t_ns),
        rays_prev_(rays_prev),
        rays_cur_(rays_cur),
        sigma_(sigma),
        rotation_sigma_(rotation_sigma),
        loss_(loss) {}
  int64_t t_ns() const override { return t_ns_; }
  ceres::CostFunction* Create(const vio::ImuPreintegration& pre, const Eigen::Vector3d& gravity,
                              bool) const override {
    return new ceres::AutoDiffCostFunction<DisplacementFunctor, 2 * kOdometryPoints, vio::kPoseSize,
                                           vio::kSpeedBiasSize>(
        new DisplacementFunctor(pre, gravity, rays_prev_, rays_cur_, sigma_, rotation_sigma_));
  }
  const ceres::LossFunction* loss() const override { return loss_; }

 private:
  int64_t t_ns_;
  std::array<Eigen::Vector3d, kOdometryPoints> rays_prev_, rays_cur_;
  double sigma_, rotation_sigma_;
  const ceres::LossFunction* loss_;
};

}  // namespace

Eigen::Matrix3d EnuFromBodyOfAttitude(double roll_deg, double pitch_deg, double heading_deg) {
  const Eigen::Matrix3d ned_from_frd = maploc::NedFromBody({roll_deg, pitch_deg, heading_deg});
  return NedFromEnu().transpose() * ned_from_frd * FrdFromFlu();
}

void AttitudeOfEnuFromBody(const Eigen::Matrix3d& enu_from_body, double* roll_deg,
                           double* pitch_deg, double* heading_deg) {
  const maploc::Attitude a =
      maploc::AttitudeOf(NedFromEnu() * enu_from_body * FrdFromFlu().transpose());
  *roll_deg = a.roll_deg;
  *pitch_deg = a.pitch_deg;
  *heading_deg = a.yaw_deg;
}

std::string NavOptions::Check() const {
  if (window_states < 3) return "window_states must be >= 3";
  for (double v : {gyro_noise_density, accel_noise_density, gyro_random_walk, accel_random_walk})
    if (!(v > 0)) return "IMU noise densities must be > 0";
  if (!(gyro_bias_prior_sigma > 0) || !(accel_bias_prior_sigma > 0))
    return "IMU bias prior sigmas must be > 0";
  if (!(fix_yaw_sigma_deg >= 0)) return "fix_yaw_sigma_deg must be >= 0";
  if (!(baro_sigma_m > 0) || !(baro_bias_sigma_m > 0) || !(baro_bias_walk_m_per_sqrt_s >= 0))
    return "barometer sigmas must be > 0 (walk >= 0)";
  if (!(drag_per_s >= 0) || !(drag_sigma_m_s2 > 0) || !(wind_prior_sigma_m_s > 0) ||
      !(wind_walk_m_s_per_sqrt_s >= 0))
    return "drag_per_s must be >= 0, the drag and wind sigmas > 0 (walk >= 0)";
  if (!(odometry_pixel_sigma > 0) || !(odometry_min_velocity_sigma > 0))
    return "odometry sigmas must be > 0";
  if (!(odometry_rotation_sigma_scale >= 0)) return "odometry_rotation_sigma_scale must be >= 0";
  if (!(fix_rate_hz >= 0)) return "fix_rate_hz must be >= 0";
  if (!(global_search_interval_s >= 0)) return "global_search_interval_s must be >= 0";
  if (!vio::ParseGnssNorm(map_norm)) return "map_norm must be l2, huber or tukey, got " + map_norm;
  if (!(fix_sigma_floor_m > 0) || !(fix_altitude_sigma_rel > 0) || !(fix_sigma_scale > 0))
    return "fix sigmas must be > 0";
  if (!(reopen_after_s > 0)) return "reopen_after_s must be > 0";
  if (!(min_prior_radius_m > 0) || !(max_local_radius_m >= min_prior_radius_m))
    return "need 0 < min_prior_radius_m <= max_local_radius_m";
  if (!(init_confirm_m > 0) || !(init_velocity_sigma_m_s > 0) || !(init_tilt_sigma_deg > 0))
    return "initialisation sigmas must be > 0";
  if (!(align_tilt_sigma_deg >= 0) || !(align_max_s > 0))
    return "align_tilt_sigma_deg must be >= 0 and align_max_s > 0";
  if (start && !(start->position_sigma_m > 0 && start->heading_sigma_deg > 0 &&
                 start->velocity_sigma_m_s > 0))
    return "start sigmas must be > 0";
  if (start && start->velocity && !start->velocity->allFinite()) return "start velocity not finite";
  return "";
}

struct MapAidedNavigator::Impl {
  NavOptions options;
  NavSensors sensors;
  const maploc::MapDatabase* db;
  std::unique_ptr<maploc::Locator> locator;
  geo::LocalEnu enu;
  vio::BackendOptions backend_options;
  std::unique_ptr<vio::SlidingWindowBackend> backend;
  std::unique_ptr<ceres::LossFunction> map_loss, odometry_loss;
  FrameOdometry odometry;
  int bias_block = -1;
  int wind_block = -1;  // drag_per_s > 0

  std::vector<vio::TimedImuSample> imu;
  std::deque<io::BaroSample> baro;
  std::optional<io::BaroSample> last_baro;
  int64_t last_frame_ns = 0;
  bool have_frame = false;
  Eigen::MatrixXd covariance;  // of the newest state (15x15)
  std::optional<int64_t> last_fix_try_ns, last_global_try_ns;
  std::optional<int64_t> rejecting_since_ns;
  double gate_scale = 1.0;
  int odometry_rejections = 0;  // consecutive
  bool relocalize = false;      // the gate refused most fixes for too long: start again
  struct RecentFix {
    int64_t t_ns;
    bool refused;
    Eigen::Vector2d innovation;  // the fix minus the prediction (m)
    double sigma_m;
  };
  std::deque<RecentFix> recent_fixes;  // found fixes of the last 20 s
  // Relocalisation: the fix to restart at (the last refused fixes agreed on one offset from the
  // estimate: the estimate drifted, the map did not; or two fixes agreed after a gap), why, and
  // the velocity's sigma for the restart; otherwise where to search around.
  struct Restart {
    FixLog fix;
    std::string why;
    double velocity_sigma_m_s;
    bool ends_alignment = false;  // the alignment's restart, not a relocalisation
  };
  // Alignment after a start from map fixes (NavOptions::align_tilt_sigma_deg), no pose output
  // until it is over: the window learns its tilt, restarts at the next accepted fix, then waits
  // for two more accepted fixes (one fix's error, up to 2 sigma, 16 m on `bench nav`'s flight 2,
  // is the restart's).
  enum class Alignment { kOff, kLearningTilt, kWaitingForFix, kSettling };
  Alignment alignment = Alignment::kOff;
  int64_t alignment_since_ns = 0;  // the start of the current phase
  int settle_fixes = 0;            // accepted since the restart (kSettling)
  void SetAlignment(Alignment a, int64_t t_ns) {
    alignment = a;
    alignment_since_ns = t_ns;
    settle_fixes = 0;
  }
  double TiltSigma() const {  // of the newest state: the world rotation's east and north parts
    return std::sqrt(std::max(covariance(3, 3), covariance(4, 4)));
  }
  std::optional<Restart> restart_fix;
  struct SearchHint {
    int64_t t_ns;
    Eigen::Vector2d position;
    double sigma_m;
  };
  std::optional<SearchHint> search_hint;
  std::optional<FixLog> candidate;  // initialisation: a global fix waiting for confirmation
  std::optional<int64_t> last_accepted_fix_ns;
  std::optional<FixLog> gap_candidate;  // after a gap: a far fix waiting for confirmation
  struct Gnss {
    int64_t t_ns;
    Eigen::Vector3d enu;
    double sigma;
  };
  std::deque<Gnss> gnss;
  std::mt19937_64 outlier_rng;
  std::vector<FixLog> fixes;
  NavStats stats;

  Impl(const NavOptions& o, const NavSensors& s, const maploc::MapDatabase* d,
       const maploc::LocateOptions& lo, const geo::LatLon& origin)
      : options(o), sensors(s), db(d), enu(origin, 0.0), outlier_rng(o.outlier_seed) {
    const std::string problem = options.Check();
    if (!problem.empty()) throw Error("nav options: " + problem);
    if (db && options.use_map) {
      maploc::LocateOptions locate = lo;
      locate.camera = sensors.camera;
      locator = std::make_unique<maploc::Locator>(*db, locate);
    }
    map_loss = vio::MakeGnssLoss(*vio::ParseGnssNorm(options.map_norm), options.map_norm_parameter);
    odometry_loss = std::make_unique<ceres::HuberLoss>(2.0);
    backend_options.window_keyframes = options.window_states;
    backend_options.imu_noise = {options.gyro_noise_density, options.accel_noise_density,
                                 options.gyro_random_walk, options.accel_random_walk};
    backend_options.max_iterations = 10;
    backend_options.prior_gyro_bias_sigma = options.gyro_bias_prior_sigma;
    backend_options.prior_accel_bias_sigma = options.accel_bias_prior_sigma;
    backend_options.jacobi_scaled_marginalization = true;
  }

  bool initialized() const { return backend && backend->initialized(); }

  // The camera's attitude for the locator (the standard mapping-camera mount).
  void CameraAttitude(const Eigen::Matrix3d& enu_from_body, double* roll, double* pitch,
                      double* heading) const {
    const Eigen::Matrix3d enu_from_cam = enu_from_body * sensors.body_from_cam.rotation.matrix();
    const Eigen::Matrix3d ned_from_mapping_body =
        NedFromEnu() * enu_from_cam * maploc::BodyFromCamera().transpose();
    const maploc::Attitude a = maploc::AttitudeOf(ned_from_mapping_body);
    *roll = a.roll_deg;
    *pitch = a.pitch_deg;
    *heading = a.yaw_deg;
  }
  // ... and the body rotation of a camera attitude.
  Eigen::Matrix3d BodyRotation(double roll, double pitch, double heading) const {
    const Eigen::Matrix3d enu_from_cam = NedFromEnu().transpose() *
                                         maploc::NedFromBody({roll, pitch, heading}) *
                                         maploc::BodyFromCamera();
    return enu_from_cam * sensors.body_from_cam.rotation.matrix().transpose();
  }

  FixLog Locate(int64_t t_ns, const cv::Mat& gray, const maploc::Prior& prior) {
    FixLog log;
    log.t_ns = t_ns;
    log.global = !prior.position.has_value();
    const auto start = std::chrono::steady_clock::now();
    const maploc::LocateResult r = locator->Locate(gray, prior);
    log.locate_ms = Ms(start);
    stats.locate_ms += log.locate_ms;
    ++stats.fixes_tried;
    log.found = r.localized;
    log.reason = r.reason;
    log.method = r.method;
    if (r.localized) {
      ++stats.fixes_found;
      log.enu.head<2>() = enu.ToEnu(r.latlon, 0.0).head<2>();
      log.enu.z() = r.method == "features" ? r.altitude_m : -1;
      log.sigma_m =
          std::max(options.fix_sigma_floor_m, options.fix_sigma_scale * r.position_sigma_m);
      fix_attitude = {r.roll_deg, r.pitch_deg, r.heading_deg};
      if (options.inject_outlier_fraction > 0 &&
          std::uniform_real_distribution<double>(0, 1)(outlier_rng) <
              options.inject_outlier_fraction) {
        const double a = std::uniform_real_distribution<double>(0, 2 * M_PI)(outlier_rng);
        const double d = std::uniform_real_distribution<double>(options.outlier_min_m,
                                                                options.outlier_max_m)(outlier_rng);
        log.enu.head<2>() += d * Eigen::Vector2d(std::cos(a), std::sin(a));
        log.injected = true;
        ++stats.outliers_injected;
      }
    }
    return log;
  }
  Eigen::Vector3d fix_attitude = Eigen::Vector3d::Zero();  // of the last found fix

  std::optional<double> BaroAt(int64_t t_ns) const {
    // The latest sample at or before t (samples are consumed as they become factors).
    std::optional<double> out;
    if (last_baro && last_baro->t_ns <= t_ns) out = last_baro->altitude_m;
    for (const auto& b : baro)
      if (b.t_ns <= t_ns) out = b.altitude_m;
    return out;
  }

  // `bias`, `baro_bias_m`: what a restarted window keeps of the previous one (zero at first).
  void Start(int64_t t_ns, const Eigen::Vector3d& position, const Eigen::Matrix3d& rotation,
             const Eigen::Vector3d& velocity, double position_sigma, double yaw_sigma_rad,
             double velocity_sigma, const vio::ImuBias& bias = {}, double baro_bias_m = 0,
             double tilt_sigma_rad = -1) {
    backend_options.prior_position_sigma_m = position_sigma;
    backend_options.prior_yaw_sigma_rad = yaw_sigma_rad;
    backend_options.prior_tilt_sigma_rad =
        tilt_sigma_rad > 0 ? tilt_sigma_rad : options.init_tilt_sigma_deg * kDeg;
    alignment = Alignment::kOff;
    backend = std::make_unique<vio::SlidingWindowBackend>(backend_options, vio::RigExtrinsics{});
    vio::StateEstimate s;
    s.t_ns = t_ns;
    s.world_from_body = {Eigen::Quaterniond(rotation), position};
    s.velocity = velocity;
    s.bias = bias;
    backend->Initialize(s, {}, -1, velocity_sigma, -1);
    bias_block =
        backend->AddGlobalBlock(Eigen::VectorXd::Constant(1, baro_bias_m),
                                Eigen::VectorXd::Constant(1, options.baro_bias_sigma_m),
                                Eigen::VectorXd::Constant(1, options.baro_bias_walk_m_per_sqrt_s));
    wind_block = -1;
    if (options.drag_per_s > 0) {
      wind_block = backend->AddGlobalBlock(
          Eigen::VectorXd::Zero(2), Eigen::VectorXd::Constant(2, options.wind_prior_sigma_m_s),
          Eigen::VectorXd::Constant(2, options.wind_walk_m_s_per_sqrt_s));
    }
    covariance = backend->NewestCovariance();
    stats.initialized_at_ns = stats.initialized_at_ns.value_or(t_ns);
    last_accepted_fix_ns = t_ns;  // the start's position counts as the last fix
    gap_candidate.reset();
    gate_scale = 1.0;
    rejecting_since_ns.reset();
    // Barometer samples before the first state cannot be used.
    while (!baro.empty() && baro.front().t_ns < t_ns) baro.pop_front();
    spdlog::debug("nav: initialised at t={} s, position ({:.1f}, {:.1f}, {:.1f})", t_ns * 1e-9,
                  position.x(), position.y(), position.z());
  }

  void TryInitialize(int64_t t_ns, const cv::Mat& gray) {
    const std::optional<double> baro_alt = BaroAt(t_ns);
    if (options.start && !stats.initialized_at_ns) {  // only the first time
      const NavStart& st = *options.start;
      Eigen::Vector3d p = enu.ToEnu(st.position, 0.0);
      p.z() = baro_alt.value_or(0.0);
      Start(t_ns, p, EnuFromBodyOfAttitude(st.roll_deg, st.pitch_deg, st.heading_deg),
            st.velocity.value_or(Eigen::Vector3d::Zero()), st.position_sigma_m,
            st.heading_sigma_deg * kDeg,
            st.velocity ? st.velocity_sigma_m_s : options.init_velocity_sigma_m_s);
      return;
    }
    if (!locator) return;
    maploc::Prior prior;
    if (baro_alt && *baro_alt > 0) {
      prior.altitude_m = *baro_alt;
      prior.altitude_sigma_rel = 0.1;
    }
    if (search_hint && !candidate) {
      // After a relocalisation: around where the estimate was, as far as it may have drifted
      // (3 sigma + 300 m) plus 40 m/s since; a global search beyond the local limit.
      const double dt = (t_ns - search_hint->t_ns) * 1e-9;
      const double radius = 3.0 * search_hint->sigma_m + 300.0 + 40.0 * dt;
      if (radius <= options.max_local_radius_m) {
        prior.position =
            enu.FromEnu(Eigen::Vector3d(search_hint->position.x(), search_hint->position.y(), 0));
        prior.radius_m = radius;
      }
    }
    if (candidate) {
      const double dt = (t_ns - candidate->t_ns) * 1e-9;
      prior.position = enu.FromEnu(Eigen::Vector3d(candidate->enu.x(), candidate->enu.y(), 0));
      prior.radius_m = options.init_confirm_m + 40.0 * dt;
      prior.heading_deg = fix_attitude[2];
      prior.heading_sigma_deg = 20;
      // Confirmed by the blocks, as the global fix was: a search around a wrong candidate (a
      // wrong fix) finds a distinct-enough correlation peak there and would confirm it.
      prior.require_confirmed = true;
    }
    if (!prior.position) {
      // A global search costs seconds: at most one per global_search_interval_s of flight, as a
      // locator on one core in real time could do.
      if (last_global_try_ns &&
          (t_ns - *last_global_try_ns) * 1e-9 < options.global_search_interval_s - 1e-3) {
        return;
      }
      last_global_try_ns = t_ns;
    }
    FixLog log = Locate(t_ns, gray, prior);
    if (!log.found) {
      log.reason = "initialisation: " + log.reason;
      if (candidate && (t_ns - candidate->t_ns) * 1e-9 > 3.0) candidate.reset();
      fixes.push_back(log);
      return;
    }
    if (!candidate) {
      log.reason = "initialisation: waiting for a confirming fix";
      candidate = log;
      fixes.push_back(log);
      return;
    }
    const double dt = (t_ns - candidate->t_ns) * 1e-9;
    const Eigen::Vector2d d = log.enu.head<2>() - candidate->enu.head<2>();
    if (d.norm() > options.init_confirm_m + 40.0 * dt) {
      log.reason = "initialisation: not confirmed, restarting";
      candidate = log;
      fixes.push_back(log);
      return;
    }
    log.accepted = true;
    log.reason = "initialisation";
    ++stats.fixes_accepted;
    if (log.injected || candidate->injected) ++stats.outliers_accepted;
    Eigen::Vector3d p(log.enu.x(), log.enu.y(), log.enu.z() > 0 ? log.enu.z() : 0.0);
    if (baro_alt && *baro_alt > 0) p.z() = *baro_alt;
    const Eigen::Matrix3d rotation =
        BodyRotation(fix_attitude[0], fix_attitude[1], fix_attitude[2]);
    // The velocity from the two fixes only when they are far enough apart in time for it to
    // mean something (the confirmation usually comes 0.2 s later); else unknown, for the
    // homography factors to find.
    Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
    double velocity_sigma = options.init_velocity_sigma_m_s;
    if (dt >= 2.0) {
      velocity.head<2>() = d / dt;
      velocity_sigma = std::min(velocity_sigma, std::max(3.0, 3.0 * log.sigma_m / dt));
    }
    odometry_rejections = 0;
    Start(t_ns, p, rotation, velocity, log.sigma_m, 5 * kDeg, velocity_sigma);
    if (options.align_tilt_sigma_deg > 0) SetAlignment(Alignment::kLearningTilt, t_ns);
    candidate.reset();
    search_hint.reset();
    fixes.push_back(log);
  }

  // The horizontal ground offset (ground point minus camera, metres) of pixel `px` seen from a
  // camera with attitude enu_from_body at height h above the plane.
  std::optional<Eigen::Vector2d> GroundOffset(const Eigen::Matrix3d& enu_from_body, double h,
                                              const Eigen::Vector2d& px) const {
    const Eigen::Vector3d ray_cam = sensors.camera.Unproject(px);
    const Eigen::Vector3d d = enu_from_body * (sensors.body_from_cam.rotation * ray_cam);
    if (d.z() > -0.2 * d.norm()) return std::nullopt;  // beyond ~78 deg from nadir
    return Eigen::Vector2d((-h / d.z()) * d.head<2>());
  }

  void AddOdometry(int64_t t_ns, const cv::Mat& gray, const vio::StateEstimate& previous,
                   const vio::NavState& predicted) {
    const auto start = std::chrono::steady_clock::now();
    const OdometryStep step = odometry.Track(gray);
    stats.odometry_ms += Ms(start);
    if (!step.ok || !options.use_odometry) return;
    const double dt = (t_ns - previous.t_ns) * 1e-9;
    const double h_prev = previous.world_from_body.translation.z();
    const double h_cur = predicted.position.z();
    if (!(h_prev > 1) || !(h_cur > 1) || !(dt > 0)) return;
    const Eigen::Matrix3d r_prev = previous.world_from_body.rotation.toRotationMatrix();
    const Eigen::Matrix3d r_cur = predicted.world_from_body_rotation.toRotationMatrix();
    const Eigen::Matrix3d body_from_cam = sensors.body_from_cam.rotation.toRotationMatrix();
    const double w = sensors.camera.width, hgt = sensors.camera.height;
    std::array<Eigen::Vector3d, kOdometryPoints> rays_prev, rays_cur;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    int n = 0;
    for (const auto& [fx, fy] :
         {std::pair{0.5, 0.5}, {0.12, 0.12}, {0.88, 0.12}, {0.12, 0.88}, {0.88, 0.88}}) {
      const cv::Vec3d c(fx * w, fy * hgt, 1.0);
      const cv::Vec3d q = step.prev_from_cur * c;
      if (std::abs(q[2]) < 1e-9) return;
      const Eigen::Vector2d q_px(q[0] / q[2], q[1] / q[2]);
      const auto cur = GroundOffset(r_cur, h_cur, {c[0], c[1]});
      const auto prev = GroundOffset(r_prev, h_prev, q_px);
      if (!cur || !prev) return;
      rays_cur[n] = body_from_cam * sensors.camera.Unproject({c[0], c[1]});
      rays_prev[n] = body_from_cam * sensors.camera.Unproject(q_px);
      sum += *prev - *cur;
      ++n;
    }
    const double gsd = 0.5 * (h_prev + h_cur) / sensors.camera.fx;
    const double sigma = std::max(options.odometry_min_velocity_sigma * dt,
                                  options.odometry_pixel_sigma * gsd * std::sqrt(2.0));
    // Gate: a wrong homography (repeated texture, a blank frame's noise) must not pull the
    // state; the displacement (with the predicted attitude) against the IMU's prediction.
    const Eigen::Vector2d measured = sum / n;
    const Eigen::Vector2d expected =
        (predicted.position - previous.world_from_body.translation).head<2>();
    const double velocity_sigma_pred =
        std::sqrt(std::max(0.0, covariance(6, 6) + covariance(7, 7)));
    // A run of rejections means the prediction, not the homography, is off (e.g. a velocity
    // still unknown after the start): the next ones go in, under the robust loss.
    if ((measured - expected).norm() >
            3.0 * std::hypot(sigma, velocity_sigma_pred * dt) + 3.0 * dt &&
        odometry_rejections < 3) {
      ++stats.odometry_rejected;
      ++odometry_rejections;
      return;
    }
    odometry_rejections = 0;
    spdlog::trace("nav-odometry {} {:.4f} {:.4f} {:.3f} {}", t_ns, measured.x() / dt,
                  measured.y() / dt, sigma / dt, step.inliers);
    backend->AddTimedFactor(std::make_unique<DisplacementFactor>(
        t_ns - 1, rays_prev, rays_cur, sigma, options.odometry_rotation_sigma_scale * sigma,
        odometry_loss.get()));
    ++stats.odometry_factors;
  }

  // A found fix enters the estimate (the caller adds its factors or restarts at it).
  void Accept(FixLog& log) {
    log.accepted = true;
    if (alignment == Alignment::kSettling) ++settle_fixes;
    ++stats.fixes_accepted;
    if (log.injected) ++stats.outliers_accepted;
    last_accepted_fix_ns = log.t_ns;
    gap_candidate.reset();
  }

  void TryFix(int64_t t_ns, const cv::Mat& gray, const vio::NavState& predicted,
              const Eigen::Matrix3d& p_cov, double yaw_sigma_rad) {
    const Eigen::Matrix2d p_xy = p_cov.topLeftCorner<2, 2>();
    const double sigma_max = std::sqrt(std::max(
        0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(p_xy).eigenvalues().maxCoeff()));
    maploc::Prior prior;
    const double radius = std::max(options.min_prior_radius_m, 3.0 * sigma_max * gate_scale + 30.0);
    // A candidate waits for the next try (at least 3 s, longer at a slow fix rate).
    const double candidate_life_s =
        std::max(3.0, options.fix_rate_hz > 0 ? 2.5 / options.fix_rate_hz : 0.0);
    if (gap_candidate && (t_ns - gap_candidate->t_ns) * 1e-9 > candidate_life_s)
      gap_candidate.reset();
    if (gap_candidate) {
      // Confirm with a search that holds both the estimate and where the candidate put the
      // vehicle (moved by the estimate since): the correlation chooses between them, rather
      // than finding the candidate's place again because it was told to look only there.
      const Eigen::Vector2d c = predicted.position.head<2>() + 0.5 * gap_candidate->innovation;
      prior.position = enu.FromEnu(Eigen::Vector3d(c.x(), c.y(), 0));
      prior.radius_m =
          std::max(options.min_prior_radius_m,
                   0.5 * gap_candidate->innovation.norm() + 3.0 * gap_candidate->sigma_m + 20.0);
    } else if (radius <= options.max_local_radius_m) {
      prior.position =
          enu.FromEnu(Eigen::Vector3d(predicted.position.x(), predicted.position.y(), 0));
      prior.radius_m = radius;
    }
    double roll, pitch, heading;
    CameraAttitude(predicted.world_from_body_rotation.toRotationMatrix(), &roll, &pitch, &heading);
    prior.heading_deg = heading;
    prior.heading_sigma_deg = std::clamp(3.0 * yaw_sigma_rad / kDeg + 3.0, 5.0, 45.0);
    prior.roll_deg = roll;
    prior.pitch_deg = pitch;
    prior.attitude_sigma_deg = 1.5;
    const double h = predicted.position.z();
    if (h > 10) {
      prior.altitude_m = h;
      prior.altitude_sigma_rel = std::clamp(3.0 * std::sqrt(p_cov(2, 2)) / h, 0.05, 0.3);
    }
    FixLog log = Locate(t_ns, gray, prior);
    if (log.found) {
      const Eigen::Vector2d e = log.enu.head<2>() - predicted.position.head<2>();
      // Relocalisation: when most fixes of the last 20 s are refused by the gate, the estimate,
      // not the map, is wrong (a few wrong fixes cannot make most of them disagree). Start again
      // from a global search confirmed by a second fix.
      const auto refused_mostly = [&](bool refused) {
        recent_fixes.push_back({t_ns, refused, e, log.sigma_m});
        while (!recent_fixes.empty() && recent_fixes.front().t_ns < t_ns - 20'000'000'000)
          recent_fixes.pop_front();
        size_t n_refused = 0;
        for (const RecentFix& f : recent_fixes) n_refused += f.refused ? 1 : 0;
        return recent_fixes.size() >= 10 && n_refused >= 0.75 * recent_fixes.size();
      };
      // The last n fixes were refused and put the vehicle at the same offset from the
      // estimate (within 3 sigma + 20 m of this one's): consistent with each other, so the
      // estimate is what is off.
      const auto refused_consistently = [&](size_t n) {
        if (recent_fixes.size() < n) return false;
        for (size_t k = recent_fixes.size() - n; k < recent_fixes.size(); ++k) {
          const RecentFix& f = recent_fixes[k];
          if (!f.refused || (f.innovation - e).norm() > 3.0 * log.sigma_m + 20.0) return false;
        }
        return true;
      };
      const Eigen::Matrix2d s = p_xy + log.sigma_m * log.sigma_m * Eigen::Matrix2d::Identity();
      log.innovation_m = e.norm();
      log.innovation = e;
      log.chi2 = e.dot(s.ldlt().solve(e));
      const bool after_gap = options.confirm_after_gap_s > 0 &&
                             (!last_accepted_fix_ns ||
                              (t_ns - *last_accepted_fix_ns) * 1e-9 > options.confirm_after_gap_s);
      const bool far = log.innovation_m > 3.0 * log.sigma_m + 30.0;
      const bool gated =
          options.gate_chi2 > 0 && log.chi2 > options.gate_chi2 * gate_scale * gate_scale;
      if (gap_candidate && (gap_candidate->innovation - e).norm() <= 3.0 * log.sigma_m + 20.0) {
        // A second fix at the candidate's offset: restart there (AddFrame, after the solve).
        log.reason = "after a gap: confirmed, restarting at the fix";
        const double gap_s = (t_ns - last_accepted_fix_ns.value_or(t_ns)) * 1e-9;
        Accept(log);
        // After a gap the velocity drifted too (18 m/s after 60 s of IMU only, flight 2).
        restart_fix = Restart{
            log, fmt::format("after {:.0f} s without an accepted map fix, two agree", gap_s),
            options.init_velocity_sigma_m_s};
        relocalize = true;
        recent_fixes.clear();
      } else if (after_gap && far) {
        log.reason = "after a gap: far from the estimate, waiting for a confirming fix";
        gap_candidate = log;
      } else if (gated) {
        log.reason = "gate";
        ++stats.fixes_rejected;
        // Relocalise when most fixes of the last 20 s were refused (at the last fix when the
        // last 3 agree), or at once when the last 5 in a row agree.
        const bool mostly = refused_mostly(true);
        if (mostly || refused_consistently(5)) {
          relocalize = true;
          if (refused_consistently(3))
            restart_fix = Restart{
                log, "most map fixes of the last 20 s refused and the last ones agree", 5.0};
          recent_fixes.clear();
        }
        if (!rejecting_since_ns) rejecting_since_ns = t_ns;
        if ((t_ns - *rejecting_since_ns) * 1e-9 > options.reopen_after_s) {
          gate_scale *= 2.0;
          rejecting_since_ns = t_ns;
        }
      } else if (alignment == Alignment::kWaitingForFix) {
        // The tilt is known now: restart at this fix, computed with it, dropping the fixes the
        // window took while its tilt was still the start's guess (a level start on a vehicle
        // tilted 2.5 deg put flight 3 of `bench nav` 22 m off for its first 10 s).
        log.reason = "alignment done: restarting at the fix";
        Accept(log);
        const double v_sigma = std::sqrt(std::max(covariance(6, 6), covariance(7, 7)));
        restart_fix = Restart{log, "alignment", std::clamp(3.0 * v_sigma, 0.5, 5.0), true};
        relocalize = true;
      } else {
        Accept(log);
        refused_mostly(false);
        rejecting_since_ns.reset();
        gate_scale = std::max(1.0, gate_scale / 2.0);
        const double alt_sigma =
            log.enu.z() > 0 ? options.fix_altitude_sigma_rel * log.enu.z() : 0.0;
        const double yaw_sigma_deg = options.fix_yaw_sigma_deg;
        if (yaw_sigma_deg > 0) {
          // The fix's heading, when it agrees with the prediction within 3 sigma + 3 deg.
          const double innovation = std::remainder(fix_attitude.z() - heading, 360.0);
          if (std::abs(innovation) < 3.0 * std::hypot(yaw_sigma_deg, yaw_sigma_rad / kDeg) + 3.0) {
            backend->AddTimedFactor(std::make_unique<FixYawFactor>(
                t_ns, sensors.body_from_cam.rotation * Eigen::Vector3d(0, -1, 0),
                fix_attitude.z() * kDeg, yaw_sigma_deg * kDeg, map_loss.get()));
            ++stats.fix_yaws;
          }
        }
        backend->AddTimedFactor(std::make_unique<PositionFactor>(
            t_ns, Eigen::Vector3d(log.enu.x(), log.enu.y(), std::max(0.0, log.enu.z())),
            log.sigma_m, alt_sigma, map_loss.get()));
      }
    }
    spdlog::debug(
        "nav: t={:.1f} fix {} {} {} innovation {:.1f} m chi2 {:.1f} sigma {:.1f} m, "
        "prior radius {:.0f} m (gate x{:.0f})",
        t_ns * 1e-9, log.found ? "found" : "none", log.accepted ? "accepted" : "-", log.method,
        log.innovation_m, log.chi2, log.sigma_m, prior.position ? prior.radius_m : -1.0,
        gate_scale);
    fixes.push_back(log);
  }

  NavPose PoseOfNewest() const {
    const vio::StateEstimate s = backend->Newest();
    NavPose pose;
    pose.t_ns = s.t_ns;
    pose.world_from_body = s.world_from_body;
    pose.velocity = s.velocity;
    pose.position_covariance = covariance.topLeftCorner<3, 3>();
    pose.yaw_sigma_deg = std::sqrt(std::max(0.0, covariance(5, 5))) / kDeg;
    pose.baro_bias_m = backend->GlobalBlock(bias_block)[0];
    return pose;
  }

  std::optional<NavPose> AddFrame(int64_t t_ns, const cv::Mat& frame) {
    if (have_frame && t_ns <= last_frame_ns)
      throw Error("nav: frame timestamps must increase (" + std::to_string(t_ns) + " after " +
                  std::to_string(last_frame_ns) + ")");
    cv::Mat gray = frame;
    if (frame.channels() == 3) cv::cvtColor(frame, gray, cv::COLOR_BGR2GRAY);
    ++stats.frames;
    const bool due = !last_fix_try_ns || options.fix_rate_hz <= 0 ||
                     (t_ns - *last_fix_try_ns) * 1e-9 >= 1.0 / options.fix_rate_hz - 1e-3;
    if (!initialized()) {
      // Global searches at the fix rate (each costs about a second); the confirming local search
      // of a candidate on the next frame.
      if (due || candidate || options.start) {
        TryInitialize(t_ns, gray);
        last_fix_try_ns = t_ns;
      }
      std::erase_if(imu,
                    [&](const vio::TimedImuSample& s) { return s.t_ns < t_ns - 1'000'000'000; });
      odometry.Reset();
      odometry.Track(gray);
      have_frame = true;
      last_frame_ns = t_ns;
      return initialized() && alignment == Alignment::kOff ? std::optional<NavPose>(PoseOfNewest())
                                                           : std::nullopt;
    }
    const std::vector<vio::ImuMeasurement> measurements =
        vio::ImuMeasurementsBetween(imu, last_frame_ns, t_ns);
    if (measurements.empty())
      throw Error("nav: no IMU samples between frames at " + std::to_string(last_frame_ns) +
                  " and " + std::to_string(t_ns) + " ns");
    const vio::StateEstimate previous = backend->Newest();
    vio::ImuPreintegration pre(previous.bias, backend_options.imu_noise);
    for (const auto& m : measurements) pre.Integrate(m.gyro, m.accel, m.dt_s);
    const vio::NavState predicted =
        pre.Predict({previous.world_from_body.rotation, previous.world_from_body.translation,
                     previous.velocity},
                    previous.bias, backend_options.gravity);
    if (wind_block >= 0) {
      // The interval's mean specific force at its middle (blank frames too: the drag needs no
      // texture).
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      double span = 0;
      for (const auto& m : measurements) sum += m.accel * m.dt_s, span += m.dt_s;
      if (span > 0) {
        backend->AddTimedFactor(std::make_unique<DragFactor>(
            previous.t_ns + static_cast<int64_t>(0.5 * span * 1e9), (sum / span).head<2>(),
            options.drag_per_s, options.drag_sigma_m_s2, wind_block));
      }
    }
    // Barometer samples up to the frame.
    while (!baro.empty() && baro.front().t_ns <= t_ns) {
      backend->AddTimedFactor(
          std::make_unique<BaroFactor>(baro.front(), options.baro_sigma_m, bias_block, nullptr));
      ++stats.baro_factors;
      baro.pop_front();
    }
    // GNSS positions up to the frame, gated against the prediction moved to their time.
    while (!gnss.empty() && gnss.front().t_ns <= t_ns) {
      const Gnss g = gnss.front();
      gnss.pop_front();
      if (g.t_ns < previous.t_ns) continue;
      const double dt = (t_ns - g.t_ns) * 1e-9;
      const Eigen::Vector3d at_sample = predicted.position - dt * predicted.velocity;
      const Eigen::Matrix3d s = covariance.topLeftCorner<3, 3>() +
                                Eigen::Matrix3d::Identity() * (g.sigma * g.sigma + 0.25);
      const Eigen::Vector3d e = g.enu - at_sample;
      if (options.gnss_gate_chi2 > 0 && e.dot(s.ldlt().solve(e)) > options.gnss_gate_chi2) continue;
      backend->AddTimedFactor(
          std::make_unique<PositionFactor>(g.t_ns, g.enu, g.sigma, g.sigma, map_loss.get()));
      ++stats.gnss_accepted;
    }
    AddOdometry(t_ns, gray, previous, predicted);
    if (locator && due) {
      const double dt = pre.dt_s();
      const Eigen::Matrix3d p_cov = covariance.topLeftCorner<3, 3>() +
                                    dt * dt * covariance.block<3, 3>(6, 6) +
                                    Eigen::Matrix3d::Identity() * (0.5 * dt * dt);
      TryFix(t_ns, gray, predicted, p_cov, std::sqrt(std::max(0.0, covariance(5, 5))));
      last_fix_try_ns = t_ns;
    }
    const auto start = std::chrono::steady_clock::now();
    const vio::StateEstimate estimate = backend->AddFrame(t_ns, pre, {}, true);
    covariance = backend->NewestCovariance();
    stats.solve_ms += Ms(start);
    spdlog::trace(
        "nav-state {} v {:.3f} {:.3f} {:.3f} bg {:.5f} {:.5f} {:.5f} ba {:.4f} {:.4f} {:.4f}", t_ns,
        estimate.velocity.x(), estimate.velocity.y(), estimate.velocity.z(), estimate.bias.gyro.x(),
        estimate.bias.gyro.y(), estimate.bias.gyro.z(), estimate.bias.accel.x(),
        estimate.bias.accel.y(), estimate.bias.accel.z());
    ++stats.states;
    have_frame = true;
    last_frame_ns = t_ns;
    // Keep one second of IMU before the newest frame.
    std::erase_if(imu, [&](const vio::TimedImuSample& s) { return s.t_ns < t_ns - 1'000'000'000; });
    if (relocalize) {
      relocalize = false;
      const NavPose last = PoseOfNewest();
      const bool ends_alignment = restart_fix && restart_fix->ends_alignment;
      if (!ends_alignment) ++stats.resets;
      if (restart_fix && restart_fix->fix.t_ns == t_ns) {
        // Restart at the fix with the estimate's attitude, velocity and biases (the position
        // drifted, the rest is likely sound; the velocity loosened). At the end of the
        // alignment the tilt keeps the sigma it reached, the yaw its own.
        const FixLog& fix = restart_fix->fix;
        if (ends_alignment)
          spdlog::debug(
              "nav: aligned at t={} s: restarting at the fix ({:.0f} m from the estimate)",
              t_ns * 1e-9, fix.innovation_m);
        else
          spdlog::warn("nav: {} at t={} s: restarting at the fix ({:.0f} m from the estimate)",
                       restart_fix->why, t_ns * 1e-9, fix.innovation_m);
        Eigen::Vector3d p = last.world_from_body.translation;
        p.head<2>() = fix.enu.head<2>();
        const double yaw_sigma = ends_alignment ? std::max(0.5 * kDeg, last.yaw_sigma_deg * kDeg)
                                                : std::max(5.0 * kDeg, last.yaw_sigma_deg * kDeg);
        const double tilt_sigma = ends_alignment ? std::max(0.2 * kDeg, TiltSigma()) : -1.0;
        Start(t_ns, p, last.world_from_body.rotation.toRotationMatrix(), last.velocity, fix.sigma_m,
              yaw_sigma, restart_fix->velocity_sigma_m_s, backend->Newest().bias, last.baro_bias_m,
              tilt_sigma);
        restart_fix.reset();
        if (ends_alignment) {
          SetAlignment(Alignment::kSettling, t_ns);
          return std::nullopt;
        }
        return PoseOfNewest();
      }
      spdlog::warn(
          "nav: most map fixes of the last 20 s refused at t={} s, relocalising by a search "
          "around the estimate",
          t_ns * 1e-9);
      restart_fix.reset();
      const double sigma =
          std::sqrt(std::max(0.0, last.position_covariance(0, 0) + last.position_covariance(1, 1)));
      search_hint = SearchHint{t_ns, last.world_from_body.translation.head<2>(), sigma};
      backend.reset();
      return last;
    }
    // The alignment's phases; without an accepted fix for 5 s in the later ones, go on.
    const double phase_s = (t_ns - alignment_since_ns) * 1e-9;
    if (alignment == Alignment::kLearningTilt) {
      spdlog::debug("nav: aligning at t={} s: tilt sigma {:.2f} deg", t_ns * 1e-9,
                    TiltSigma() / kDeg);
      if (TiltSigma() < options.align_tilt_sigma_deg * kDeg || phase_s > options.align_max_s)
        SetAlignment(Alignment::kWaitingForFix, t_ns);
    } else if (alignment == Alignment::kWaitingForFix && phase_s > 5.0) {
      alignment = Alignment::kOff;
    } else if (alignment == Alignment::kSettling && (settle_fixes >= 2 || phase_s > 5.0)) {
      alignment = Alignment::kOff;
    }
    const double sigma_h = std::sqrt(std::max(0.0, covariance(0, 0) + covariance(1, 1)));
    if (!estimate.world_from_body.translation.allFinite() || !estimate.velocity.allFinite() ||
        !(sigma_h < 5000.0)) {
      spdlog::warn(
          "nav: estimate diverged at t={} s (horizontal sigma {} m, speed {} m/s), "
          "re-initialising",
          t_ns * 1e-9, sigma_h, estimate.velocity.norm());
      backend.reset();
      ++stats.resets;
      return std::nullopt;
    }
    if (alignment != Alignment::kOff) return std::nullopt;  // no pose while aligning
    return PoseOfNewest();
  }
};

MapAidedNavigator::MapAidedNavigator(const NavOptions& options, const NavSensors& sensors,
                                     const maploc::MapDatabase* db,
                                     const maploc::LocateOptions& locate_options,
                                     const geo::LatLon& origin)
    : impl_(std::make_unique<Impl>(options, sensors, db, locate_options, origin)) {}

MapAidedNavigator::~MapAidedNavigator() = default;

void MapAidedNavigator::AddImu(const io::ImuSample& s) {
  if (!impl_->imu.empty() && s.t_ns <= impl_->imu.back().t_ns)
    throw Error("nav: IMU timestamps must increase (" + std::to_string(s.t_ns) + ")");
  if (!s.gyro_rad_s.allFinite() || !s.accel_m_s2.allFinite())
    throw Error("nav: IMU sample at " + std::to_string(s.t_ns) + " ns is not finite");
  impl_->imu.push_back({s.t_ns, s.gyro_rad_s, s.accel_m_s2});
}

void MapAidedNavigator::AddBaro(const io::BaroSample& s) {
  if (impl_->last_baro && s.t_ns <= impl_->last_baro->t_ns)
    throw Error("nav: barometer timestamps must increase (" + std::to_string(s.t_ns) + ")");
  impl_->last_baro = s;
  impl_->baro.push_back(s);
  // Before initialisation only the latest few are kept (for the start altitude).
  if (!impl_->initialized())
    while (impl_->baro.size() > 100) impl_->baro.pop_front();
}

void MapAidedNavigator::AddGnss(int64_t t_ns, const Eigen::Vector3d& enu, double sigma_m) {
  if (!impl_->gnss.empty() && t_ns <= impl_->gnss.back().t_ns)
    throw Error("nav: GNSS timestamps must increase (" + std::to_string(t_ns) + ")");
  if (!enu.allFinite() || !(sigma_m > 0))
    throw Error("nav: GNSS sample at " + std::to_string(t_ns) + " ns is not finite");
  ++impl_->stats.gnss_received;
  impl_->gnss.push_back({t_ns, enu, sigma_m});
  if (!impl_->initialized())
    while (impl_->gnss.size() > 100) impl_->gnss.pop_front();
}

std::optional<NavPose> MapAidedNavigator::AddFrame(int64_t t_ns, const cv::Mat& frame) {
  return impl_->AddFrame(t_ns, frame);
}

const std::vector<FixLog>& MapAidedNavigator::fixes() const { return impl_->fixes; }
const NavStats& MapAidedNavigator::stats() const { return impl_->stats; }
const geo::LocalEnu& MapAidedNavigator::enu() const { return impl_->enu; }

}  // namespace optinav::nav
