#include "optinav/nav/internal/mission_nav.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include "optinav/geo/geo.h"
#include "optinav/geometry/angles.h"
#include "optinav/maploc/frame_synth.h"
#include "optinav/nav/internal/closed_loop_flight.h"
#include "optinav/util/error.h"
#include "optinav/util/timer.h"

namespace optinav::nav {

namespace {

constexpr double kDeg = M_PI / 180.0;
// Guidance: the turn rate commanded per radian of course error (saturating at the bank limit).
constexpr double kCourseGain = 0.5;  // 1/s

// The corner ray's angle from the optical axis (deg).
double CornerDeg(const camera::PinholeCamera& c) {
  return std::atan(std::hypot(0.5 * c.width, 0.5 * c.height) / c.fx) / kDeg;
}

// The fraction along a-b of the point closest to p.
double ClosestFraction(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                       const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  return len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 1.0;
}

}  // namespace

std::string CheckNavMission(const maploc::MapDatabase& db, const MissionOptions& o) {
  const sim::NadirCameraOptions& c = o.nadir;
  if (c.width < 64 || c.height < 64 || c.width > 4096 || c.height > 4096)
    return fmt::format("--nadir-camera {}x{} not within 64x64 to 4096x4096", c.width, c.height);
  if (!(c.hfov_deg >= 20 && c.hfov_deg <= 120))
    return fmt::format("--nadir-hfov {} deg not in [20, 120]", c.hfov_deg);
  if (!(c.rate_hz >= 1 && c.rate_hz <= 30))
    return fmt::format("--nadir-rate {} Hz not in [1, 30]", c.rate_hz);
  const camera::PinholeCamera cam = c.Camera();
  const double altitude = o.altitude_m > 0 ? o.altitude_m : db.options.altitude_m;
  const double footprint = altitude * (1 - o.effects.altitude_variation) / cam.fx * c.width;
  if (o.speed_m_s / c.rate_hz > 0.3 * footprint) {
    return fmt::format(
        "speed / nadir rate = {:.0f} m per frame is more than 30 % of the nadir camera's "
        "footprint ({:.0f} m); lower --speed or raise --nadir-rate",
        o.speed_m_s / c.rate_hz, footprint);
  }
  // Bank plus gusts must keep the horizon out of the frame (a corner ray 5 deg below it).
  const double max_tilt = 85.0 - CornerDeg(cam);
  if (o.max_bank_deg + o.effects.max_tilt_deg > max_tilt) {
    return fmt::format(
        "bank ({} deg) plus gust tilt (--tilt {} deg) would put the horizon in the nadir frame "
        "(at most {:.0f} deg together with a {:.0f} deg field of view)",
        o.max_bank_deg, o.effects.max_tilt_deg, max_tilt, c.hfov_deg);
  }
  if (const std::string e = o.imu.Check(); !e.empty()) return e;
  if (const std::string e = o.baro.Check(); !e.empty()) return e;
  if (const std::string e = o.nav.Check(); !e.empty()) return "nav: " + e;
  return "";
}

MissionResult RunNavMission(const maploc::MapDatabase& db, const geo::GeoRaster& frames,
                            double frames_gsd_m, const maploc::LocateOptions& locate_options,
                            const MissionOptions& o) {
  const geo::CrsTransform frames_crs(frames.crs_wkt());
  auto frames_pixel = [&](const geo::LatLon& ll) {
    return frames.transform().CrsToPixel(frames_crs.FromLatLon(ll));
  };
  // A heading (deg clockwise from north) as an angle in the frames raster (deg from up).
  auto heading_in_frames = [&](const geo::LatLon& ll, double heading_deg) {
    const Eigen::Vector2d d =
        frames_pixel(geo::GeodesicDirect(ll, heading_deg, 20.0)) - frames_pixel(ll);
    return std::atan2(d.x(), -d.y()) / kDeg;
  };
  const double altitude = o.altitude_m > 0 ? o.altitude_m : db.options.altitude_m;
  const camera::PinholeCamera cam = o.nadir.Camera();

  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> u01(0, 1);
  const double heading_error = o.compass_bias_deg * (2 * u01(rng) - 1);
  const double wind_dir = 2 * M_PI * u01(rng);
  std::mt19937_64 effects_rng(rng());

  const geo::LocalEnu enu(o.start, 0.0);
  const Eigen::Vector2d target = enu.ToEnu(o.target, 0.0).head<2>();
  const double heading0 = geo::GeodesicInverse(o.start, o.target).azimuth1_deg;
  FlightModelOptions fo;
  fo.air_speed_m_s = o.speed_m_s;
  fo.altitude_m = altitude;
  fo.altitude_variation = o.effects.altitude_variation;
  fo.max_bank_deg = o.max_bank_deg;
  fo.gust_tilt_deg = o.effects.max_tilt_deg;
  fo.wind_m_s = o.wind_m_s * Eigen::Vector2d(std::sin(wind_dir), std::cos(wind_dir));
  fo.seed = rng();
  ClosedLoopFlight flight(fo, Eigen::Vector2d::Zero(), heading0);
  sim::ImuSensor imu(o.imu, rng());
  sim::BaroSensor baro(o.baro, rng());

  NavOptions nav_options = o.nav;
  nav_options.use_odometry = o.nav.use_odometry && o.use_odometry;
  // The start as the 2-D filter gets it: the position within ~10 m, the heading with the
  // compass error; roll and pitch from the autopilot's AHRS, with its error (attitude_noise_deg);
  // the velocity from the air speed. Without the velocity the window starts at rest (30 m/s
  // sigma): that prior stays in the marginalised window and pulls the speed down, and in
  // unaccelerated flight the pitch (with the accelerometer bias) can follow, which scales the
  // homography's displacement (10 % slow, 1 deg of pitch, measured).
  double roll0, pitch0, yaw0;
  AttitudeOfEnuFromBody(flight.State().world_from_body.rotation.toRotationMatrix(), &roll0, &pitch0,
                        &yaw0);
  std::normal_distribution<double> n01(0, 1);
  NavStart start{o.start, WrapDeg360(heading0 + heading_error), 10.0,
                 std::max(5.0, o.compass_bias_deg)};
  start.roll_deg = roll0 + o.attitude_noise_deg * n01(rng);
  start.pitch_deg = pitch0 + o.attitude_noise_deg * n01(rng);
  // The air speed along the given heading (a pitot tube); the wind is what the estimator learns.
  start.velocity = o.speed_m_s * Eigen::Vector3d(std::sin(start.heading_deg * kDeg),
                                                 std::cos(start.heading_deg * kDeg), 0.0);
  start.velocity_sigma_m_s = 10.0;
  nav_options.start = start;
  nav_options.init_tilt_sigma_deg = std::max(1.0, 2.0 * o.attitude_noise_deg);
  nav_options.gyro_noise_density = o.imu.gyroscope_noise_density;
  nav_options.accel_noise_density = o.imu.accelerometer_noise_density;
  nav_options.gyro_random_walk = o.imu.gyroscope_random_walk;
  nav_options.accel_random_walk = o.imu.accelerometer_random_walk;
  nav_options.baro_sigma_m = std::max(nav_options.baro_sigma_m, o.baro.noise_sigma_m);
  MapAidedNavigator navigator(nav_options, {cam, sim::NadirCameraMount()}, &db, locate_options,
                              o.start);

  MissionResult res;
  res.straight_distance_m = geo::GeodesicInverse(o.start, o.target).distance_m;
  const double time_limit =
      o.time_limit_s > 0 ? o.time_limit_s : 3.0 * res.straight_distance_m / o.speed_m_s + 120.0;
  const int64_t frame_ns = std::llround(1e9 / o.nadir.rate_hz);
  const int64_t imu_ns = std::llround(1e9 / o.imu.rate_hz);
  const int64_t baro_ns = std::llround(1e9 / o.baro.rate_hz);
  const int frames_per_step =
      std::max(1, static_cast<int>(std::lround(o.step_s * o.nadir.rate_hz)));
  int64_t next_imu = 0, next_baro = 0;
  size_t fixes_logged = 0, odometry_logged = 0;
  double locate_ms_logged = 0, odometry_ms_logged = 0;
  std::optional<Eigen::Vector2d> previous_estimate;
  Eigen::Vector2d previous_truth = Eigen::Vector2d::Zero(), truth_before = Eigen::Vector2d::Zero();
  std::vector<std::pair<int64_t, geo::LatLon>> step_truth;  // the truth at this step's frames
  StepTimes step_times;
  double command_deg = heading0;

  for (int k = 0;; ++k) {
    const int64_t t = k * frame_ns;
    // 1. The sensors up to the frame, in time order.
    Timer synth;
    while (next_imu <= t || next_baro <= t) {
      if (next_imu <= next_baro) {
        flight.AdvanceTo(next_imu);
        sim::BodyState s = flight.State();
        s.t_ns = next_imu;
        const sim::ImuMeasurement m = imu.Measure(s);
        step_times.synthesis_ms += synth.ElapsedMs();
        const Timer nav_timer;
        navigator.AddImu({m.t_ns, m.gyro_rad_s, m.accel_m_s2});
        step_times.navigation_ms += nav_timer.ElapsedMs();
        synth.Restart();
        next_imu += imu_ns;
      } else {
        flight.AdvanceTo(next_baro);
        const double z = flight.State().world_from_body.translation.z();
        const sim::BaroMeasurement m = baro.Measure(next_baro, z);
        step_times.synthesis_ms += synth.ElapsedMs();
        const Timer nav_timer;
        navigator.AddBaro({m.t_ns, m.altitude_m});
        step_times.navigation_ms += nav_timer.ElapsedMs();
        synth.Restart();
        next_baro += baro_ns;
      }
    }
    flight.AdvanceTo(t);
    const sim::BodyState truth_state = flight.State();
    const Eigen::Vector3d& p = truth_state.world_from_body.translation;
    const geo::LatLon truth = enu.FromEnu(Eigen::Vector3d(p.x(), p.y(), 0.0));
    if (k > 0) res.flown_m += (p.head<2>() - previous_truth).norm();
    truth_before = previous_truth;
    previous_truth = p.head<2>();
    step_truth.emplace_back(t, truth);

    // 2. The nadir frame at the true pose.
    double roll, pitch, heading;
    AttitudeOfEnuFromBody(truth_state.world_from_body.rotation.toRotationMatrix(), &roll, &pitch,
                          &heading);
    const maploc::AerialPose pose{
        .nadir_px = frames_pixel(truth),
        .altitude_m = p.z(),
        .attitude = {.roll_deg = roll,
                     .pitch_deg = pitch,
                     .yaw_deg = WrapDeg360(heading_in_frames(truth, heading))}};
    cv::Mat frame = maploc::RenderAerialFrame(frames, frames_gsd_m, pose, cam);
    ApplyPhotometricEffects(frame, o.effects, 0.0, effects_rng);
    if (o.weather) {
      o.weather(frame, {.t_ns = t,
                        .position_enu = p,
                        .heading_deg = heading,
                        .roll_deg = roll,
                        .pitch_deg = pitch,
                        .focal_px = cam.fx,
                        .width = cam.width,
                        .height = cam.height});
    }
    step_times.synthesis_ms += synth.ElapsedMs();

    // 3. The estimate, and guidance on the estimated course.
    Timer nav_timer;
    const std::optional<NavPose> estimate = navigator.AddFrame(t, frame);
    Eigen::Vector2d est_xy = Eigen::Vector2d::Zero();
    double sigma = 0;
    bool arrived = false;
    Eigen::Vector2d arrival_truth = p.head<2>();
    if (estimate) {
      est_xy = estimate->world_from_body.translation.head<2>();
      sigma = std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(
                                          estimate->position_covariance.topLeftCorner<2, 2>())
                                          .eigenvalues()
                                          .maxCoeff()));
      // Arrival: the estimate passes within the radius during the last frame interval. The
      // vehicle is where its estimate was closest to the target (the 2-D loop's last step flies
      // exactly to the estimated target): the true position at that fraction of the interval.
      const Eigen::Vector2d from = previous_estimate.value_or(est_xy);
      const double f = ClosestFraction(target, from, est_xy);
      if ((from + f * (est_xy - from) - target).norm() <= o.arrive_radius_m) {
        arrived = true;
        arrival_truth = truth_before + f * (p.head<2>() - truth_before);
      }
      previous_estimate = est_xy;
      const Eigen::Vector2d to_target = target - est_xy;
      const Eigen::Vector2d v = estimate->velocity.head<2>();
      double roll_e, pitch_e, yaw_e;
      AttitudeOfEnuFromBody(estimate->world_from_body.rotation.toRotationMatrix(), &roll_e,
                            &pitch_e, &yaw_e);
      const double course = v.norm() > 0.3 * o.speed_m_s ? std::atan2(v.x(), v.y()) : yaw_e * kDeg;
      const double bearing = std::atan2(to_target.x(), to_target.y());
      command_deg = WrapDeg360(bearing / kDeg);
      flight.Command(kCourseGain * WrapRadPi(bearing - course));
    }
    step_times.navigation_ms += nav_timer.ElapsedMs();
    const double t_s = t * 1e-9;
    const bool timeout = t_s >= time_limit;
    if (o.keep_frames && k % frames_per_step == 0) res.frames.push_back(frame.clone());

    // 4. The step log: every frames_per_step frames, and the last frame.
    if ((k + 1) % frames_per_step == 0 || arrived || timeout) {
      StepLog log;
      log.step = static_cast<int>(res.steps.size());
      log.t_s = t_s;
      log.truth = truth;
      log.truth_heading_deg = heading;
      log.command_heading_deg = command_deg;
      log.altitude_m = p.z();
      log.roll_deg = roll;
      log.pitch_deg = pitch;
      log.estimate = estimate ? enu.FromEnu(Eigen::Vector3d(est_xy.x(), est_xy.y(), 0)) : o.start;
      log.estimate_error_m = estimate ? (est_xy - p.head<2>()).norm() : -1;
      log.estimate_sigma_m = sigma;
      const std::vector<FixLog>& fixes = navigator.fixes();
      for (; fixes_logged < fixes.size(); ++fixes_logged) {
        const FixLog& f = fixes[fixes_logged];
        log.global_search |= f.global;
        if (f.found && (!log.fix_found || f.accepted)) {
          log.fix_found = true;
          log.fix_accepted = f.accepted;
          log.fix = enu.FromEnu(Eigen::Vector3d(f.enu.x(), f.enu.y(), 0));
          for (const auto& [tf, ll] : step_truth)
            if (tf == f.t_ns) log.fix_error_m = geo::GeodesicInverse(log.fix, ll).distance_m;
        }
        if (f.found || !log.fix_found) {
          log.fix_method = f.method;
          log.fix_reason = f.reason;
        }
      }
      const NavStats& stats = navigator.stats();
      log.odometry_ok = stats.odometry_factors > odometry_logged;
      odometry_logged = stats.odometry_factors;
      step_times.locate_ms = stats.locate_ms - locate_ms_logged;
      step_times.odometry_ms = stats.odometry_ms - odometry_ms_logged;
      locate_ms_logged = stats.locate_ms;
      odometry_ms_logged = stats.odometry_ms;
      log.times = step_times;
      step_times = StepTimes();
      step_truth.clear();
      res.steps.push_back(log);
    }
    if (arrived || timeout) {
      res.end_reason = arrived ? "arrived" : "time limit";
      res.duration_s = t_s;
      res.final_distance_m = (target - arrival_truth).norm();
      break;
    }
  }
  res.reached = res.final_distance_m <= o.success_radius_m;
  return res;
}

}  // namespace optinav::nav
