// The weather benchmark behind `optinav bench weather`: the weather document's table (SEEDS.md
// part 1: the mean localization error of stereo SLAM on the car route in each weather) made with
// our odometry, side by side with the document's ORB-SLAM3 figures.
//
// Per seed, world and condition the car route is rendered once (sim::RunSimulation, EuRoC, the
// car rig scaled by `scale`) into OUT/sequences/seed<S>/<name>, where a sequence counts as
// rendered only with its completion marker (sim_complete.json, written last), and every mode
// runs on it: `optinav vio`'s driver (app::RunVioDataset), threaded as `optinav vio` runs by
// default, writing OUT/runs/<name>_<mode>_seed<S>.{tum,odometry.tum,stats.json,json}. Figures
// per run: the document's mean error (eval::MeanErrorAfterStartPose), APE RMSE after SE(3), the
// same mean error of the odometry before loop closure, the lost intervals (the run is "lost", as
// the document marks a sequence whose local map was lost, when the VIO reported any), frames
// per second; per condition the ratio to clear (`none`) of the same world and mode. Outputs:
// results.json, table.md, table.csv, weather_error.svg and weather_error.png (docs/WEATHER.md),
// and report.json (the HTML report's document; report.html with `html`).
#pragma once

#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "optinav/app/html_report.h"
#include "optinav/app/slurm_plan.h"
#include "optinav/app/vio_run.h"
#include "optinav/geometry/trajectory.h"
#include "optinav/sim/camera_noise.h"
#include "optinav/sim/weather.h"
#include "optinav/sim/world.h"
#include "optinav/vio/estimator.h"

namespace optinav::app {

// "urban" | "terrain" (the document's two worlds).
std::optional<sim::WorldKind> ParseWeatherBenchWorld(const std::string& name);
std::string WeatherBenchWorldName(sim::WorldKind world);

// The conditions of the weather suite (sim::WeatherSuite()) for a world, in its order: none,
// rain:50, snow:50, leaves:50, fog and dust at 25/50/75/100 %, and in the urban world
// road-wetness, road-snow and road-leaves at 25/50/75/100 % (12 terrain, 24 urban).
std::vector<sim::WeatherSpec> SuiteConditions(sim::WorldKind world);

// The document's ORB-SLAM3 stereo mean error (m) for a world and condition: a value, "lost"
// (lost = true), or nullopt where the document has no figure (road-* levels, levels it did not
// run).
struct DocumentFigure {
  double mean_error_m = NAN;
  bool lost = false;
};
std::optional<DocumentFigure> DocumentMeanError(sim::WorldKind world,
                                                const sim::WeatherSpec& condition);

struct WeatherBenchOptions {
  std::string out_dir;
  // Image size factor of the car rig (800x600 at 1, the document's camera); 0.5 is 400x300.
  double scale = 0.5;
  std::vector<sim::WorldKind> worlds = {sim::WorldKind::kUrban, sim::WorldKind::kTerrain};
  // Empty: each world's SuiteConditions(). Else these for every world, road-* in urban only.
  std::vector<sim::WeatherSpec> conditions;
  std::vector<vio::VioMode> modes = {vio::VioMode::kStereo};
  int seeds = 1;      // simulation seeds 1 .. seeds (world detail, particles, IMU noise)
  int jobs = 1;       // sequences in parallel (each VIO run has three threads of its own)
  bool html = false;  // also render report.html (app/html_report.h) at the end
  // Keep complete sequences (their marker names the same options) and finished runs of them;
  // re-render interrupted ones. Without it everything is rendered and run again.
  bool reuse = false;
  // YAML vio::VioOptions for every run (as `optinav vio --config`); empty: the built-in defaults.
  // Its text is recorded with each run, and --reuse keeps only runs made with the same text.
  std::string vio_config;
  // The motion model of every run (as `optinav vio --vehicle`); auto: a car on these routes.
  // Recorded with each run; --reuse keeps only runs made with the same setting.
  VehicleModel vehicle = VehicleModel::kAuto;
  // The urban road's asphalt in 8 variants (the default) instead of one repeating texture
  // (`optinav sim --asphalt tiled`); recorded with the sequences and runs, --reuse keeps only
  // the same.
  bool varied_asphalt = true;
  // The cameras' noise (`optinav sim --camera-noise`; on by default); recorded with the sequences
  // and runs, --reuse keeps only the same.
  sim::CameraNoiseOptions camera_noise;
  double duration_s = 0;  // seconds of the car route to render (0: all of it); tests
  size_t max_frames = 0;  // frames the VIO processes (0: all); tests
  // A planned sweep (app/slurm_plan.h). task >= 0: only that task of WeatherBenchTasks() (one
  // sequence and mode): render the sequence unless complete (one task at a time, under a lock
  // beside it), run the mode, write the run's files; no tables; a failed run throws.
  int task = -1;
  // Merge a planned sweep in out_dir: every task must have finished (else Error listing those that
  // have not, with their logs); nothing is rendered or run.
  bool merge = false;

  // "" when valid, else a message that starts with the flag at fault ("--seeds must be ...").
  std::string Check() const;
};

// The command line's list flags ("urban,terrain", "none,fog:100", "stereo,stereo-imu"; an empty
// conditions list: the suite's) into `options`. Throws Error (field: the flag) naming an unknown
// world or mode or a malformed condition.
void ParseWeatherBenchLists(const std::string& worlds, const std::string& conditions,
                            const std::string& modes, WeatherBenchOptions* options);

struct WeatherLost {
  double start_s = 0, end_s = 0;  // from the sequence's first frame
  std::string reason;
};

// One VIO run on one sequence. Errors in metres; NaN where there is no figure.
struct WeatherRunResult {
  std::string sequence;  // e.g. "urban_fog_100"
  sim::WorldKind world = sim::WorldKind::kUrban;
  sim::WeatherSpec condition;
  vio::VioMode mode = vio::VioMode::kStereo;
  int seed = 1;
  bool ok = false;                     // the run finished and was evaluated
  std::string error;                   // why not
  double mean_error_m = NAN;           // the document's metric, the output (loops closed)
  double odometry_mean_error_m = NAN;  // the same before loop closure (= output without loops)
  double ape_rmse_se3_m = NAN;         // RMSE ATE after SE(3) alignment
  double fps = NAN;                    // frames processed / wall time of the run
  double frame_median_ms = NAN, frame_p95_ms = NAN;  // the VIO's work per frame ("total")
  double wall_s = NAN, path_length_m = NAN;
  size_t frames = 0, poses = 0, loops = 0;
  // The loops against the ground truth (from the run's stats, LoopsOffTruth): how many carry
  // their measured relative pose, and how many of those are off the truth's by more than 1 m.
  size_t loops_checked = 0, loops_off_truth = 0;
  std::string vehicle;    // the motion model the run resolved: "ground" | "free"
  double coverage = NAN;  // poses matched to the ground truth / ground-truth frames
  std::vector<WeatherLost> lost;
  // For the HTML report: the ground truth and the output with its first pose put on the truth's
  // (the document metric's alignment), synchronized; the error over time (s, m) between them.
  Trajectory truth, aligned;
  std::vector<std::pair<double, double>> error_over_time;
  bool reused = false;
  bool Lost() const { return !lost.empty(); }
};

// The runs of one world, condition and mode summarised over the seeds.
struct WeatherCell {
  sim::WorldKind world = sim::WorldKind::kUrban;
  sim::WeatherSpec condition;
  vio::VioMode mode = vio::VioMode::kStereo;
  int runs = 0, failed = 0, lost = 0;  // lost: runs with a lost interval
  double mean_error_m = NAN, mean_error_max_m = NAN, odometry_mean_error_m = NAN,
         ape_rmse_se3_m = NAN, fps = NAN;
  double ratio_to_clear = NAN;  // mean_error_m / the clear cell's of the same world and mode
  std::optional<DocumentFigure> document;
  double document_ratio_to_clear = NAN;
};

struct WeatherBenchResult {
  std::vector<WeatherRunResult> runs;
  std::vector<WeatherCell> cells;  // world, then condition, then mode, in the options' order
  std::string table;               // as printed and written to table.md
  double wall_s = 0;
  std::optional<HtmlReportResult> html;  // when options.html
};

// One line of progress (no newline): a sequence rendered, a run finished. Called from one thread
// at a time.
using WeatherBenchProgress = std::function<void(const std::string& line)>;

// Runs the benchmark and writes its files. Throws Error on invalid options (field: the flag) or
// when a sequence cannot be rendered; a failed VIO run is a row marked failed.
WeatherBenchResult RunWeatherBench(const WeatherBenchOptions& options,
                                   const WeatherBenchProgress& progress = {});

// The benchmark's tasks for a planned sweep, in RunWeatherBench's order: per seed, world and
// condition, one per mode; each writes OUT/runs/<sequence>_<mode>_seed<S>.{tum,odometry.tum,
// stats.json,json} (.json last).
std::vector<PlannedTask> WeatherBenchTasks(const WeatherBenchOptions& options);
// Per task: 2 CPUs (the threaded VIO), memory and time from the frame size (docs/SLURM.md).
SlurmResources WeatherBenchTaskResources(const WeatherBenchOptions& options);

// Checks a run's loops (`optinav vio --stats` "loops", each with "old_keyframe_s",
// "new_keyframe_s" and "old_body_from_new_body" [tx ty tz qx qy qz qw]) against `truth`: the
// truth's translation between the two keyframes (interpolated at their times; loops outside the
// truth are not checked) is compared with the measured one. Returns {loops checked, loops off by
// more than `tolerance_m`}; loops without the relative pose (stats before it was written) are not
// checked.
std::pair<size_t, size_t> LoopsOffTruth(const Trajectory& truth, const nlohmann::json& loops,
                                        double tolerance_m = 1.0);

// The cells from the runs (summaries over the seeds, ratios, the document's figures).
std::vector<WeatherCell> SummariseWeatherRuns(const WeatherBenchOptions& options,
                                              const std::vector<WeatherRunResult>& runs);

}  // namespace optinav::app
