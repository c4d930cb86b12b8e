// optinav nav: map-aided inertial navigation (IMU + nadir camera + barometer + map fixes) on a
// EuRoC dataset with mav0/cam2. Parses the flags into app::NavRunSettings, runs app::RunNav and
// prints its summary.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "optinav/app/nav_bench.h"
#include "optinav/app/nav_run.h"
#include "optinav/exe/cli_common.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"
#include "optinav/util/progress.h"

namespace optinav {

int RunNav(int argc, char** argv) {
  CLI::App command{
      "Map-aided inertial navigation: IMU + nadir camera (mav0/cam2) + barometer (mav0/baro0) + "
      "map fixes in one sliding-window estimator (GNSS-free from take-off)",
      "optinav nav"};
  app::NavRunSettings st;
  std::string start;
  command.add_option("--dataset", st.dataset, "sequence folder (holding mav0/ with cam2, imu0)")
      ->required();
  command.add_option("--map", st.map_path, "map database (optinav map build)");
  cli::OutputFile(command.add_option("--out", st.out,
                                     "output trajectory of the body (IMU), TUM, ENU about the "
                                     "map's centre"))
      ->required();
  cli::OutputFile(command.add_option("--stats", st.stats_path,
                                     "statistics JSON: fixes, timing, global error against "
                                     "simulator ground truth"));
  cli::OutputFile(command.add_option(
      "--wgs84-out", st.wgs84_out,
      "WGS84 csv: t_ns, lat, lon, height above the map, 1-sigma east/north/up, yaw sigma"));
  cli::OutputFile(command.add_option("--geojson-out", st.geojson_out, "GeoJSON line of the path"));
  command.add_option("--map-norm", st.nav.map_norm, "robust norm of map fixes: l2|huber|tukey")
      ->capture_default_str();
  command.add_flag("--no-map", st.no_map,
                   "no map fixes: IMU + barometer + visual odometry from --start");
  command.add_option("--start", start,
                     "LAT,LON,HEADING: the start (default: the first map fix, found globally "
                     "and confirmed)");
  command
      .add_option("--fix-rate", st.nav.fix_rate_hz, "map fixes tried per second (0: every frame)")
      ->capture_default_str();
  command
      .add_option("--global-search-interval", st.nav.global_search_interval_s,
                  "seconds of flight between global searches (take-off, relocalisation; each "
                  "costs seconds on one core)")
      ->capture_default_str();
  command.add_flag("!--no-odometry", st.nav.use_odometry, "no frame-to-frame velocity factors");
  command
      .add_option("--odometry-sigma-px", st.nav.odometry_pixel_sigma,
                  "frame-to-frame homography error (px, 1 sigma) behind the velocity factors")
      ->capture_default_str();
  command
      .add_option("--fix-sigma-scale", st.nav.fix_sigma_scale,
                  "a map fix's sigma is the locator's position_sigma_m times this")
      ->capture_default_str();
  command
      .add_option("--fix-yaw-sigma", st.nav.fix_yaw_sigma_deg,
                  "a map fix's heading enters with this sigma (deg; 0: not used)")
      ->capture_default_str();
  command
      .add_option("--align-tilt-sigma", st.nav.align_tilt_sigma_deg,
                  "after a start from map fixes, no pose until the tilt is known to this (deg; "
                  "0: poses from the first fix)")
      ->capture_default_str();
  command.add_option("--window", st.nav.window_states, "states in the sliding window")
      ->capture_default_str();
  command.add_option("--max-frames", st.max_frames,
                     "process only the first N nadir frames (0: all)");
  command.add_flag("--gnss", st.gnss,
                   "also fuse GNSS positions (mav0/gnss0), gated like map fixes");
  command.add_option("--gnss-sigma", st.gnss_sigma_m,
                     "GNSS sigma per axis, m (default: the file's sigma column, else 3)");
  std::vector<std::string> blank;
  command.add_option("--blank", blank,
                     "START_S:DURATION_S: blank the nadir frames in that window (no map match "
                     "possible; repeatable)");
  command
      .add_option("--drag", st.nav.drag_per_s,
                  "the multirotor's calibrated rotor drag K (1/s; 0: off): the accelerometer's "
                  "horizontal specific force -K (v - wind) gives the velocity without texture")
      ->capture_default_str();
  command
      .add_option("--drag-sigma", st.nav.drag_sigma_m_s2,
                  "sigma of the drag factor (the frame interval's mean specific force, m/s^2)")
      ->capture_default_str();
  command.add_option("--inject-outliers", st.nav.inject_outlier_fraction,
                     "testing: replace this fraction of the found map fixes by positions "
                     "300-1500 m away (seeded)");
  return cli::RunCli(command, argc, argv, [&] {
    if (!start.empty()) {
      const std::vector<double> v = ParseNumbers(start, 3, "LAT,LON,HEADING", "--start");
      st.nav.start = nav::NavStart{{v[0], v[1]}, v[2]};
    }
    for (const std::string& b : blank) {
      std::string text = b;
      std::replace(text.begin(), text.end(), ':', ',');
      const std::vector<double> v = ParseNumbers(text, 2, "START_S:DURATION_S", "--blank");
      st.blank.emplace_back(v[0], v[1]);
    }
    cli::ThrowIfCheckFailed(st.Check());
    std::optional<ProgressBar> progress;
    const app::NavRunReport r = app::RunNav(st, [&](size_t done, size_t total) {
      if (!progress) progress.emplace(total, "nav");
      progress->Advance();
      (void)done;
    });
    if (progress) progress->Finish();
    std::printf(
        "optinav nav: %zu poses over %.1f s (%zu nadir frames) in %.1f s wall (%.1fx real "
        "time); map fixes %zu tried, %zu found, %zu accepted, %zu rejected\n",
        r.poses.size(), r.duration_s, r.stats.frames, r.wall_s,
        r.wall_s > 0 ? r.duration_s / r.wall_s : 0.0, r.stats.fixes_tried, r.stats.fixes_found,
        r.stats.fixes_accepted, r.stats.fixes_rejected);
    if (r.error)
      std::printf(
          "global error vs ground truth (no alignment): horizontal RMSE %.2f m, max %.2f "
          "m, final %.2f m; altitude RMSE %.2f m; heading RMSE %.2f deg, max %.2f deg\n",
          r.error->rmse_m, r.error->max_m, r.error->final_m, r.error->altitude_rmse_m,
          r.error->heading_rmse_deg, r.error->heading_max_deg);
    std::printf("trajectory -> %s\n", st.out.c_str());
    return 0;
  });
}

}  // namespace optinav

namespace optinav {

// optinav bench nav: the map-aided navigation benchmark (app/nav_bench.h).
int RunNavBench(int argc, char** argv) {
  CLI::App command{
      "Map-aided navigation benchmark: seeded flights over NAIP 2017 with a NAIP 2009 map; map "
      "fixes vs no map vs GNSS 3 m, in fog, through a 60 s gap and with 10 % wrong fixes",
      "optinav bench nav"};
  app::NavBenchOptions o;
  const std::string naip =
      std::string(std::getenv("OPTINAV_SHARED_DATA") ? std::getenv("OPTINAV_SHARED_DATA")
                                                     : OPTINAV_SHARED_DATA_DEFAULT) +
      "/geo/naip/naip_";
  o.map_ortho = naip + "20090818.tif";
  o.flight_ortho = naip + "20170827.tif";
  std::string configs;
  command.add_option("--out", o.out_dir, "output folder (flights, runs, tables, plots)")
      ->required();
  command.add_option("--map-ortho", o.map_ortho, "the map's orthophoto")->capture_default_str();
  command.add_option("--flight-ortho", o.flight_ortho, "the orthophoto the flights see")
      ->capture_default_str();
  command.add_option("--flights", o.flights, "seeded flights")->capture_default_str();
  command.add_option("--flight-length", o.flight_length_m, "metres per flight")
      ->capture_default_str();
  command.add_option("--seed", o.seed, "seed of the flight plans and speeds")
      ->capture_default_str();
  command.add_option("--configs", configs,
                     "comma list of map,fog50,gap60,outliers10,no-map,gnss3 (default: all)");
  command.add_flag("--drag", o.drag,
                   "the navigator uses the drones' rotor drag (nav --drag with the flights' K)");
  command.add_option("--fix-rate", o.fix_rate_hz, "map fixes tried per second")
      ->capture_default_str();
  command.add_option("--jobs", o.jobs, "runs in parallel")->capture_default_str();
  command.add_flag("--reuse", o.reuse, "keep rendered flights and the map");
  return cli::RunCli(command, argc, argv,
                     [&] {
                       if (!configs.empty()) {
                         o.configs.clear();
                         std::string item;
                         for (char c : configs + ",") {
                           if (c == ',') {
                             if (!item.empty()) o.configs.push_back(item);
                             item.clear();
                           } else {
                             item += c;
                           }
                         }
                       }
                       cli::ThrowIfCheckFailed(o.Check());
                       const app::NavBenchResult r =
                           app::RunNavBench(o, [](const std::string& line) {
                             std::fprintf(stderr, "bench nav: %s\n", line.c_str());
                           });
                       std::printf("%s\nresults -> %s/results.json, table.md, flight*_paths.png\n",
                                   r.table_md.c_str(), o.out_dir.c_str());
                       return 0;
                     },
                     {.default_log_level = "warn"});
}

}  // namespace optinav
