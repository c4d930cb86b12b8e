// The mission experiment behind `optinav mission` (also run by `optinav demo`): seeded GNSS-denied
// flights over a map database, each run's outcome, the summary figures, and in the output folder
// summary.json, pictures (PNG + SVG) and GIS files (GeoJSON, KML), per run and for all runs, and
// the HTML report's document (report.json + report_map.jpg; report.html with `html`).
//
// The driver prints nothing on stdout: the caller prints the table (FormatMissionRunHeader/Row as
// the runs finish, through the callback, then FormatMissionSummary).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "optinav/app/html_report.h"
#include "optinav/geo/geo.h"
#include "optinav/nav/mission.h"
#include "optinav/util/statistics.h"

namespace optinav::app {

struct MissionExperimentOptions {
  std::string map_path;  // map database (optinav map build)
  // Both set: every run flies this leg. Both unset: a seeded random leg per run, at least
  // min_distance_m long and margin_m inside the map edges.
  std::optional<geo::LatLon> start, target;
  double min_distance_m = 3000, margin_m = 300;
  std::string frames_from;  // orthophoto the frames are cut from; empty: the map's own
  std::string ortho_path;   // the map's orthophoto when moved since the build; empty: as recorded
  std::string model_path;   // XFeat network of an XFeat map; empty: the default
  std::string out_dir;
  bool force = false;  // write into a non-empty output folder
  std::string weather = "none";
  std::string pictures = "all";  // all | summary | none
  bool save_frames = false;      // every camera frame to run_NNN/frames/
  bool html = false;             // also render report.html (app/html_report.h) at the end
  int runs = 1;                  // seeds mission.seed .. mission.seed + runs - 1
  // Per-run settings; start, target, weather and keep_frames are filled in per run.
  nav::MissionOptions mission;

  // "" when valid, else a message that starts with the flag at fault ("--runs must be ...").
  // What needs the map (start inside it, altitude, speed) is checked by the driver.
  std::string Check() const;
};

struct MissionRunOutcome {
  int run = 0;  // 1-based
  geo::LatLon start, target;
  nav::MissionResult mission;     // frames dropped once written (save_frames)
  double fix_rate = 0;            // steps with a fix found
  double median_fix_error_m = 0;  // NaN when no fix was found
};

// Mean and spread of the per-step stage times (ms) over every step of every run.
struct MissionTimings {
  Statistics extraction, matching, estimation, localization, odometry, navigation, synthesis;
};

struct MissionExperimentResult {
  std::vector<MissionRunOutcome> runs;
  int reached = 0;  // runs whose true position ended within success_radius_m of the target
  int steps = 0, fixes_found = 0, fixes_accepted = 0;
  double success_radius_m = 0, map_gsd_m = 0;
  std::optional<Statistics> fix_error_m;  // over every fix found; unset when none was
  Statistics estimate_error_m, final_distance_m;
  MissionTimings timing_ms;
  double navigation_steps_per_second = 0;
  std::string out_dir;
  std::string estimator;                 // options.mission.estimator
  nlohmann::json summary;                // as written to summary.json
  std::optional<HtmlReportResult> html;  // when options.html

  bool all_reached() const { return reached == static_cast<int>(runs.size()); }
};

// Runs the experiment. Throws Error on bad input (a bad map, a start outside it, an unknown
// weather, ...) before anything is written. `on_run` is called after each run.
MissionExperimentResult RunMissionExperiment(
    const MissionExperimentOptions& options,
    const std::function<void(const MissionRunOutcome&)>& on_run = {});

// The run table's header and one row (with the newline), and the summary after the table.
std::string FormatMissionRunHeader();
std::string FormatMissionRunRow(const MissionRunOutcome& outcome);
std::string FormatMissionSummary(const MissionExperimentResult& result);

}  // namespace optinav::app
