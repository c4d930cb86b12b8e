// optinav nav: map-aided inertial navigation (IMU + nadir camera + barometer + map fixes) on a
// EuRoC dataset with mav0/cam2. Parses the flags into app::NavRunSettings, runs app::RunNav and
// prints its summary.
#include <algorithm>
#include <cstdio>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

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
  command.add_option("--fix-rate", st.nav.fix_rate_hz, "map fixes tried per second (0: every frame)")
      ->capture_default_str();
  command.add_flag("!--no-odometry", st.nav.use_odometry, "no frame-to-frame velocity factors");
  command.add_option("--window", st.nav.window_states, "states in the sliding window")
      ->capture_default_str();
  command.add_option("--max-frames", st.max_frames, "process only the first N nadir frames (0: all)");
  command.add_flag("--gnss", st.gnss, "also fuse GNSS positions (mav0/gnss0), gated like map fixes");
  command.add_option("--gnss-sigma", st.gnss_sigma_m,
                     "GNSS sigma per axis, m (default: the file's sigma column, else 3)");
  std::vector<std::string> blank;
  command.add_option("--blank", blank,
                     "START_S:DURATION_S: blank the nadir frames in that window (no map match "
                     "possible; repeatable)");
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
    std::printf("optinav nav: %zu poses over %.1f s (%zu nadir frames) in %.1f s wall (%.1fx real "
                "time); map fixes %zu tried, %zu found, %zu accepted, %zu rejected\n",
                r.poses.size(), r.duration_s, r.stats.frames, r.wall_s,
                r.wall_s > 0 ? r.duration_s / r.wall_s : 0.0, r.stats.fixes_tried,
                r.stats.fixes_found, r.stats.fixes_accepted, r.stats.fixes_rejected);
    if (r.error)
      std::printf("global error vs ground truth (no alignment): horizontal RMSE %.2f m, max %.2f "
                  "m, final %.2f m; altitude RMSE %.2f m\n",
                  r.error->rmse_m, r.error->max_m, r.error->final_m, r.error->altitude_rmse_m);
    std::printf("trajectory -> %s\n", st.out.c_str());
    return 0;
  });
}

}  // namespace optinav
