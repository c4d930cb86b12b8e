// The GNSS fusion benchmark behind `optinav bench gnss`: RMSE ATE after SE(3) alignment of the
// fused VIO per GNSS condition (ideal, 0.5 / 1.5 / 3 m noise), the table by which GNSS-VIO fusion
// is usually compared, on simulated flights, extended with outliers, an outage, three norms,
// several seeds and the global (unaligned) error that GNSS fusion is for.
//
// Per sequence the VIO runs alone once (the reference of every row), then once per condition x
// norm x seed, `jobs` runs in parallel. Output folder: sequences/ (rendered), runs/ (per run
// <stem>.tum, <stem>.live.tum, <stem>.json; --reuse takes them back), results.csv,
// results.json, tables.md, error_<sequence>.svg and report.json (the HTML report's document;
// report.html with `html`) (docs/FORMATS.md).
#pragma once

#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "optinav/app/html_report.h"
#include "optinav/app/slurm_plan.h"
#include "optinav/geometry/trajectory.h"
#include "optinav/vio/gnss_fusion.h"

namespace optinav::app {

enum class GnssBenchSequence {
  kRoom,     // a 12 x 8 m room flown five times at 1.5 - 3 m, 1.5 m/s, 100 s
  kOutdoor,  // the simulator's urban drone flight at 10 m, 5 m/s, 200 s
};
std::string GnssBenchSequenceName(GnssBenchSequence sequence);  // room | outdoor
std::optional<GnssBenchSequence> ParseGnssBenchSequence(const std::string& name);

enum class GnssCondition { kIdeal, kSigma0_5, kSigma1_5, kSigma3, kOutliers, kOutage };

// What a condition does to the GNSS (5 Hz, from the ground truth plus the lever arm).
struct GnssConditionSpec {
  const char* key;          // as --conditions spells it
  const char* name;         // as the tables, results and run files name it
  double sigma_m;           // Gaussian noise added, per axis
  double factor_sigma_m;    // the sigma the fusion is told
  double outlier_fraction;  // samples moved 20-50 m in a random direction
  double outage_s;          // no samples for this long from the sequence's outage start
};
const GnssConditionSpec& ConditionSpec(GnssCondition condition);
std::vector<GnssCondition> AllGnssConditions();
std::optional<GnssCondition> ParseGnssCondition(const std::string& key);
// The names a run is filed under: "no GNSS" and "-" for the VIO alone.
std::string ConditionLabel(std::optional<GnssCondition> condition);
std::string NormLabel(std::optional<vio::GnssNorm> norm);

struct GnssBenchOptions {
  std::string out_dir;
  std::vector<GnssBenchSequence> sequences = {GnssBenchSequence::kRoom,
                                              GnssBenchSequence::kOutdoor};
  std::vector<GnssCondition> conditions = AllGnssConditions();
  std::vector<vio::GnssNorm> norms = {vio::GnssNorm::kL2, vio::GnssNorm::kHuber,
                                      vio::GnssNorm::kTukey};
  int seeds = 3;          // GNSS noise seeds 1 .. seeds per condition and norm
  int jobs = 2;           // runs in parallel (each VIO run is single-threaded)
  double scale = 1.0;     // image size factor of the rendered sequences
  double duration_s = 0;  // the sequences' length; 0: room 100 s, outdoor 200 s
  // Reuse complete sequences in out_dir/sequences and finished runs in out_dir/runs (resume an
  // interrupted benchmark, add seeds). A run made with other fusion settings is made again.
  bool reuse = false;
  // Every fused run's fusion; the norm and the lever arm are set per run.
  vio::GnssFusionOptions fusion;
  // A planned sweep (app/slurm_plan.h). task >= 0: only that task of GnssBenchTasks() (one run):
  // render its sequence unless complete (one task at a time, under a lock beside it), run the
  // VIO, write the run's files; no tables; a failed run throws.
  int task = -1;
  // Merge a planned sweep in out_dir: every task must have finished (else Error listing those
  // that have not, with their logs); nothing is rendered or run.
  bool merge = false;
  bool html = false;  // also render report.html (app/html_report.h) at the end

  // "" when valid, else a message that starts with the flag at fault ("--seeds must be ...").
  std::string Check() const;
};

struct GnssBenchSequenceInfo {
  GnssBenchSequence sequence = GnssBenchSequence::kRoom;
  std::string name, dir;
  double outage_start_s = 20;  // after the first frame
  Trajectory truth;            // body, world = ENU
  Eigen::Vector3d lever_arm_in_body = Eigen::Vector3d::Zero();
  double length_m = 0;
  bool rendered = false;  // rendered by this invocation: its earlier runs are not reused
};

// Errors in metres; NaN where a figure does not apply.
struct GnssRunResult {
  std::string sequence;
  std::optional<GnssCondition> condition;  // nullopt: the VIO alone
  std::optional<vio::GnssNorm> norm;       // nullopt: the VIO alone
  int seed = 0;                            // 0: the VIO alone
  bool ok = false;
  std::string error;
  double ate_se3 = NAN, global_rmse = NAN;
  double global_rmse_10s = NAN;  // from 10 s on: after the VIO start-up and the ENU alignment
  // The live (causal) estimate's, when the output is smoothed (GnssFusionOptions::smooth).
  double ate_se3_live = NAN, global_rmse_live = NAN;
  double outage_growth_live = NAN, err_10s_after_live = NAN;
  size_t poses = 0, lost = 0, factors = 0, rejected = 0;
  double backend_median_ms = NAN, backend_keyframe_median_ms = NAN;
  // Outage: error at its start and end, VIO-alone drift over it, error 10 s after it.
  double outage_start_err = NAN, outage_end_err = NAN, vio_drift_over_outage = NAN,
         err_10s_after = NAN, recovery_s = NAN;
  std::vector<std::pair<double, double>> error_over_time;  // (s, m), unaligned
  std::vector<std::pair<double, double>> live_error_over_time;
  Trajectory estimate;  // as output (ENU when aligned, else the VIO world)
  Trajectory live;      // GNSS runs with an alignment: the live estimate in ENU
  // What the global error is measured on (ENU; the VIO alone: aligned on its first 5 s), synced
  // to the truth; empty without a global error.
  Trajectory global;
  // GNSS samples the fusion did not use: time and reason (the HTML report marks them).
  std::vector<std::pair<int64_t, std::string>> gnss_rejected;
  bool aligned = false;  // ENU alignment made (GNSS runs)
  bool reused = false;   // loaded from out_dir/runs (--reuse)
};

struct GnssBenchResult {
  std::vector<GnssBenchSequenceInfo> sequences;
  // The VIO alone per sequence, then every sequence x condition x norm x seed.
  std::vector<GnssRunResult> runs;
  std::string tables;                    // as printed and written to tables.md
  bool never_worse = true;               // every fused run's ATE <= 1.05 x the VIO alone's
  std::optional<HtmlReportResult> html;  // when options.html
};

// One line of progress (no newline): a sequence rendered, a run finished. Called from one thread
// at a time.
using GnssBenchProgress = std::function<void(const std::string& line)>;

// Runs the benchmark and writes its files. Throws Error when a sequence cannot be made or the VIO
// alone fails; a failed fused run is a row marked failed.
GnssBenchResult RunGnssBench(const GnssBenchOptions& options,
                             const GnssBenchProgress& progress = {});

// The benchmark's tasks for a planned sweep, one per run in RunGnssBench's order: per sequence
// the VIO alone, then per sequence, condition, norm and seed the fused run; each writes
// OUT/runs/<stem>.{tum,json} (.json last).
std::vector<PlannedTask> GnssBenchTasks(const GnssBenchOptions& options);
// Per task: 1 CPU (the VIO runs unthreaded here), memory and time from the frame size and the
// sequence's length (docs/SLURM.md).
SlurmResources GnssBenchTaskResources(const GnssBenchOptions& options);

// The GNSS of a condition for a ground truth. Common random numbers: the Gaussian noise of a
// sample depends only on its time and the seed, so the outlier and outage conditions are the
// sigma 3 m draw with samples replaced or removed, and the 0.5 / 1.5 / 3 m conditions scale one
// draw.
std::vector<vio::GnssSample> MakeConditionGnss(const Trajectory& truth,
                                               const Eigen::Vector3d& lever_arm_in_body,
                                               double outage_start_s, GnssCondition condition,
                                               int seed);

}  // namespace optinav::app
