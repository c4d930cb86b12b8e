// The map-aided navigation benchmark behind `optinav bench nav` (issue 20's table): seeded
// flights over an orthophoto several years newer than the map (NAIP 2017 frames, NAIP 2009 map),
// 350-600 m above ground at 15-25 m/s with turns and climbs, rendered once by the simulator
// (nadir camera 640x480 at 5 Hz, IMU, barometer, GNSS; cached under OUT/flights/ with their
// completion markers), and `optinav nav`'s driver (app::RunNav) run on each in these
// configurations:
//   map          map fixes + IMU + baro + visual odometry, GNSS-free from take-off
//   fog50        the same flights rendered in 50 % fog
//   gap60        the map cannot be matched for 60 s (frames blanked from 40 s on)
//   outliers10   10 % of the found fixes replaced by positions 300-1500 m away
//   no-map       IMU + baro + visual odometry from the true start (what the map adds)
//   gnss3        GNSS 3 m fused instead of the map, from the true start (reference)
// Figures per run (global error, no alignment): horizontal RMSE, max and final, altitude RMSE,
// real-time factor, fixes tried/accepted; gap: the error at the gap's end and the time after the
// first accepted fix until it is back under 10 m; outliers: injected and accepted. Outputs:
// results.json, table.md, and per flight a picture (paths on the orthophoto, error over time).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace optinav::app {

struct NavBenchOptions {
  std::string out_dir;
  std::string map_ortho;     // the map's orthophoto (default: shared data NAIP 2009)
  std::string flight_ortho;  // the flights' orthophoto (default: shared data NAIP 2017)
  int flights = 3;
  double flight_length_m = 3600;  // per flight (3 x 3.6 km >= the acceptance's 10 km)
  uint64_t seed = 1;
  std::vector<std::string> configs = {"map", "fog50", "gap60", "outliers10", "no-map", "gnss3"};
  int jobs = 1;        // runs in parallel
  bool reuse = false;  // keep rendered flights and finished runs
  double fix_rate_hz = 1.0;
  bool drag = false;          // the navigator uses the drones' rotor drag (NavOptions::drag_per_s)
  std::string Check() const;  // "" when valid, else starts with the flag at fault
};

// The known configurations (the list above).
const std::vector<std::string>& NavBenchConfigs();

struct NavBenchRun {
  std::string flight, config;
  bool ok = false;
  std::string error;  // when !ok
  double rmse_m = 0, max_m = 0, final_m = 0, altitude_rmse_m = 0;
  double realtime_factor = 0;
  size_t fixes_tried = 0, fixes_accepted = 0, outliers_injected = 0, outliers_accepted = 0;
  double gap_end_error_m = -1, recovery_s = -1;  // gap60
  // The first estimate's time after the first nadir frame (the global search before it: the
  // errors above cover the flight from then on).
  double initialised_after_s = -1;
  double length_m = 0, duration_s = 0;
};

struct NavBenchResult {
  std::vector<NavBenchRun> runs;
  std::string table_md;
  nlohmann::json ToJson() const;
};

// Throws Error on invalid options or when a flight cannot be rendered; a failed run is reported
// in its row. `progress(line)` after each flight rendered and each run.
NavBenchResult RunNavBench(const NavBenchOptions& options,
                           const std::function<void(const std::string&)>& progress = {});

}  // namespace optinav::app
