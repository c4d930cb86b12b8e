#include "optinav/nav/mission.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "optinav/geo/geo.h"
#include "optinav/geometry/angles.h"
#include "optinav/maploc/aerial_camera.h"
#include "optinav/maploc/frame_synth.h"
#include "optinav/nav/internal/mission_nav.h"
#include "optinav/util/timer.h"

namespace optinav::nav {

namespace {

constexpr double kDeg = M_PI / 180.0;

// Angle (radians, clockwise from raster up) of a pixel direction.
double PixelAngle(const Eigen::Vector2d& d) { return std::atan2(d.x(), -d.y()); }

Eigen::Vector2d RotateFrameToMap(double theta, const Eigen::Vector2d& v) {
  const double c = std::cos(theta), s = std::sin(theta);
  return {c * v.x() - s * v.y(), s * v.x() + c * v.y()};
}

}  // namespace

struct Mission::Impl {
  Impl(const maploc::MapDatabase& d, const geo::GeoRaster& f, const maploc::LocateOptions& lo)
      : db(d),
        frames(f),
        locate_options(lo),
        locator(d, lo),
        map_crs(d.crs_wkt),
        frames_crs(f.crs_wkt()) {
    const double hfov = db.options.hfov_deg * kDeg;
    focal = 0.5 * db.options.frame_width / std::tan(0.5 * hfov);
    camera = camera::PinholeCamera::FromHorizontalFov(db.options.frame_width,
                                                      db.options.frame_height, hfov);
    const Eigen::Vector2d mid =
        frames.transform().PixelToCrs(Eigen::Vector2d(0.5 * frames.width(), 0.5 * frames.height()));
    frames_gsd = frames.transform().UnitsPerPixel() * frames_crs.MetresPerUnit(mid);
  }

  Eigen::Vector2d FramesPixel(const geo::LatLon& ll) const {
    return frames.transform().CrsToPixel(frames_crs.FromLatLon(ll));
  }
  // Heading (deg clockwise from true north) as an angle in the frames raster (deg from up).
  double HeadingInFrames(const geo::LatLon& ll, double heading_deg) const {
    const Eigen::Vector2d a = FramesPixel(ll);
    const Eigen::Vector2d b = FramesPixel(geo::GeodesicDirect(ll, heading_deg, 20.0));
    return PixelAngle(b - a) / kDeg;
  }

  const maploc::MapDatabase& db;
  const geo::GeoRaster& frames;
  maploc::LocateOptions locate_options;
  maploc::Locator locator;
  geo::CrsTransform map_crs, frames_crs;
  double focal = 0, frames_gsd = 0;
  camera::PinholeCamera camera;  // the map's camera (principal point at the frame centre)
};

Mission::Mission(const maploc::MapDatabase& db, const geo::GeoRaster& frames,
                 const maploc::LocateOptions& locate_options)
    : impl_(std::make_unique<Impl>(db, frames, locate_options)) {}

Mission::~Mission() = default;

double Mission::focal_px() const { return impl_->focal; }
double Mission::map_gsd_m() const { return impl_->db.map_gsd_m; }
maploc::Locator& Mission::locator() { return impl_->locator; }

bool Mission::InsideMap(const geo::LatLon& ll, double margin_m) const {
  Eigen::Vector2d px;
  try {
    px = impl_->locator.LatLonToPixel(ll);
  } catch (const Error&) {
    return false;  // outside the CRS's domain
  }
  const double m = margin_m / impl_->db.map_gsd_m;
  return px.x() >= m && px.y() >= m && px.x() <= impl_->db.width - m &&
         px.y() <= impl_->db.height - m;
}

std::string Mission::Check(const MissionOptions& o) const {
  auto ll = [](const geo::LatLon& p) { return fmt::format("{:.6f},{:.6f}", p.lat_deg, p.lon_deg); };
  for (const auto& [name, p] : {std::pair{"start", o.start}, std::pair{"target", o.target}}) {
    if (!std::isfinite(p.lat_deg) || !std::isfinite(p.lon_deg) || std::abs(p.lat_deg) > 90 ||
        std::abs(p.lon_deg) > 180) {
      return fmt::format("{} {} is not a valid latitude,longitude", name, ll(p));
    }
    if (!InsideMap(p)) return fmt::format("{} {} is outside the map", name, ll(p));
  }
  const double built = impl_->db.options.altitude_m;
  const double alt = o.altitude_m > 0 ? o.altitude_m : built;
  if (!(o.speed_m_s > 0 && o.speed_m_s <= 150)) {
    return fmt::format("speed must be in (0, 150] m/s, got {}", o.speed_m_s);
  }
  if (!(o.altitude_m >= 0) || alt < 0.5 * built || alt > 2.0 * built) {
    return fmt::format(
        "altitude {} m is out of range for this map: it was built for {} m; frames must be "
        "within 0.5-2x of that ({:.0f}-{:.0f} m) to match its features",
        o.altitude_m, built, 0.5 * built, 2 * built);
  }
  if (!(o.step_s > 0 && o.step_s <= 10)) {
    return fmt::format("step time must be in (0, 10] s, got {}", o.step_s);
  }
  if (o.estimator != "2d" && o.estimator != "nav") {
    return fmt::format("estimator must be 2d or nav, got '{}'", o.estimator);
  }
  if (o.estimator == "nav") {
    if (const std::string e = CheckNavMission(impl_->db, o); !e.empty()) return e;
  }
  const double footprint = alt / impl_->focal * impl_->db.options.frame_width;
  if (o.estimator == "2d" && o.speed_m_s * o.step_s > 0.3 * footprint) {
    return fmt::format(
        "speed x step = {:.0f} m per frame is more than 30 % of the camera footprint ({:.0f} m): "
        "consecutive frames would not overlap enough; lower --speed or the step time",
        o.speed_m_s * o.step_s, footprint);
  }
  if (!(o.arrive_radius_m > 0) || !(o.success_radius_m > 0)) {
    return "arrival and success radii must be positive";
  }
  if (!(o.time_limit_s >= 0)) return "time limit must be >= 0";
  if (!(o.compass_bias_deg >= 0 && o.compass_bias_deg <= 45)) {
    return "compass bias must be in [0, 45] deg";
  }
  if (!(o.attitude_noise_deg >= 0 && o.attitude_noise_deg <= 10)) {
    return fmt::format("attitude noise must be in [0, 10] deg, got {}", o.attitude_noise_deg);
  }
  if (!(o.max_bank_deg >= 0 && o.max_bank_deg <= 30)) {
    return fmt::format("max bank must be in [0, 30] deg, got {}", o.max_bank_deg);
  }
  if (!(o.wind_m_s >= 0 && o.wind_m_s < o.speed_m_s)) {
    return fmt::format("wind must be in [0, speed) m/s, got {}", o.wind_m_s);
  }
  if (!(o.odometry_sigma > 0) || !(o.dead_reckoning_sigma > 0) || !(o.gate_chi2 > 0)) {
    return "odometry/dead-reckoning sigmas and the fix gate must be positive";
  }
  if (o.global_after_failures < 1) return "global_after_failures must be >= 1";
  const double d = geo::GeodesicInverse(o.start, o.target).distance_m;
  if (d <= o.arrive_radius_m) {
    return fmt::format("start and target are {:.1f} m apart, within the arrival radius ({} m)", d,
                       o.arrive_radius_m);
  }
  return o.effects.Check();
}

MissionResult Mission::Run(const MissionOptions& o) {
  if (const std::string e = Check(o); !e.empty()) throw Error(e);
  Impl& im = *impl_;
  if (o.estimator == "nav")
    return RunNavMission(im.db, im.frames, im.frames_gsd, im.locate_options, o);
  maploc::Locator& locator = im.locator;
  locator.ResetAdaptiveOrder();  // each mission learns the method order afresh
  const double map_gsd = im.db.map_gsd_m;
  const double altitude = o.altitude_m > 0 ? o.altitude_m : im.db.options.altitude_m;
  const double fix_sigma_feat = o.feature_fix_sigma_m > 0 ? o.feature_fix_sigma_m : 1.5 * map_gsd;
  const double fix_sigma_oc = o.oc_fix_sigma_m > 0 ? o.oc_fix_sigma_m : 3.0 * map_gsd;
  const int fw = im.db.options.frame_width, fh = im.db.options.frame_height;
  const Eigen::Matrix3d K = im.camera.K();
  const Eigen::Vector2d principal(im.camera.cx, im.camera.cy);
  // The tilt a frame may have: every corner ray at least 10 deg above the horizon.
  const double corner_deg = std::atan(std::hypot(0.5 * fw, 0.5 * fh) / im.camera.fx) / kDeg;
  const double max_total_tilt_deg = std::max(0.0, 80.0 - corner_deg);

  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> n01(0, 1);
  const double compass_bias = o.compass_bias_deg * (2 * u01(rng) - 1);
  const double wind_dir = 360 * u01(rng);
  const AltitudeProfile altitude_profile(o.effects.altitude_variation, rng());
  std::mt19937_64 effects_rng(rng());
  std::mt19937_64 attitude_rng(rng());

  const geo::LocalEnu enu(o.start, 0.0);
  auto to_enu = [&](const geo::LatLon& ll) -> Eigen::Vector2d {
    return enu.ToEnu(ll, 0.0).head<2>();
  };
  auto from_enu = [&](const Eigen::Vector2d& xy) {
    return enu.FromEnu(Eigen::Vector3d(xy.x(), xy.y(), 0.0));
  };

  MissionResult res;
  res.straight_distance_m = geo::GeodesicInverse(o.start, o.target).distance_m;
  const double time_limit =
      o.time_limit_s > 0 ? o.time_limit_s : 3.0 * res.straight_distance_m / o.speed_m_s + 120.0;

  // Filter state: position (east, north) about the start with covariance; the frame's heading
  // (radians clockwise from map up) and scale (map px per frame px) for the odometry.
  Eigen::Vector2d x = Eigen::Vector2d::Zero();
  Eigen::Matrix2d P = Eigen::Matrix2d::Identity() * 100.0;  // start known to ~10 m
  double command = geo::GeodesicInverse(o.start, o.target).azimuth1_deg;
  double theta = PixelAngle(locator.HeadingToPixelDirection(command));
  double scale = altitude / im.focal / map_gsd;
  geo::LatLon truth = o.start;
  geo::LatLon last_fix = o.start;
  double last_fix_t = 0;
  int failures = 0;  // consecutive steps without an accepted fix
  Eigen::Vector2d last_command_step = Eigen::Vector2d::Zero();  // commanded ENU displacement
  FrameOdometry odometry;
  // The attitude error of what locate and the odometry are given (Gauss-Markov per axis).
  constexpr double kAttitudeCorrelation = 0.95;
  Eigen::Vector2d attitude_error =
      o.attitude_noise_deg * Eigen::Vector2d(n01(attitude_rng), n01(attitude_rng));
  double flight_heading = WrapDeg360(command + compass_bias),
         previous_flight_heading = flight_heading;
  double flight_dt = o.step_s;
  Eigen::Matrix3d previous_nadir_from_image = Eigen::Matrix3d::Identity();
  std::vector<Eigen::Vector2d> rejected_innovations;  // consecutive rejected fixes
  double t = 0;

  for (int step = 0;; ++step) {
    StepLog log;
    log.step = step;
    log.t_s = t;
    log.truth = truth;
    log.command_heading_deg = command;
    const double truth_heading = WrapDeg360(command + compass_bias);
    log.truth_heading_deg = truth_heading;

    // 1. The camera frame at the true pose.
    Timer synth;
    const double alt = altitude * altitude_profile.Factor(t);
    log.altitude_m = alt;
    const double camera_heading = truth_heading + o.effects.yaw_jitter_deg * n01(effects_rng);
    // The attitude: the bank of the coordinated turn flown since the last frame, plus gusts.
    const double turn_rate = std::remainder(flight_heading - previous_flight_heading, 360.0) *
                             kDeg / std::max(flight_dt, 1e-3);
    const double bank = std::clamp(std::atan(o.speed_m_s * turn_rate / 9.81) / kDeg,
                                   -o.max_bank_deg, o.max_bank_deg);
    const double gust = o.effects.max_tilt_deg * u01(effects_rng);
    const double gust_dir = 2 * M_PI * u01(effects_rng);
    double roll = bank + gust * std::sin(gust_dir), pitch = gust * std::cos(gust_dir);
    if (const double total = std::hypot(roll, pitch); total > max_total_tilt_deg) {
      roll *= max_total_tilt_deg / total;  // keep the horizon out of the frame
      pitch *= max_total_tilt_deg / total;
    }
    log.roll_deg = roll;
    log.pitch_deg = pitch;
    const maploc::AerialPose pose{
        .nadir_px = im.FramesPixel(truth),
        .altitude_m = alt,
        .attitude = {.roll_deg = roll,
                     .pitch_deg = pitch,
                     .yaw_deg = WrapDeg360(im.HeadingInFrames(truth, camera_heading))}};
    cv::Mat frame = maploc::RenderAerialFrame(im.frames, im.frames_gsd, pose, im.camera);
    ApplyPhotometricEffects(frame, o.effects, 0.0, effects_rng);
    if (o.weather) {
      FrameView view;
      view.t_ns = static_cast<int64_t>(std::llround(t * 1e9));
      view.position_enu << to_enu(truth), alt;
      view.heading_deg = WrapDeg360(camera_heading);
      view.roll_deg = roll;
      view.pitch_deg = pitch;
      view.focal_px = im.focal;
      view.width = fw;
      view.height = fh;
      o.weather(frame, view);
    }
    // What the autopilot reports: the attitude with its slowly varying error.
    if (step > 0) {
      const double c = kAttitudeCorrelation, w = o.attitude_noise_deg * std::sqrt(1 - c * c);
      attitude_error =
          c * attitude_error + w * Eigen::Vector2d(n01(attitude_rng), n01(attitude_rng));
    }
    const double given_roll = roll + attitude_error.x(), given_pitch = pitch + attitude_error.y();
    const Eigen::Matrix3d nadir_from_image = maploc::NadirFromImage(K, given_roll, given_pitch);
    log.times.synthesis_ms = synth.ElapsedMs();
    if (o.keep_frames) res.frames.push_back(frame.clone());

    Timer nav;
    // 2. Prediction: frame-to-frame odometry, or dead reckoning on the last command.
    if (o.use_odometry) {
      const OdometryStep os = odometry.Track(frame);
      log.times.odometry_ms = os.total_ms;
      log.odometry_ok = os.ok;
      if (step > 0) {
        Eigen::Vector2d dx;
        double sigma;
        bool odometry_used = false;
        if (os.ok) {
          // Both frames rectified to level (the given attitudes): the motion of the principal
          // point is then the vehicle's, whatever the frames' roll and pitch.
          Eigen::Matrix3d prev_from_cur;
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) prev_from_cur(r, c) = os.prev_from_cur(r, c);
          const Eigen::Matrix3d level =
              previous_nadir_from_image * prev_from_cur * nadir_from_image.inverse();
          cv::Matx33d level_cv;
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) level_cv(r, c) = level(r, c) / level(2, 2);
          const LocalSimilarity s =
              SimilarityAt(level_cv, cv::Point2d(principal.x(), principal.y()));
          const Eigen::Vector2d d_px =
              scale * RotateFrameToMap(theta, {s.translation_px.x, s.translation_px.y});
          const Eigen::Vector2d here_px = locator.LatLonToPixel(from_enu(x));
          dx = to_enu(locator.PixelToLatLon(here_px + d_px)) - x;
          // Plausibility: close to the commanded step (compass error and wind allowed for), no
          // sharp turn or jump in altitude. An implausible homography (e.g. a frame matched to
          // the wrong place) is ignored and the step is dead-reckoned instead.
          const double allowed = 0.3 * last_command_step.norm() + 20.0;
          odometry_used = (dx - last_command_step).norm() <= allowed &&
                          std::abs(s.rotation_rad) < 30 * kDeg && s.scale > 0.8 && s.scale < 1.25;
          if (odometry_used) {
            theta += s.rotation_rad;
            scale *= s.scale;
            // Plus the change of the attitude error between the frames (its ground shift).
            sigma = o.odometry_sigma * dx.norm() + 1.0 +
                    alt * std::tan(o.attitude_noise_deg * kDeg) *
                        std::sqrt(2 * (1 - kAttitudeCorrelation));
          } else {
            log.odometry_ok = false;
          }
        }
        if (!odometry_used) {
          dx = last_command_step;
          theta = PixelAngle(locator.HeadingToPixelDirection(command));
          sigma = o.dead_reckoning_sigma * dx.norm() + 2.0;
        }
        x += dx;
        P += Eigen::Matrix2d::Identity() * sigma * sigma;
      }
    }

    previous_nadir_from_image = nadir_from_image;

    // 3. The map fix, with a prior from the prediction.
    maploc::Prior prior;
    const double pos_sigma = std::sqrt(P.eigenvalues().real().maxCoeff());
    prior.position = from_enu(x);
    prior.radius_m = std::clamp(3.0 * pos_sigma + 100.0, 150.0, 2000.0);
    prior.heading_deg = locator.PixelDirectionToHeading(RotateFrameToMap(theta, {0, -1}));
    prior.heading_sigma_deg = failures > 3 ? 20.0 : 10.0;
    prior.altitude_m = altitude;
    prior.roll_deg = given_roll;
    prior.pitch_deg = given_pitch;
    prior.attitude_sigma_deg = std::max(0.25, o.attitude_noise_deg);
    if (!o.use_odometry) {
      // The thesis's prediction (SEEDS.md part 3): the reachable distance along the bearing to the
      // target (and deviated bearings) from the last fix.
      const double reach = o.speed_m_s * (t - last_fix_t);
      prior.position = geo::GeodesicDirect(last_fix, command, reach);
      prior.radius_m = std::max(250.0, 0.2 * reach + 150.0);
      for (double dev : {-20.0, 20.0}) {
        prior.extra_centres.push_back(geo::GeodesicDirect(last_fix, command + dev, reach));
      }
    } else if (failures >= 2) {
      const double reach = o.speed_m_s * (t - last_fix_t);
      for (double dev : {-30.0, -15.0, 0.0, 15.0, 30.0}) {
        prior.extra_centres.push_back(geo::GeodesicDirect(last_fix, command + dev, reach));
      }
    }
    if (failures >= o.global_after_failures) {
      prior.position.reset();  // lost: search every tile
      prior.extra_centres.clear();
      log.global_search = true;
    }
    // Method order: the locator's adaptive one (correlation first once features keep failing).
    const maploc::LocateResult r = locator.Locate(frame, prior);
    log.times.extraction_ms = r.times.extraction_ms;
    log.times.matching_ms = r.times.matching_ms;
    log.times.estimation_ms = r.times.estimation_ms;
    log.fix_found = r.localized;
    log.fix_method = r.method;
    log.fix_reason = r.reason;
    log.inliers = r.inliers;
    if (r.localized) {
      log.fix = r.latlon;
      log.fix_error_m = geo::GeodesicInverse(r.latlon, truth).distance_m;
      const Eigen::Vector2d z = to_enu(r.latlon);
      if (!o.use_odometry) {
        x = z;  // as in the thesis: the fix is the estimate
        log.fix_accepted = true;
      } else {
        const double s = r.method == "features" ? fix_sigma_feat : fix_sigma_oc;
        const Eigen::Matrix2d S = P + Eigen::Matrix2d::Identity() * s * s;
        const Eigen::Vector2d innov = z - x;
        const double d2 = innov.dot(S.ldlt().solve(innov));
        // Relocalization: when the last fixes were all rejected but agree with each other about
        // where the drone is relative to the prediction, the filter is the one that is wrong
        // (e.g. after a bad odometry step): restart it at the fix.
        rejected_innovations.push_back(innov);
        bool relocalize = false;
        if (d2 > o.gate_chi2 && rejected_innovations.size() >= 3) {
          const size_t n = rejected_innovations.size();
          relocalize = true;
          for (size_t k = n - 3; k + 1 < n; ++k) {
            relocalize &= (rejected_innovations[k] - innov).norm() < 3 * s + 20.0;
          }
        }
        if (relocalize) {
          x = z;
          P = Eigen::Matrix2d::Identity() * s * s;
          rejected_innovations.clear();
          log.fix_accepted = true;
          log.fix_reason = "relocalized: the last 3 fixes agreed on a filter offset";
        } else if (d2 <= o.gate_chi2) {
          rejected_innovations.clear();
          const Eigen::Matrix2d K = P * S.inverse();
          x += K * innov;
          P = (Eigen::Matrix2d::Identity() - K) * P;
          P = 0.5 * (P + P.transpose());
          log.fix_accepted = true;
        } else {
          log.fix_reason = fmt::format(
              "rejected: {:.0f} m from the prediction (Mahalanobis {:.1f}, gate {:.1f})",
              innov.norm(), std::sqrt(d2), std::sqrt(o.gate_chi2));
        }
      }
      if (log.fix_accepted) {
        theta = PixelAngle(locator.HeadingToPixelDirection(r.heading_deg));
        // The odometry works on level-rectified frames: their scale is the altitude's.
        if (r.altitude_m > 0) {
          scale = r.altitude_m / im.focal / map_gsd;
        } else if (r.scale > 0) {
          scale = r.scale;
        }
        last_fix = from_enu(x);
        last_fix_t = t;
        failures = 0;
      }
    }
    if (!log.fix_accepted) ++failures;

    // 4. Guidance: towards the target from the estimate (the thesis's rule; without
    // odometry, a failed fix keeps the last bearing).
    const geo::LatLon estimate = from_enu(x);
    log.estimate = estimate;
    log.estimate_error_m = geo::GeodesicInverse(estimate, truth).distance_m;
    log.estimate_sigma_m = std::sqrt(P.eigenvalues().real().maxCoeff());
    const geo::GeodesicResult to_target = geo::GeodesicInverse(estimate, o.target);
    const bool arrived = to_target.distance_m <= o.arrive_radius_m;
    const bool timeout = t >= time_limit;
    if (!arrived && !timeout && (o.use_odometry || log.fix_accepted)) {
      command = WrapDeg360(to_target.azimuth1_deg);
    }
    log.times.navigation_ms = nav.ElapsedMs();
    res.steps.push_back(log);
    if (arrived || timeout) {
      res.end_reason = arrived ? "arrived" : "time limit";
      break;
    }

    // 5. The true drone flies the step (the last one only as far as the estimated target).
    const double dist = std::min(o.speed_m_s * o.step_s, to_target.distance_m);
    const double dt = dist / o.speed_m_s;
    const geo::LatLon before = truth;
    previous_flight_heading = flight_heading;
    flight_heading = WrapDeg360(command + compass_bias);
    flight_dt = dt;
    truth = geo::GeodesicDirect(truth, flight_heading, dist);
    if (o.wind_m_s > 0) truth = geo::GeodesicDirect(truth, wind_dir, o.wind_m_s * dt);
    res.flown_m += geo::GeodesicInverse(before, truth).distance_m;
    last_command_step = dist * Eigen::Vector2d(std::sin(command * kDeg), std::cos(command * kDeg));
    t += dt;
  }
  res.duration_s = t;
  res.final_distance_m = geo::GeodesicInverse(truth, o.target).distance_m;
  res.reached = res.final_distance_m <= o.success_radius_m;
  return res;
}

std::pair<geo::LatLon, geo::LatLon> RandomStartTarget(const maploc::MapDatabase& db,
                                                      double min_distance_m, double margin_m,
                                                      uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  const geo::CrsTransform crs(db.crs_wkt);
  const double m = margin_m / db.map_gsd_m;
  auto sample = [&] {
    const Eigen::Vector2d px(m + (db.width - 2 * m) * u01(rng), m + (db.height - 2 * m) * u01(rng));
    return crs.ToLatLon(db.transform.PixelToCrs(px));
  };
  for (int i = 0; i < 10000; ++i) {
    const geo::LatLon a = sample(), b = sample();
    if (geo::GeodesicInverse(a, b).distance_m >= min_distance_m) {
      return {a, b};
    }
  }
  throw Error(fmt::format(
      "no start/target pair {:.0f} m apart fits inside the map with a {:.0f} m margin (map is "
      "{:.0f} x {:.0f} m)",
      min_distance_m, margin_m, db.width * db.map_gsd_m, db.height * db.map_gsd_m));
}

}  // namespace optinav::nav
