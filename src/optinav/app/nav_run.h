// The run behind `optinav nav`: reads a EuRoC dataset with a nadir camera (mav0/cam2), an IMU and
// optionally a barometer (mav0/baro0), runs nav::MapAidedNavigator against a map database, and
// writes the trajectory (TUM, ENU about the map's centre), a WGS84 csv with each pose's 1-sigma
// uncertainty, a GeoJSON line and a statistics JSON (fixes, timing and, when the dataset carries
// simulator ground truth with its ENU origin, the global error: no alignment). Files are written
// atomically after the run.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "optinav/geometry/trajectory.h"
#include "optinav/nav/map_aided_nav.h"

namespace optinav::app {

struct NavRunSettings {
  std::string dataset;                             // sequence folder (holding mav0/)
  std::string map_path;                            // map database (required unless no_map)
  bool no_map = false;                             // IMU + baro + odometry only (needs nav.start)
  std::string out;                                 // TUM trajectory (required)
  std::string stats_path, wgs84_out, geojson_out;  // optional (empty: none)
  nav::NavOptions nav;
  maploc::LocateOptions locate;
  size_t max_frames = 0;  // 0: all nadir frames
  // GNSS (mav0/gnss0, ENU about the simulator's origin or lat/lon/height) fused as positions
  // with this sigma (<= 0: the file's, else 3 m). Off by default: nav is GNSS-free.
  bool gnss = false;
  double gnss_sigma_m = -1;
  // Frames replaced by a blank (uniform grey) image over [start_s, start_s + duration_s) after
  // the first frame: the map cannot be matched there (water, cloud; the gap acceptance).
  std::vector<std::pair<double, double>> blank;
  // Empty when valid, else a message that starts with the flag at fault.
  std::string Check() const;
};

// Global error against the dataset's ground truth (sim datasets: ENU origin in
// sim_complete.json), over the estimated poses.
struct NavError {
  size_t poses = 0;
  double rmse_m = 0, max_m = 0, final_m = 0;  // horizontal
  double altitude_rmse_m = 0;
  double heading_rmse_deg = 0, heading_max_deg = 0;  // yaw of the body
};

struct NavRunReport {
  std::vector<nav::NavPose> poses;
  std::vector<nav::FixLog> fixes;
  nav::NavStats stats;
  geo::LatLon origin;  // the world frame's ENU origin (the map's centre)
  std::optional<NavError> error;
  std::vector<int64_t> error_t_ns;  // the poses with ground truth, when `error`
  std::vector<double> errors_m;     // per entry of error_t_ns
  std::vector<double> altitude_errors_m;
  std::vector<double> heading_errors_deg;  // estimate minus truth, wrapped to [-180, 180); NaN:
                                           // no truth heading
  double wall_s = 0, duration_s = 0;
  int64_t first_frame_ns = 0;  // the first nadir frame (the reference of `blank`)
  nlohmann::json ToJson() const;
};

// A simulator dataset's truth: its ENU origin (sim_complete.json "gnss_origin", beside mav0/ or
// one folder up) and its ground truth in that frame. nullopt when the dataset has no such origin
// or no ground truth.
struct SimTruth {
  geo::LatLon origin;
  Trajectory groundtruth;
  // The true start as `optinav nav --start` takes it (5 m, 3 deg).
  nav::NavStart Start() const;
};
std::optional<SimTruth> ReadSimTruth(const std::string& dataset);

// Throws Error on invalid settings, bad input (naming the file), and when no pose was estimated.
// `progress(done, total)` after each nadir frame.
NavRunReport RunNav(const NavRunSettings& settings,
                    const std::function<void(size_t, size_t)>& progress = {});

}  // namespace optinav::app
