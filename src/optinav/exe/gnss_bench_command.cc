// optinav bench gnss: the GNSS-VIO document's table (RMSE ATE after SE(3) alignment per GNSS
// condition), reproduced on simulated sequences and extended: outliers, an outage, three norms,
// several seeds, and the global (unaligned) error that GNSS fusion is for.
#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <random>
#include <thread>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "optinav/eval/metrics.h"
#include "optinav/exe/cli_common.h"
#include "optinav/exe/commands.h"
#include "optinav/io/gnss_io.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/report/svg.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/error.h"
#include "optinav/util/logging.h"
#include "optinav/vio/pipeline.h"

namespace fs = std::filesystem;

namespace optinav {
namespace {

struct Condition {
  std::string name;
  std::string key;            // for --conditions
  double sigma_m = 0;         // noise added
  double factor_sigma_m = 0;  // sigma the fusion is told
  double outlier_fraction = 0;
  double outage_s = 0;  // duration, from outage_start_s of the sequence
};

// The fusion options of every fused run (--gnss-walk changes them before the runs start).
vio::GnssFusionOptions& FusionDefaults() {
  static vio::GnssFusionOptions o;
  return o;
}

const std::vector<Condition>& Conditions() {
  static const std::vector<Condition> c = {{"ideal", "ideal", 0.0, 0.05, 0, 0},
                                           {"sigma 0.5 m", "sigma0.5", 0.5, 0.5, 0, 0},
                                           {"sigma 1.5 m", "sigma1.5", 1.5, 1.5, 0, 0},
                                           {"sigma 3 m", "sigma3", 3.0, 3.0, 0, 0},
                                           {"3 m + 10 % outliers", "outliers", 3.0, 3.0, 0.10, 0},
                                           {"3 m + 60 s outage", "outage", 3.0, 3.0, 0, 60.0}};
  return c;
}

struct Sequence {
  std::string name, dir;
  double outage_start_s = 20;  // after the first frame
  Trajectory truth;            // body, world = ENU
  Eigen::Vector3d lever = Eigen::Vector3d::Zero();
  double length_m = 0;
};

struct RunResult {
  std::string sequence, condition, norm;
  int seed = 0;
  bool ok = false;
  std::string error;
  double ate_se3 = NAN, global_rmse = NAN;
  // The live (causal) estimate's, when the output is smoothed (GnssFusionOptions::smooth).
  double ate_se3_live = NAN, global_rmse_live = NAN;
  double outage_growth_live = NAN, err_10s_after_live = NAN;
  double global_rmse_10s = NAN;  // from 10 s on: after the VIO start-up and the ENU alignment
  size_t poses = 0, lost = 0, factors = 0, rejected = 0;
  double backend_median_ms = NAN, backend_keyframe_median_ms = NAN;
  // Outage: error at its start and end, VIO-alone drift over it, error 10 s after it.
  double outage_start_err = NAN, outage_end_err = NAN, vio_drift_over_outage = NAN,
         err_10s_after = NAN, recovery_s = NAN;
  std::vector<std::pair<double, double>> error_over_time;  // (s, m), unaligned
  std::vector<std::pair<double, double>> live_error_over_time;
  Trajectory estimate;   // as output (world or ENU)
  Trajectory live;       // GNSS runs with an alignment: the live estimate in ENU
  bool aligned = false;  // ENU alignment made (GNSS runs)
};

// The room flight: a loop of a 12 x 8 m room at 1.5 - 3 m, flown four times.
void WriteRoomWaypoints(const std::string& path) {
  std::string s = "# x y altitude (m): a EuRoC-like room flight\n";
  const double pts[][3] = {{0, 0, 1.5},  {5, 1, 2.0},  {6, 4, 2.5},   {2, 6, 3.0},
                           {-4, 5, 2.5}, {-6, 1, 2.0}, {-3, -2, 1.8}, {1, -1, 1.6}};
  for (int lap = 0; lap < 5; ++lap)
    for (const auto& p : pts) s += fmt::format("{} {} {}\n", p[0], p[1], p[2]);
  s += "0 0 1.5\n";
  io::WriteFileAtomically(path, s);
}

Sequence PrepareSequence(const std::string& name, const std::string& root, double scale,
                         bool reuse) {
  Sequence seq;
  seq.name = name;
  seq.dir = (fs::path(root) / "sequences" / name).string();
  const bool complete = fs::is_regular_file(fs::path(seq.dir) / "sim_complete.json");
  if (!(reuse && complete)) {
    sim::SimulationOptions o;
    o.out_dir = seq.dir;
    o.force = true;
    o.scale = scale;
    o.seed = 7;
    o.world.kind = sim::WorldKind::kUrban;
    if (name == "room") {
      const std::string wp = (fs::path(root) / "sequences" / "room_waypoints.txt").string();
      fs::create_directories(fs::path(wp).parent_path());
      WriteRoomWaypoints(wp);
      o.route = "drone:" + wp;
      o.speed_m_s = 1.5;
      o.duration_s = 100;
    } else {
      o.route = "drone";
      o.speed_m_s = 5.0;
      o.altitude_m = 10.0;
      o.duration_s = 200;
    }
    std::printf("bench gnss: rendering the %s sequence -> %s\n", name.c_str(), seq.dir.c_str());
    std::fflush(stdout);
    sim::RunSimulation(o);
  }
  seq.truth = io::ReadTrajectory(
      (fs::path(seq.dir) / "mav0" / "state_groundtruth_estimate0" / "data.csv").string());
  seq.length_m = seq.truth.PathLength();
  seq.outage_start_s = name == "room" ? 20.0 : 40.0;
  const io::GnssSensorInfo info =
      io::ReadGnssSensorYaml((fs::path(seq.dir) / "mav0" / "gnss0" / "sensor.yaml").string());
  seq.lever = info.lever_arm_in_body.value_or(Eigen::Vector3d::Zero());
  return seq;
}

// GNSS of a condition from the ground truth (the simulator's world frame is ENU), 5 Hz. The
// Gaussian noise of a sample depends only on its time and the seed (common random numbers: the
// outlier and outage conditions are the sigma 3 m draw with samples replaced or removed, so
// their rows differ from it by the outliers or the outage alone, not by another noise draw).
std::vector<vio::GnssSample> MakeGnss(const Sequence& seq, const Condition& c, int seed) {
  std::mt19937 rng(1000 + seed), outlier_rng(5000 + seed);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<vio::GnssSample> out;
  const int64_t t0 = seq.truth.t_ns.front(), t1 = seq.truth.t_ns.back();
  for (int64_t t = t0 + 100'000'000; t <= t1; t += 200'000'000) {
    const double ts = (t - t0) * 1e-9;
    const Eigen::Vector3d noise(normal(rng), normal(rng), normal(rng));
    const bool outlier = c.outlier_fraction > 0 && u(outlier_rng) < c.outlier_fraction;
    const Eigen::Vector3d outlier_dir(normal(outlier_rng), normal(outlier_rng),
                                      normal(outlier_rng));
    const double outlier_m = 20.0 + 30.0 * u(outlier_rng);
    if (c.outage_s > 0 && ts >= seq.outage_start_s && ts < seq.outage_start_s + c.outage_s)
      continue;
    const auto pose = seq.truth.InterpolateAt(t);
    if (!pose) continue;
    vio::GnssSample s;
    s.t_ns = t;
    s.sigma_m = c.factor_sigma_m;
    s.position_enu_m = pose->translation + pose->rotation * seq.lever + c.sigma_m * noise;
    if (outlier) s.position_enu_m += outlier_dir.normalized() * outlier_m;
    out.push_back(s);
  }
  return out;
}

double ErrorAtTime(const std::vector<std::pair<double, double>>& series, double t) {
  for (const auto& [ts, e] : series)
    if (ts >= t) return e;
  return NAN;
}

// A run's files in OUT/runs: <stem>.tum (the estimate as output: ENU when aligned, else the VIO
// world) and <stem>.json (what the VIO run reported). Written as each run finishes, so that
// --reuse resumes an interrupted benchmark or adds seeds; the metrics are always recomputed.
std::string RunFileStem(const RunResult& r) {
  std::string name = fmt::format("{}_{}_{}_seed{}", r.sequence, r.condition, r.norm, r.seed);
  for (char& ch : name)
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '.' && ch != '_') ch = '_';
  return name;
}

// The fusion settings a GNSS run was made with (--gnss-factor-scale, --gnss-walk,
// --gnss-smooth-walk-scale): a run made with other settings is not reused.
nlohmann::json FusionSettings() {
  const vio::GnssFusionOptions& o = FusionDefaults();
  nlohmann::json j = {{"factor_sigma_scale", o.factor_sigma_scale},
                      {"alignment_walk_m_per_sqrt_m", o.alignment_walk_m_per_sqrt_m},
                      {"alignment_walk_rad_per_sqrt_m", o.alignment_walk_rad_per_sqrt_m},
                      {"smooth", o.smooth},
                      {"smooth_walk_m_per_sqrt_s", o.smooth_walk_m_per_sqrt_s},
                      {"smooth_walk_rad_per_sqrt_s", o.smooth_walk_rad_per_sqrt_s}};
  // Recorded when not the default (runs made before the option existed used the default).
  if (o.smooth_walk_scale != 1.0) j["smooth_walk_scale"] = o.smooth_walk_scale;
  return j;
}

double JsonNumber(const nlohmann::json& j, const char* key) {
  return j.contains(key) && j.at(key).is_number() ? j.at(key).get<double>() : NAN;
}

// Loads a finished run of the same sequence, condition, norm and seed; false if there is none.
bool LoadRun(const fs::path& stem, RunResult* r) {
  const fs::path json_path = stem.string() + ".json", tum_path = stem.string() + ".tum";
  if (!fs::is_regular_file(json_path) || !fs::is_regular_file(tum_path)) return false;
  try {
    const nlohmann::json j = nlohmann::json::parse(io::ReadFileToString(json_path.string()));
    if (j.at("sequence") != r->sequence || j.at("condition") != r->condition ||
        j.at("norm") != r->norm || j.at("seed") != r->seed)
      throw Error("names another run", {.file = json_path.string()});
    if (r->condition != "no GNSS" && j.value("gnss_settings", nlohmann::json()) != FusionSettings())
      throw Error(
          "made with other fusion settings (--gnss-factor-scale, --gnss-walk, "
          "--gnss-smooth-walk-scale)",
          {.file = json_path.string()});
    r->poses = j.at("poses").get<size_t>();
    r->lost = j.at("lost_intervals").get<size_t>();
    r->factors = j.at("factors").get<size_t>();
    r->rejected = j.at("rejected").get<size_t>();
    r->aligned = j.at("enu_aligned").get<bool>();
    r->backend_median_ms = JsonNumber(j, "backend_median_ms");
    r->backend_keyframe_median_ms = JsonNumber(j, "backend_keyframe_median_ms");
    r->estimate = io::ReadTrajectory(tum_path.string());
    const fs::path live_path = stem.string() + ".live.tum";
    if (r->aligned && r->condition != "no GNSS") r->live = io::ReadTrajectory(live_path.string());
    return !r->estimate.empty();
  } catch (const std::exception& e) {
    spdlog::warn("bench gnss: not reusing {}: {}", json_path.string(), e.what());
    return false;
  }
}

void SaveRun(const fs::path& stem, const RunResult& r) {
  io::WriteTrajectory(stem.string() + ".tum", r.estimate, io::TrajectoryFormat::kTum);
  if (!r.live.empty())
    io::WriteTrajectory(stem.string() + ".live.tum", r.live, io::TrajectoryFormat::kTum);
  const nlohmann::json j = {{"sequence", r.sequence},
                            {"condition", r.condition},
                            {"norm", r.norm},
                            {"seed", r.seed},
                            {"poses", r.poses},
                            {"lost_intervals", r.lost},
                            {"factors", r.factors},
                            {"rejected", r.rejected},
                            {"enu_aligned", r.aligned},
                            {"backend_median_ms", r.backend_median_ms},
                            {"backend_keyframe_median_ms", r.backend_keyframe_median_ms},
                            {"gnss_settings", FusionSettings()}};
  io::WriteFileAtomically(stem.string() + ".json", j.dump(2) + "\n");
}

// Runs the VIO on a condition (nullptr: no GNSS), or reuses the run's files, and evaluates it.
RunResult RunOne(const Sequence& seq, const Condition* condition, const std::string& norm, int seed,
                 const Trajectory* vio_alone, const std::string& out, bool reuse,
                 bool* reused = nullptr) {
  RunResult r;
  r.sequence = seq.name;
  r.condition = condition ? condition->name : "no GNSS";
  r.norm = condition ? norm : "-";
  r.seed = seed;
  const fs::path stem = fs::path(out) / "runs" / RunFileStem(r);
  const bool loaded = reuse && LoadRun(stem, &r);
  if (reused) *reused = loaded;
  try {
    if (!loaded) {
      vio::VioRunOptions options;
      options.threaded = false;
      if (condition) {
        vio::GnssFusionOptions g = FusionDefaults();
        g.norm = *vio::ParseGnssNorm(norm);
        g.lever_arm_in_body = seq.lever;
        options.gnss = g;
        options.gnss_samples = MakeGnss(seq, *condition, seed);
      }
      const vio::VioRunResult v = vio::RunVioOnEuroc(seq.dir, options);
      r.poses = v.estimates.size();
      r.lost = v.lost.size();
      r.factors = v.gnss_stats.factors;
      r.rejected = v.gnss_stats.rejected;
      if (v.timing.count("backend")) r.backend_median_ms = v.timing.at("backend").median_s * 1e3;
      if (v.timing.count("backend_keyframe"))
        r.backend_keyframe_median_ms = v.timing.at("backend_keyframe").median_s * 1e3;
      Trajectory est =
          condition ? vio::EstimatesToEnuTrajectory(v.estimates, v.gnss_smoothing.enu_from_world)
                    : Trajectory();
      if (condition) r.live = vio::EstimatesToEnuTrajectory(v.estimates);
      // Without an ENU alignment (too little motion for the GNSS noise to fix the yaw) the
      // output stays in the VIO world frame, as `optinav vio --gnss` writes it: its ATE counts,
      // it has no global error.
      r.aligned = !est.empty();
      if (est.empty()) est = vio::EstimatesToTrajectory(v.estimates);
      if (est.empty()) throw Error("no pose estimated");
      r.estimate = est;
      SaveRun(stem, r);
    }
    const auto ate_se3 = [&](const eval::SyncedPair& synced) {
      Trajectory aligned = synced.est;
      eval::AlignmentOptions a;
      a.mode = eval::AlignMode::kSe3;
      eval::AlignTrajectory(synced.ref, &aligned, a);
      return eval::ComputeStatistics(
                 eval::ComputeApe(synced.ref, aligned, eval::PoseRelation::kTranslation).errors)
          .rmse;
    };
    const int64_t t0 = seq.truth.t_ns.front();
    // Position error over time (s from the truth's start, m), no alignment.
    const auto error_over_time = [&](const Trajectory& ref, const Trajectory& est) {
      const eval::ErrorSeries e = eval::ComputeApe(ref, est, eval::PoseRelation::kTranslation);
      std::vector<std::pair<double, double>> series;
      for (size_t i = 0; i < e.errors.size(); ++i)
        series.emplace_back((ref.t_ns[e.indices[i]] - t0) * 1e-9, e.errors[i]);
      return series;
    };
    // RMSE of a series from t_from s on (NAN when empty).
    const auto rmse_from = [](const std::vector<std::pair<double, double>>& series, double t_from) {
      double sse = 0;
      size_t n = 0;
      for (const auto& [t, err] : series)
        if (t >= t_from) sse += err * err, ++n;
      return n ? std::sqrt(sse / n) : NAN;
    };
    if (!r.live.empty()) {
      const eval::SyncedPair live = eval::Synchronize(seq.truth, r.live);
      r.ate_se3_live = ate_se3(live);
      r.live_error_over_time = error_over_time(live.ref, live.est);
      const auto& series = r.live_error_over_time;
      r.global_rmse_live = rmse_from(series, -INFINITY);
      if (condition && condition->outage_s > 0) {
        const double ts = seq.outage_start_s, te = ts + condition->outage_s;
        r.outage_growth_live = ErrorAtTime(series, te) - ErrorAtTime(series, ts);
        r.err_10s_after_live = ErrorAtTime(series, te + 10.0);
      }
    }
    const Trajectory& est = r.estimate;
    eval::SyncedPair synced = eval::Synchronize(seq.truth, est);
    r.ate_se3 = ate_se3(synced);
    r.ok = true;
    if (condition && !r.aligned) return r;  // no global error in the world frame
    Trajectory global = synced.est;
    if (!condition) {  // no ENU frame: SE(3) alignment on the first 5 s only
      r.aligned = false;
      eval::AlignmentOptions a;
      a.mode = eval::AlignMode::kSe3;
      for (size_t i = 0; i < synced.est.size(); ++i)
        if (synced.est.t_ns[i] - synced.est.t_ns[0] <= 5'000'000'000) a.n_to_align = i + 1;
      eval::AlignTrajectory(synced.ref, &global, a);
    }
    r.error_over_time = error_over_time(synced.ref, global);
    r.global_rmse = rmse_from(r.error_over_time, -INFINITY);
    r.global_rmse_10s = rmse_from(r.error_over_time, 10.0);
    if (condition && condition->outage_s > 0) {
      const double ts = seq.outage_start_s, te = ts + condition->outage_s;
      r.outage_start_err = ErrorAtTime(r.error_over_time, ts);
      r.outage_end_err = ErrorAtTime(r.error_over_time, te);
      r.err_10s_after = ErrorAtTime(r.error_over_time, te + 10.0);
      for (const auto& [t, err] : r.error_over_time)
        if (t >= te && err < 1.5) {
          r.recovery_s = t - te;
          break;
        }
      if (vio_alone && !vio_alone->empty()) {
        // VIO alone over the same interval: its pose at the outage start put on the truth's.
        const auto a0 = vio_alone->InterpolateAt(t0 + static_cast<int64_t>(ts * 1e9));
        const auto a1 = vio_alone->InterpolateAt(t0 + static_cast<int64_t>(te * 1e9));
        const auto g0 = seq.truth.InterpolateAt(t0 + static_cast<int64_t>(ts * 1e9));
        const auto g1 = seq.truth.InterpolateAt(t0 + static_cast<int64_t>(te * 1e9));
        if (a0 && a1 && g0 && g1)
          r.vio_drift_over_outage =
              ((*g0 * a0->Inverse() * *a1).translation - g1->translation).norm();
      }
    }
  } catch (const std::exception& ex) {
    r.error = ex.what();
  }
  return r;
}

struct Cell {
  double mean = NAN, max = NAN;
  int n = 0, failed = 0;
};

Cell Summarise(const std::vector<RunResult>& runs, const std::string& seq,
               const std::string& condition, const std::string& norm, double RunResult::*field) {
  Cell c;
  double sum = 0, mx = -INFINITY;
  for (const RunResult& r : runs) {
    if (r.sequence != seq || r.condition != condition || r.norm != norm) continue;
    if (!r.ok || !std::isfinite(r.*field)) {
      if (r.ok && !r.aligned && r.condition != "no GNSS") continue;  // world frame: no global
      ++c.failed;
      continue;
    }
    sum += r.*field;
    mx = std::max(mx, r.*field);
    ++c.n;
  }
  if (c.n) c.mean = sum / c.n, c.max = mx;
  return c;
}

// Error over time of the outdoor flight: no GNSS vs sigma 3 m vs the outage (first seed, Huber).
void WritePlot(const std::string& path, const std::vector<RunResult>& runs, const std::string& seq,
               double outage_start_s) {
  struct Series {
    std::string name, colour;
    bool live;  // the run's live estimate instead of its output
  };
  const std::vector<Series> series = {{"no GNSS", "#888888", false},
                                      {"sigma 3 m", "#9ecae1", true},
                                      {"sigma 3 m", "#1f77b4", false},
                                      {"3 m + 10 % outliers", "#2ca02c", false},
                                      {"3 m + 60 s outage", "#d62728", false}};
  std::vector<const RunResult*> picked;
  double t_max = 1, e_max = 0.5;
  for (const auto& [name, colour, live] : series) {
    const RunResult* best = nullptr;
    for (const RunResult& r : runs)
      if (r.ok && r.sequence == seq && r.condition == name &&
          (r.norm == "huber" || r.norm == "-") && (!best || r.seed < best->seed))
        best = &r;
    picked.push_back(best);
    if (!best) continue;
    for (const auto& [t, e] : live ? best->live_error_over_time : best->error_over_time)
      t_max = std::max(t_max, t), e_max = std::max(e_max, e);
  }
  e_max = std::min(e_max, 20.0);
  const double W = 900, H = 420, left = 60, right = 20, top = 40, bottom = 50;
  report::SvgDocument svg(W, H);
  svg.Rect(0, 0, W, H, "white");
  auto X = [&](double t) { return left + (W - left - right) * t / t_max; };
  auto Y = [&](double e) { return H - bottom - (H - top - bottom) * std::min(e, e_max) / e_max; };
  svg.Text(W / 2, 22,
           "optinav bench gnss: global position error (no alignment), " + seq + " flight", 15,
           "middle");
  const report::Ticks yt = report::NiceTicks(0, e_max), xt = report::NiceTicks(0, t_max, 8);
  for (double v = yt.start; v <= e_max + 1e-9; v += yt.step) {
    svg.Line(left, Y(v), W - right, Y(v), "#eeeeee", 1);
    svg.Text(left - 6, Y(v) + 4, report::FormatTick(v, yt.step), 11, "end");
  }
  for (double v = xt.start; v <= t_max + 1e-9; v += xt.step)
    svg.Text(X(v), H - bottom + 16, report::FormatTick(v, xt.step), 11, "middle");
  svg.Text(W / 2, H - 12, "time (s)", 12, "middle");
  svg.Text(16, H / 2, "error (m)", 12, "middle",
           "transform=\"rotate(-90 16 " + std::to_string(H / 2) + ")\"");
  svg.Rect(X(outage_start_s), top, X(outage_start_s + 60) - X(outage_start_s), H - top - bottom,
           "#fde0dd");
  svg.Text(X(outage_start_s + 30), top + 14, "60 s outage (red run)", 11, "middle");
  for (size_t k = 0; k < series.size(); ++k) {
    if (!picked[k] || (series[k].live && picked[k]->live_error_over_time.empty())) continue;
    std::string pts;
    const auto& s = series[k].live ? picked[k]->live_error_over_time : picked[k]->error_over_time;
    const size_t step = std::max<size_t>(1, s.size() / 1500);
    for (size_t i = 0; i < s.size(); i += step)
      pts += fmt::format("{:.1f},{:.1f} ", X(s[i].first), Y(s[i].second));
    svg.Polyline(pts, series[k].colour, 1.5);
    svg.Rect(W - 260, top + 10 + 18 * k, 14, 4, series[k].colour);
    svg.Text(W - 240, top + 16 + 18 * k,
             series[k].name +
                 (series[k].name == "no GNSS" ? " (first 5 s aligned)"
                  : series[k].live            ? ", Huber, live"
                                              : ", Huber") +
                 fmt::format(": RMSE {:.2f} m",
                             series[k].live ? picked[k]->global_rmse_live : picked[k]->global_rmse),
             11);
  }
  svg.Line(left, H - bottom, W - right, H - bottom, "black", 1);
  svg.Line(left, top, left, H - bottom, "black", 1);
  io::WriteFileAtomically(path, svg.Finish());
}

std::vector<std::string> SplitList(const std::string& s) {
  std::vector<std::string> out;
  std::string cur;
  for (char ch : s + ",") {
    if (ch == ',') {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      cur += ch;
    }
  }
  return out;
}

int RunGnssBench(int argc, char** argv) {
  CLI::App app{"GNSS fusion benchmark: the GNSS-VIO document's table on simulated flights",
               "optinav bench gnss"};
  std::string out, sequences = "room,outdoor", norms = "l2,huber,tukey", log_level = "warn";
  std::string conditions = "ideal,sigma0.5,sigma1.5,sigma3,outliers,outage", walk;
  int seeds = 3, jobs = 2;
  double scale = 1.0;
  bool reuse = false;
  app.add_option("--out", out, "output folder (sequences/, results.csv/.json, plot)")->required();
  app.add_option("--seeds", seeds, "GNSS noise seeds per condition")->capture_default_str();
  app.add_option("--sequences", sequences, "room,outdoor (comma separated)")->capture_default_str();
  app.add_option("--norms", norms, "l2,huber,tukey (comma separated)")->capture_default_str();
  app.add_option("--conditions", conditions, "GNSS conditions (comma separated)")
      ->capture_default_str();
  app.add_option("--gnss-factor-scale", FusionDefaults().factor_sigma_scale,
                 "GNSS factor sigma x this for every fused run (as optinav vio "
                 "--gnss-factor-scale)")
      ->capture_default_str();
  app.add_option("--gnss-smooth-walk-scale", FusionDefaults().smooth_walk_scale,
                 "the output smoother's random walk = the alignment walk x this, for every fused "
                 "run (as optinav vio --gnss-smooth-walk-scale)")
      ->capture_default_str();
  app.add_option("--gnss-walk", walk,
                 "alignment random walk M_PER_SQRT_M,RAD_PER_SQRT_M for every fused run (default "
                 "from GnssFusionOptions, as optinav vio --gnss-walk)");
  app.add_option("--scale", scale, "image size factor of the rendered sequences")
      ->capture_default_str();
  app.add_option("--jobs", jobs, "runs in parallel (each VIO run is single-threaded)")
      ->capture_default_str();
  app.add_flag(
      "--reuse", reuse,
      "reuse complete sequences in OUT/sequences and finished runs in OUT/runs (resume, add "
      "seeds)");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    SetLogLevel(log_level);
    if (seeds < 1) throw Error("must be >= 1", {.field = "--seeds"});
    if (jobs < 1) throw Error("must be >= 1", {.field = "--jobs"});
    const std::vector<std::string> seq_names = SplitList(sequences), norm_names = SplitList(norms);
    for (const std::string& s : seq_names)
      if (s != "room" && s != "outdoor")
        throw Error("unknown sequence '" + s + "'", {.field = "--sequences"});
    for (const std::string& n : norm_names)
      if (!vio::ParseGnssNorm(n)) throw Error("unknown norm '" + n + "'", {.field = "--norms"});
    std::vector<const Condition*> selected;
    for (const std::string& k : SplitList(conditions)) {
      const auto it = std::find_if(Conditions().begin(), Conditions().end(),
                                   [&](const Condition& c) { return c.key == k; });
      if (it == Conditions().end())
        throw Error(
            "unknown condition '" + k + "' (ideal, sigma0.5, sigma1.5, sigma3, outliers, outage)",
            {.field = "--conditions"});
      selected.push_back(&*it);
    }
    if (const std::string e = FusionDefaults().Check(); !e.empty())
      throw Error(e,
                  {.field = e.find("smooth_walk") != std::string::npos ? "--gnss-smooth-walk-scale"
                                                                       : "--gnss-factor-scale"});
    if (!walk.empty()) {
      const std::vector<double> w =
          ParseNumbers(walk, 2, "M_PER_SQRT_M,RAD_PER_SQRT_M", "--gnss-walk");
      if (w[0] < 0 || w[1] < 0) throw Error("must be >= 0", {.field = "--gnss-walk"});
      FusionDefaults().alignment_walk_m_per_sqrt_m = w[0];
      FusionDefaults().alignment_walk_rad_per_sqrt_m = w[1];
    }
    fs::create_directories(fs::path(out) / "runs");
    std::vector<Sequence> seqs;
    for (const std::string& s : seq_names) seqs.push_back(PrepareSequence(s, out, scale, reuse));

    // VIO alone first (the reference of every row), then every condition x norm x seed.
    std::vector<RunResult> runs;
    std::map<std::string, Trajectory> alone;
    for (const Sequence& s : seqs) {
      runs.push_back(RunOne(s, nullptr, "", 0, nullptr, out, reuse));
      if (!runs.back().ok) throw Error("VIO alone failed: " + runs.back().error, {.file = s.dir});
      std::printf(
          "bench gnss: %s (%.0f m): VIO alone ATE %.3f m, global (first 5 s aligned) %.3f m, "
          "%zu lost interval(s)\n",
          s.name.c_str(), s.length_m, runs.back().ate_se3, runs.back().global_rmse,
          runs.back().lost);
      std::fflush(stdout);
      alone[s.name] = runs.back().estimate;
    }
    struct Job {
      const Sequence* seq;
      const Condition* condition;
      std::string norm;
      int seed;
    };
    std::vector<Job> todo;
    for (const Sequence& s : seqs)
      for (const Condition* c : selected)
        for (const std::string& n : norm_names)
          for (int seed = 1; seed <= seeds; ++seed) todo.push_back({&s, c, n, seed});
    std::vector<RunResult> results(todo.size());
    std::atomic<size_t> next{0}, done{0};
    std::mutex print;
    auto worker = [&] {
      for (size_t i; (i = next++) < todo.size();) {
        const Job& j = todo[i];
        bool reused = false;
        results[i] =
            RunOne(*j.seq, j.condition, j.norm, j.seed, &alone[j.seq->name], out, reuse, &reused);
        std::lock_guard lock(print);
        const RunResult& r = results[i];
        std::printf(
            "bench gnss: [%zu/%zu] %s, %s, %s, seed %d: %s%s\n", ++done, todo.size(),
            r.sequence.c_str(), r.condition.c_str(), r.norm.c_str(), r.seed,
            reused ? "(reused) " : "",
            r.ok ? fmt::format("ATE {:.3f} m, global {:.3f} m", r.ate_se3, r.global_rmse).c_str()
                 : ("failed: " + r.error).c_str());
        std::fflush(stdout);
      }
    };
    std::vector<std::thread> threads;
    for (int k = 0; k < jobs; ++k) threads.emplace_back(worker);
    for (auto& t : threads) t.join();
    runs.insert(runs.end(), results.begin(), results.end());

    // Tables.
    std::string table1 =
        "RMSE ATE after SE(3) alignment (m), mean over seeds [max]; last column: fused <= 1.05 x "
        "no GNSS in every seed\n";
    std::string table2 =
        "Global RMSE in ENU without alignment (m), mean over seeds [max] (no GNSS: SE(3)-aligned "
        "on its first 5 s)\n";
    std::string header = fmt::format("| {:<22} | {:<5} |", "GNSS", "norm");
    for (const Sequence& s : seqs)
      header += fmt::format(" {:>20} |", s.name + fmt::format(" ({:.0f} m)", s.length_m));
    std::string table3 =
        "Global RMSE in ENU without alignment from 10 s on (m): after the VIO's in-motion start-up "
        "and the ENU alignment\n";
    std::string table4 =
        "The live (causal) estimate, each frame through the alignment known right after it: RMSE "
        "ATE after SE(3) / global RMSE (m), mean over seeds\n";
    table1 += header + " never worse |\n";
    table2 += header + "\n";
    table3 += header + "\n";
    table4 += header + "\n";
    bool all_never_worse = true;
    auto row = [&](const std::string& cond, const std::string& norm) {
      std::string r1 = fmt::format("| {:<22} | {:<5} |", cond, norm), r2 = r1, r3 = r1, r4 = r1;
      bool never_worse = true;
      for (const Sequence& s : seqs) {
        const Cell a = Summarise(runs, s.name, cond, norm, &RunResult::ate_se3);
        const Cell g = Summarise(runs, s.name, cond, norm, &RunResult::global_rmse);
        r1 += fmt::format(
            " {:>20} |",
            a.n ? fmt::format("{:.3f} [{:.3f}]{}", a.mean, a.max, a.failed ? " !" : "") : "failed");
        r2 += fmt::format(
            " {:>20} |", g.n ? fmt::format("{:.3f} [{:.3f}]{}", g.mean, g.max, g.failed ? " !" : "")
                         : a.n ? "not aligned"
                               : "failed");
        const Cell g10 = Summarise(runs, s.name, cond, norm, &RunResult::global_rmse_10s);
        r3 += fmt::format(" {:>20} |", g10.n ? fmt::format("{:.3f} [{:.3f}]", g10.mean, g10.max)
                                       : a.n ? "not aligned"
                                             : "failed");
        const Cell la = Summarise(runs, s.name, cond, norm, &RunResult::ate_se3_live);
        const Cell lg = Summarise(runs, s.name, cond, norm, &RunResult::global_rmse_live);
        r4 +=
            fmt::format(" {:>20} |", la.n ? fmt::format("{:.3f} / {:.3f}", la.mean, lg.mean) : "-");
        const Cell base = Summarise(runs, s.name, "no GNSS", "-", &RunResult::ate_se3);
        if (cond != "no GNSS") {
          if (a.failed || !(a.max <= 1.05 * base.mean)) never_worse = false;
        }
      }
      if (cond != "no GNSS") all_never_worse &= never_worse;
      table1 += r1 +
                (cond == "no GNSS" ? "             |"
                 : never_worse     ? " yes         |"
                                   : " NO          |") +
                "\n";
      table2 += r2 + "\n";
      table3 += r3 + "\n";
      if (cond != "no GNSS") table4 += r4 + "\n";
    };
    row("no GNSS", "-");
    for (const Condition* c : selected)
      for (const std::string& n : norm_names) row(c->name, n);

    std::string outage;
    for (const RunResult& r : runs) {
      if (!r.ok || !r.aligned || r.condition != "3 m + 60 s outage") continue;  // no ENU: no error
      outage += fmt::format(
          "| {:<8} | {:<5} | {:>4} | {:>10.2f} | {:>10.2f} | {:>10.2f} | {:>14.2f} | {:>12.2f} | "
          "{:>11.2f} | {:>11.2f} |\n",
          r.sequence, r.norm, r.seed, r.outage_start_err, r.outage_end_err,
          r.outage_end_err - r.outage_start_err, r.vio_drift_over_outage, r.err_10s_after,
          r.outage_growth_live, r.err_10s_after_live);
    }
    const std::string outage_table =
        "60 s outage: error at its start and end (m), growth, VIO alone's drift over the same 60 s "
        "(m), error 10 s after GNSS returns (m); the same two for the live estimate (which does "
        "not "
        "see the samples after the outage)\n| sequence | norm  | seed | start      | end        | "
        "growth     | VIO-alone drift | +10 s        | live growth | live +10 s  |\n" +
        outage;
    std::string speed;
    for (const Sequence& s : seqs) {
      const Cell b0 = Summarise(runs, s.name, "no GNSS", "-", &RunResult::backend_median_ms);
      const Cell b1 = Summarise(runs, s.name, "sigma 3 m", "huber", &RunResult::backend_median_ms);
      const Cell k0 =
          Summarise(runs, s.name, "no GNSS", "-", &RunResult::backend_keyframe_median_ms);
      const Cell k1 =
          Summarise(runs, s.name, "sigma 3 m", "huber", &RunResult::backend_keyframe_median_ms);
      speed += fmt::format(
          "backend median, {}: per frame no GNSS {:.2f} ms, GNSS sigma 3 m (Huber) {:.2f} ms "
          "(x{:.3f}); per keyframe {:.2f} ms vs {:.2f} ms (x{:.3f}); runs in parallel, noisy: "
          "bench/RESULTS.md has side-by-side runs\n",
          s.name, b0.mean, b1.mean, b1.mean / b0.mean, k0.mean, k1.mean, k1.mean / k0.mean);
    }
    const std::string report =
        table1 + "\n" + table2 + "\n" + table3 + "\n" + table4 + "\n" + outage_table + "\n" + speed;
    std::printf("\n%s", report.c_str());
    std::printf("never worse than VIO alone (every row, every seed, 5 %% margin): %s\n",
                all_never_worse ? "yes" : "NO");

    // Files.
    std::string csv =
        "sequence,condition,norm,seed,ok,aligned,ate_se3_m,global_rmse_m,poses,lost,factors,"
        "rejected,global_rmse_10s_m,backend_median_ms,backend_keyframe_median_ms,outage_start_err_"
        "m,outage_end_err_m,vio_drift_over_outage_m,"
        "err_10s_after_m,live_ate_se3_m,live_global_rmse_m,error\n";
    nlohmann::json j;
    j["sequences"] = nlohmann::json::array();
    for (const Sequence& s : seqs)
      j["sequences"].push_back({{"name", s.name}, {"dir", s.dir}, {"length_m", s.length_m}});
    j["runs"] = nlohmann::json::array();
    for (const RunResult& r : runs) {
      csv += fmt::format(
          "{},{},{},{},{},{},{:.4f},{:.4f},{},{},{},{},{:.4f},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{:"
          ".3f},{:.4f},{:.4f},\"{}\"\n",
          r.sequence, r.condition, r.norm, r.seed, r.ok ? 1 : 0, r.aligned ? 1 : 0, r.ate_se3,
          r.global_rmse, r.poses, r.lost, r.factors, r.rejected, r.global_rmse_10s,
          r.backend_median_ms, r.backend_keyframe_median_ms, r.outage_start_err, r.outage_end_err,
          r.vio_drift_over_outage, r.err_10s_after, r.ate_se3_live, r.global_rmse_live, r.error);
      j["runs"].push_back({{"sequence", r.sequence},
                           {"condition", r.condition},
                           {"norm", r.norm},
                           {"seed", r.seed},
                           {"ok", r.ok},
                           {"enu_aligned", r.aligned},
                           {"ate_se3_m", r.ate_se3},
                           {"global_rmse_m", r.global_rmse},
                           {"global_rmse_from_10s_m", r.global_rmse_10s},
                           {"live_ate_se3_m", r.ate_se3_live},
                           {"live_global_rmse_m", r.global_rmse_live},
                           {"live_outage_growth_m", r.outage_growth_live},
                           {"live_err_10s_after_m", r.err_10s_after_live},
                           {"lost_intervals", r.lost},
                           {"factors", r.factors},
                           {"rejected", r.rejected},
                           {"backend_median_ms", r.backend_median_ms},
                           {"backend_keyframe_median_ms", r.backend_keyframe_median_ms},
                           {"outage_start_err_m", r.outage_start_err},
                           {"outage_end_err_m", r.outage_end_err},
                           {"vio_drift_over_outage_m", r.vio_drift_over_outage},
                           {"err_10s_after_m", r.err_10s_after},
                           {"error", r.error}});
    }
    j["never_worse"] = all_never_worse;
    io::WriteFileAtomically((fs::path(out) / "results.csv").string(), csv);
    io::WriteFileAtomically((fs::path(out) / "results.json").string(), j.dump(2) + "\n");
    io::WriteFileAtomically((fs::path(out) / "tables.md").string(), report);
    for (const Sequence& s : seqs)
      WritePlot((fs::path(out) / ("error_" + s.name + ".svg")).string(), runs, s.name,
                s.outage_start_s);
    std::printf(
        "bench gnss: results.csv, results.json, tables.md, error_*.svg, runs/*.tum+json -> %s\n",
        out.c_str());
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}

}  // namespace

int RunBench(int argc, char** argv) {
  if (argc >= 2 && std::string(argv[1]) == "gnss") return RunGnssBench(argc - 1, argv + 1);
  std::fprintf(stderr,
               "usage: optinav bench gnss --out DIR [options]   (optinav bench gnss --help)\n");
  return 2;
}

}  // namespace optinav
