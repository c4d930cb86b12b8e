// A GNSS-denied mission over an orthophoto (the loop of the orthophoto-navigation thesis, SEEDS.md
// part 3, plus odometry and fix gating): the drone knows its start and the target; every step it
// takes a camera frame (a true perspective view of an orthophoto from its true position, altitude
// and attitude: banking in turns, gusts), localizes it against the
// map database, blends the fix with frame-to-frame odometry in a small Kalman filter, and turns
// towards the target.
//
// Frames and coordinates: truth and estimates are WGS84 lat/lon; the filter works in a local
// east/north frame about the start (metres). Headings are degrees clockwise from north.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "optinav/geo/raster.h"
#include "optinav/maploc/locator.h"
#include "optinav/nav/frame_effects.h"
#include "optinav/nav/internal/frame_odometry.h"
#include "optinav/nav/map_aided_nav.h"
#include "optinav/sim/rig.h"
#include "optinav/sim/sensors.h"

namespace optinav::nav {

struct MissionOptions {
  geo::LatLon start, target;
  double speed_m_s = 30.0;       // ground speed commanded
  double altitude_m = 0.0;       // above ground; 0: the altitude the map was built for
  double step_s = 1.0;           // time between frames (and guidance updates)
  double arrive_radius_m = 10;   // the mission ends when the estimate is this close
  double success_radius_m = 50;  // a run succeeds when the true drone ends this close
  double time_limit_s = 0;       // 0: 3 x the straight-line time + 120 s
  double compass_bias_deg = 3;   // heading hold error of the autopilot, uniform +- this per run
  double wind_m_s = 0;           // constant wind (seeded direction) pushing the true drone
  FrameEffectOptions effects;
  // Error of the roll and pitch given to locate (the autopilot's attitude), 1-sigma degrees per
  // axis: a slowly varying error (first-order Gauss-Markov, correlation 0.95 per frame). 0.5 deg
  // is about the acceptance set's +-1 deg uniform (sigma 0.58); at 640 m each 0.1 deg moves a
  // fix that takes the attitude as given (orientation correlation) by 1.1 m.
  double attitude_noise_deg = 0.5;
  double max_bank_deg = 20;            // bank of a coordinated turn, limited to this
  FrameHook weather;                   // optional, applied after the photometric effects
  bool use_odometry = true;            // false: the thesis loop (fix or keep the last bearing)
  double feature_fix_sigma_m = 0;      // 0: 1.5 map pixels
  double oc_fix_sigma_m = 0;           // 0: 3 map pixels
  double odometry_sigma = 0.05;        // odometry error per metre flown (fraction)
  double dead_reckoning_sigma = 0.15;  // error per metre when flying blind (compass bias, wind)
  double gate_chi2 = 13.8;             // Mahalanobis gate for fixes (99.9 % for 2 dof)
  int global_after_failures = 4;       // consecutive steps without an accepted fix -> search all
  uint64_t seed = 1;
  bool keep_frames = false;  // keep every frame in the result (for debugging/tests)

  // The navigation: "2d" (the filter above, one frame of the map's camera every step_s) or "nav"
  // (MapAidedNavigator: a 200 Hz IMU, a barometer and the nadir camera below at its own rate,
  // with map fixes; the true vehicle turns at a commanded rate with a lag and banks as it turns,
  // nav/internal/closed_loop_flight.h; guidance every frame on the estimated course). With "nav",
  // compass_bias_deg is the error of the start heading given to the navigator,
  // attitude_noise_deg the error of its start roll and pitch (the AHRS), step_s the
  // interval of the step log, and use_odometry switches the navigator's visual odometry.
  std::string estimator = "2d";
  sim::NadirCameraOptions nadir{.enabled = true};  // nav: 640x480, 90 deg, 5 Hz
  NavOptions nav;                                  // nav: its start is set per run
  sim::ImuOptions imu;                             // nav: the simulated IMU (200 Hz)
  sim::BaroOptions baro{.enabled = true};          // nav: the simulated barometer (20 Hz)
};

struct StepTimes {
  double synthesis_ms = 0;                                       // simulation (not navigation)
  double extraction_ms = 0, matching_ms = 0, estimation_ms = 0;  // the map fix (the thesis's rows)
  double odometry_ms = 0;
  double locate_ms = 0;      // estimator nav: the map fixes, timed whole (not split in stages)
  double navigation_ms = 0;  // everything the drone computes: fix + odometry + filter + guidance
};

struct StepLog {
  int step = 0;
  double t_s = 0;
  geo::LatLon truth, estimate;
  double truth_heading_deg = 0, command_heading_deg = 0;
  double altitude_m = 0;
  double roll_deg = 0, pitch_deg = 0;  // the true attitude of the frame
  bool fix_found = false;              // the locator returned a position
  bool fix_accepted = false;           // and the filter took it
  std::string fix_method;              // features | orientation-correlation
  std::string fix_reason;              // locator's reason, or why the filter rejected the fix
  geo::LatLon fix;
  double fix_error_m = -1;      // fix vs truth (when found)
  double estimate_error_m = 0;  // filter vs truth after the step
  double estimate_sigma_m = 0;  // filter's 1-sigma horizontal uncertainty
  bool odometry_ok = false;
  bool global_search = false;
  int inliers = 0;
  StepTimes times;
};

struct MissionResult {
  bool reached = false;            // the true drone ended within success_radius_m of the target
  std::string end_reason;          // "arrived" (estimate within radius) | "time limit"
  double final_distance_m = 0;     // true position to target at the end
  double straight_distance_m = 0;  // start to target
  double flown_m = 0;              // true path length
  double duration_s = 0;
  std::vector<StepLog> steps;
  std::vector<cv::Mat> frames;  // when keep_frames
};

class Mission {
 public:
  // `frames`: the orthophoto the camera frames are cut from (the map's own image, or another
  // image of the same area). Both must outlive the mission. Throws Error on bad options.
  Mission(const maploc::MapDatabase& db, const geo::GeoRaster& frames,
          const maploc::LocateOptions& locate_options = {});
  ~Mission();

  // Checks start, target, speed and altitude against the map; "" when valid.
  std::string Check(const MissionOptions& options) const;
  // Runs one mission; throws Error when Check fails.
  MissionResult Run(const MissionOptions& options);

  // Focal length (pixels) of the map's camera, and the map's ground sample distance (metres).
  double focal_px() const;
  double map_gsd_m() const;
  // True when the point is inside the map with `margin_m` to spare.
  bool InsideMap(const geo::LatLon& ll, double margin_m = 0) const;
  maploc::Locator& locator();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Random start and target inside the map (margin_m from the edges) at least min_distance_m
// apart, seeded. Throws Error when the map is too small for that distance.
std::pair<geo::LatLon, geo::LatLon> RandomStartTarget(const maploc::MapDatabase& db,
                                                      double min_distance_m, double margin_m,
                                                      uint64_t seed);

}  // namespace optinav::nav
