#include "optinav/app/gnss_bench.h"

#include <array>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "optinav/app/internal/gnss_bench_report.h"
#include "optinav/eval/metrics.h"
#include "optinav/io/gnss_io.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/report/html_report.h"
#include "optinav/sim/sensors.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/error.h"
#include "optinav/util/file_lock.h"
#include "optinav/util/string_printf.h"
#include "optinav/vio/pipeline.h"

namespace fs = std::filesystem;

namespace optinav::app {
namespace {

constexpr std::array<GnssConditionSpec, 6> kConditions = {{
    {"ideal", "ideal", 0.0, 0.05, 0, 0},
    {"sigma0.5", "sigma 0.5 m", 0.5, 0.5, 0, 0},
    {"sigma1.5", "sigma 1.5 m", 1.5, 1.5, 0, 0},
    {"sigma3", "sigma 3 m", 3.0, 3.0, 0, 0},
    {"outliers", "3 m + 10 % outliers", 3.0, 3.0, 0.10, 0},
    {"outage", "3 m + 60 s outage", 3.0, 3.0, 0, 60.0},
}};

}  // namespace

std::string GnssBenchSequenceName(GnssBenchSequence sequence) {
  return sequence == GnssBenchSequence::kRoom ? "room" : "outdoor";
}

std::optional<GnssBenchSequence> ParseGnssBenchSequence(const std::string& name) {
  for (GnssBenchSequence s : {GnssBenchSequence::kRoom, GnssBenchSequence::kOutdoor})
    if (GnssBenchSequenceName(s) == name) return s;
  return std::nullopt;
}

const GnssConditionSpec& ConditionSpec(GnssCondition condition) {
  return kConditions.at(static_cast<size_t>(condition));
}

std::vector<GnssCondition> AllGnssConditions() {
  return {GnssCondition::kIdeal,  GnssCondition::kSigma0_5, GnssCondition::kSigma1_5,
          GnssCondition::kSigma3, GnssCondition::kOutliers, GnssCondition::kOutage};
}

std::optional<GnssCondition> ParseGnssCondition(const std::string& key) {
  for (GnssCondition c : AllGnssConditions())
    if (ConditionSpec(c).key == key) return c;
  return std::nullopt;
}

std::string ConditionLabel(std::optional<GnssCondition> condition) {
  return condition ? ConditionSpec(*condition).name : "no GNSS";
}

std::string NormLabel(std::optional<vio::GnssNorm> norm) {
  return norm ? vio::GnssNormName(*norm) : "-";
}

std::string GnssBenchOptions::Check() const {
  if (out_dir.empty()) return "--out must not be empty";
  if (seeds < 1) return "--seeds must be >= 1";
  if (jobs < 1) return "--jobs must be >= 1";
  if (!(scale > 0 && std::isfinite(scale)))
    return fmt::format("--scale must be > 0, got {}", scale);
  if (!(duration_s >= 0 && std::isfinite(duration_s)))
    return fmt::format("--duration must be >= 0, got {}", duration_s);
  if (const std::string e = fusion.Check(); !e.empty()) return "--gnss " + e;
  return "";
}

std::vector<vio::GnssSample> MakeConditionGnss(const Trajectory& truth,
                                               const Eigen::Vector3d& lever_arm_in_body,
                                               double outage_start_s, GnssCondition condition,
                                               int seed) {
  if (truth.empty()) return {};
  const GnssConditionSpec& c = ConditionSpec(condition);
  sim::GnssOptions o;
  o.draws = sim::GnssDraws::kNoiseAndOutlierStreams;
  o.rate_hz = 5.0;
  o.first_sample_s = 0.1;
  o.sigma_m = c.sigma_m;
  o.outlier_fraction = c.outlier_fraction;
  o.outlier_magnitude_m = 20.0;
  o.outlier_magnitude_max_m = 50.0;
  if (c.outage_s > 0) o.outages = {{outage_start_s, c.outage_s}};
  o.lever_arm_in_body = lever_arm_in_body;
  const std::vector<sim::GnssMeasurement> gnss =
      sim::SimulateGnss([&](int64_t t_ns) { return truth.InterpolateAt(t_ns); }, truth.t_ns.front(),
                        truth.t_ns.back(), o, static_cast<uint64_t>(seed));
  std::vector<vio::GnssSample> out;
  out.reserve(gnss.size());
  for (const sim::GnssMeasurement& m : gnss) {
    vio::GnssSample s;
    s.t_ns = m.t_ns;
    s.sigma_m = c.factor_sigma_m;
    s.position_enu_m = m.position_enu_m;
    out.push_back(s);
  }
  return out;
}

namespace {

// ---------------------------------------------------------------------------------------------
// Sequences.

// The room flight: a loop of a 12 x 8 m room at 1.5 - 3 m, flown five times.
void WriteRoomWaypoints(const std::string& path) {
  std::string s = "# x y altitude (m): a EuRoC-like room flight\n";
  const double pts[][3] = {{0, 0, 1.5},  {5, 1, 2.0},  {6, 4, 2.5},   {2, 6, 3.0},
                           {-4, 5, 2.5}, {-6, 1, 2.0}, {-3, -2, 1.8}, {1, -1, 1.6}};
  for (int lap = 0; lap < 5; ++lap)
    for (const auto& p : pts) s += fmt::format("{} {} {}\n", p[0], p[1], p[2]);
  s += "0 0 1.5\n";
  io::WriteFileAtomically(path, s);
}

// The simulation of a sequence (the room's waypoints file: OUT/sequences/room_waypoints.txt,
// written by RenderSequence).
sim::SimulationOptions SequenceOptions(GnssBenchSequence sequence, const GnssBenchOptions& options,
                                       const std::string& dir) {
  sim::SimulationOptions o;
  o.out_dir = dir;
  o.force = true;
  o.scale = options.scale;
  o.seed = 7;
  o.world.kind = sim::WorldKind::kUrban;
  // The road as rendered before 2026-12-06 (`sim --asphalt tiled`), where every recorded figure
  // of this benchmark was measured. Over the varied road the outdoor flight's in-motion start
  // aligns at 16 s instead of 12 (226x144), and a 40 s run aligns no ENU frame (docs/VIO.md,
  // 2026-12-06): re-measuring this benchmark there is open work.
  o.world.varied_asphalt = false;
  // And without the cameras' noise (`sim --camera-noise off`), as every recorded figure of this
  // benchmark was measured; with it (the default since 2026-12-07) its in-motion start takes
  // longer. Re-measuring this benchmark with it is open work.
  o.camera_noise.enabled = false;
  if (sequence == GnssBenchSequence::kRoom) {
    o.route = "drone:" + (fs::path(options.out_dir) / "sequences" / "room_waypoints.txt").string();
    o.speed_m_s = 1.5;
    o.duration_s = 100;
  } else {
    o.route = "drone";
    o.speed_m_s = 5.0;
    o.altitude_m = 10.0;
    o.duration_s = 200;
  }
  if (options.duration_s > 0) o.duration_s = options.duration_s;
  return o;
}

void RenderSequence(const sim::SimulationOptions& o) {
  if (o.route.rfind("drone:", 0) == 0) {
    const std::string wp = o.route.substr(6);
    fs::create_directories(fs::path(wp).parent_path());
    WriteRoomWaypoints(wp);
  }
  sim::RunSimulation(o);
}

// Renders the sequence (unless --reuse finds it complete) and reads its ground truth.
GnssBenchSequenceInfo PrepareSequence(GnssBenchSequence sequence, const GnssBenchOptions& options,
                                      const GnssBenchProgress& progress) {
  GnssBenchSequenceInfo seq;
  seq.sequence = sequence;
  seq.name = GnssBenchSequenceName(sequence);
  seq.dir = (fs::path(options.out_dir) / "sequences" / seq.name).string();
  // Tasks of a planned sweep that share a sequence take turns: the first renders it.
  std::optional<FileLock> lock;
  if (options.task >= 0) {
    fs::create_directories(fs::path(seq.dir).parent_path());
    lock.emplace(seq.dir + ".lock");
  }
  const sim::SimulationOptions sim_options = SequenceOptions(sequence, options, seq.dir);
  // By this renderer version, of these options (--scale, --duration).
  std::string why;
  const bool complete = sim::IsRenderingOf(seq.dir, sim_options, &why);
  if (options.merge && !complete) {
    throw Error(
        "the sequence is not complete or not of these options (merge renders nothing): " + why,
        {.file = seq.dir});
  }
  if (!(options.reuse && complete)) {
    if (progress) {
      const std::string reason = options.reuse ? " (not reused: " + why + ")" : "";
      progress(StringPrintf("bench gnss: rendering the %s sequence -> %s%s", seq.name.c_str(),
                            seq.dir.c_str(), reason.c_str()));
    }
    RenderSequence(sim_options);
    seq.rendered = true;
  }
  const fs::path mav0 = fs::path(seq.dir) / "mav0";
  seq.truth = io::ReadTrajectory((mav0 / "state_groundtruth_estimate0" / "data.csv").string());
  seq.length_m = seq.truth.PathLength();
  seq.outage_start_s = sequence == GnssBenchSequence::kRoom ? 20.0 : 40.0;
  const io::GnssSensorInfo info = io::ReadGnssSensorYaml((mav0 / "gnss0" / "sensor.yaml").string());
  seq.lever_arm_in_body = info.lever_arm_in_body.value_or(Eigen::Vector3d::Zero());
  return seq;
}

// ---------------------------------------------------------------------------------------------
// Run files: <stem>.tum (the estimate as output: ENU when aligned, else the VIO world),
// <stem>.live.tum and <stem>.json (what the VIO run reported), in OUT/runs. Written as each run
// finishes, so that --reuse resumes an interrupted benchmark or adds seeds; the metrics are
// always recomputed.

std::string RunFileStem(const GnssRunResult& r) {
  std::string name = fmt::format("{}_{}_{}_seed{}", r.sequence, ConditionLabel(r.condition),
                                 NormLabel(r.norm), r.seed);
  for (char& ch : name)
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '.' && ch != '_') ch = '_';
  return name;
}

// The fusion settings a GNSS run was made with: a run made with other settings is not reused.
// What runs made before a setting existed did not record is recorded only when not the default,
// so that those runs still match.
nlohmann::json FusionSettings(const vio::GnssFusionOptions& o) {
  nlohmann::json j = {{"factor_sigma_scale", o.factor_sigma_scale},
                      {"alignment_walk_m_per_sqrt_m", o.alignment_walk_m_per_sqrt_m},
                      {"alignment_walk_rad_per_sqrt_m", o.alignment_walk_rad_per_sqrt_m},
                      {"smooth", o.smooth},
                      {"smooth_walk_m_per_sqrt_s", o.smooth_walk_m_per_sqrt_s},
                      {"smooth_walk_rad_per_sqrt_s", o.smooth_walk_rad_per_sqrt_s}};
  const vio::GnssFusionOptions d;
  if (o.smooth_walk_scale != d.smooth_walk_scale) j["smooth_walk_scale"] = o.smooth_walk_scale;
  if (o.time_mode != d.time_mode) j["time_mode"] = vio::GnssTimeModeName(o.time_mode);
  if (o.norm_parameter != d.norm_parameter) j["norm_parameter"] = o.norm_parameter;
  if (o.gate_chi2 != d.gate_chi2) j["gate_chi2"] = o.gate_chi2;
  if (o.init_min_distance_m != d.init_min_distance_m)
    j["init_min_distance_m"] = o.init_min_distance_m;
  if (o.init_max_yaw_sigma_rad != d.init_max_yaw_sigma_rad)
    j["init_max_yaw_sigma_rad"] = o.init_max_yaw_sigma_rad;
  if (o.drift_window_samples != d.drift_window_samples)
    j["drift_window_samples"] = o.drift_window_samples;
  if (o.drift_test_chi2 != d.drift_test_chi2) j["drift_test_chi2"] = o.drift_test_chi2;
  return j;
}

double JsonNumber(const nlohmann::json& j, const char* key) {
  return j.contains(key) && j.at(key).is_number() ? j.at(key).get<double>() : NAN;
}

// Loads a finished run of the same sequence, condition, norm and seed; false if there is none.
bool LoadRun(const fs::path& stem, const vio::GnssFusionOptions& fusion, GnssRunResult* r) {
  const fs::path json_path = stem.string() + ".json", tum_path = stem.string() + ".tum";
  if (!fs::is_regular_file(json_path) || !fs::is_regular_file(tum_path)) return false;
  try {
    const nlohmann::json j = nlohmann::json::parse(io::ReadFileToString(json_path.string()));
    if (j.at("sequence") != r->sequence || j.at("condition") != ConditionLabel(r->condition) ||
        j.at("norm") != NormLabel(r->norm) || j.at("seed") != r->seed)
      throw Error("names another run", {.file = json_path.string()});
    if (r->condition && j.value("gnss_settings", nlohmann::json()) != FusionSettings(fusion))
      throw Error(
          "made with other fusion settings (--gnss-factor-scale, --gnss-walk, "
          "--gnss-smooth-walk-scale, ...)",
          {.file = json_path.string()});
    r->poses = j.at("poses").get<size_t>();
    r->lost = j.at("lost_intervals").get<size_t>();
    r->factors = j.at("factors").get<size_t>();
    r->rejected = j.at("rejected").get<size_t>();
    r->aligned = j.at("enu_aligned").get<bool>();
    r->backend_median_ms = JsonNumber(j, "backend_median_ms");
    r->backend_keyframe_median_ms = JsonNumber(j, "backend_keyframe_median_ms");
    if (j.contains("rejected_samples"))  // runs saved before the HTML report have none
      for (const nlohmann::json& x : j.at("rejected_samples"))
        r->gnss_rejected.emplace_back(x.at(0).get<int64_t>(), x.at(1).get<std::string>());
    r->estimate = io::ReadTrajectory(tum_path.string());
    if (r->aligned && r->condition) r->live = io::ReadTrajectory(stem.string() + ".live.tum");
    return !r->estimate.empty();
  } catch (const std::exception& e) {
    spdlog::warn("bench gnss: not reusing {}: {}", json_path.string(), e.what());
    return false;
  }
}

void SaveRun(const fs::path& stem, const vio::GnssFusionOptions& fusion, const GnssRunResult& r) {
  io::WriteTrajectory(stem.string() + ".tum", r.estimate, io::TrajectoryFormat::kTum);
  if (!r.live.empty())
    io::WriteTrajectory(stem.string() + ".live.tum", r.live, io::TrajectoryFormat::kTum);
  const nlohmann::json j = {{"sequence", r.sequence},
                            {"condition", ConditionLabel(r.condition)},
                            {"norm", NormLabel(r.norm)},
                            {"seed", r.seed},
                            {"poses", r.poses},
                            {"lost_intervals", r.lost},
                            {"factors", r.factors},
                            {"rejected", r.rejected},
                            {"enu_aligned", r.aligned},
                            {"backend_median_ms", r.backend_median_ms},
                            {"backend_keyframe_median_ms", r.backend_keyframe_median_ms},
                            {"gnss_settings", FusionSettings(fusion)},
                            {"rejected_samples", r.gnss_rejected}};
  io::WriteFileAtomically(stem.string() + ".json", j.dump(2) + "\n");
}

// ---------------------------------------------------------------------------------------------
// One run.

// Runs the VIO on the run's condition (none: no GNSS) and fills the run's VIO figures and
// trajectories.
void RunVio(const GnssBenchSequenceInfo& seq, const vio::GnssFusionOptions& fusion,
            GnssRunResult* r) {
  vio::VioRunOptions options;
  options.threaded = false;
  if (r->condition) {
    vio::GnssFusionOptions g = fusion;
    g.norm = *r->norm;
    g.lever_arm_in_body = seq.lever_arm_in_body;
    options.gnss = g;
    options.gnss_samples = MakeConditionGnss(seq.truth, seq.lever_arm_in_body, seq.outage_start_s,
                                             *r->condition, r->seed);
  }
  const vio::VioRunResult v = vio::RunVioOnEuroc(seq.dir, options);
  r->poses = v.estimates.size();
  r->lost = v.lost.size();
  r->factors = v.gnss_stats.factors;
  r->rejected = v.gnss_stats.rejected;
  for (const vio::RejectedGnss& g : v.gnss_rejected)
    r->gnss_rejected.emplace_back(g.t_ns, g.reason);
  if (v.timing.count("backend")) r->backend_median_ms = v.timing.at("backend").median_s * 1e3;
  if (v.timing.count("backend_keyframe"))
    r->backend_keyframe_median_ms = v.timing.at("backend_keyframe").median_s * 1e3;
  Trajectory est = r->condition
                       ? vio::EstimatesToEnuTrajectory(v.estimates, v.gnss_smoothing.enu_from_world)
                       : Trajectory();
  if (r->condition) r->live = vio::EstimatesToEnuTrajectory(v.estimates);
  // Without an ENU alignment (too little motion for the GNSS noise to fix the yaw) the output
  // stays in the VIO world frame, as `optinav vio --gnss` writes it: its ATE counts, it has no
  // global error.
  r->aligned = !est.empty();
  if (est.empty()) est = vio::EstimatesToTrajectory(v.estimates);
  if (est.empty()) throw Error("no pose estimated");
  r->estimate = est;
}

using ErrorSeries = std::vector<std::pair<double, double>>;

double AteSe3(const eval::SyncedPair& synced) {
  Trajectory aligned = synced.est;
  eval::AlignmentOptions a;
  a.mode = eval::AlignMode::kSe3;
  eval::AlignTrajectory(synced.ref, &aligned, a);
  return eval::ComputeStatistics(
             eval::ComputeApe(synced.ref, aligned, eval::PoseRelation::kTranslation).errors)
      .rmse;
}

// Position error over time (s from t0_ns, m), no alignment.
ErrorSeries ErrorOverTime(const Trajectory& ref, const Trajectory& est, int64_t t0_ns) {
  const eval::ErrorSeries e = eval::ComputeApe(ref, est, eval::PoseRelation::kTranslation);
  ErrorSeries series;
  for (size_t i = 0; i < e.errors.size(); ++i)
    series.emplace_back((ref.t_ns[e.indices[i]] - t0_ns) * 1e-9, e.errors[i]);
  return series;
}

// RMSE of a series from t_from s on (NaN when empty).
double RmseFrom(const ErrorSeries& series, double t_from) {
  double sse = 0;
  size_t n = 0;
  for (const auto& [t, err] : series)
    if (t >= t_from) sse += err * err, ++n;
  return n ? std::sqrt(sse / n) : NAN;
}

// The first error at or after t (NaN when none).
double ErrorAtTime(const ErrorSeries& series, double t) {
  for (const auto& [ts, e] : series)
    if (ts >= t) return e;
  return NAN;
}

// The outage window of the run's condition, s after the truth's start; nullopt without one.
std::optional<std::pair<double, double>> OutageWindow(const GnssBenchSequenceInfo& seq,
                                                      const GnssRunResult& r) {
  if (!r.condition || !(ConditionSpec(*r.condition).outage_s > 0)) return std::nullopt;
  return std::pair{seq.outage_start_s, seq.outage_start_s + ConditionSpec(*r.condition).outage_s};
}

void EvaluateLive(const GnssBenchSequenceInfo& seq, GnssRunResult* r) {
  const eval::SyncedPair live = eval::Synchronize(seq.truth, r->live);
  r->ate_se3_live = AteSe3(live);
  r->live_error_over_time = ErrorOverTime(live.ref, live.est, seq.truth.t_ns.front());
  const ErrorSeries& series = r->live_error_over_time;
  r->global_rmse_live = RmseFrom(series, -INFINITY);
  if (const auto window = OutageWindow(seq, *r)) {
    const auto [ts, te] = *window;
    r->outage_growth_live = ErrorAtTime(series, te) - ErrorAtTime(series, ts);
    r->err_10s_after_live = ErrorAtTime(series, te + 10.0);
  }
}

// The outage's figures from the run's global error; the VIO alone's drift over the same window.
void EvaluateOutage(const GnssBenchSequenceInfo& seq, const Trajectory* vio_alone, double ts,
                    double te, GnssRunResult* r) {
  r->outage_start_err = ErrorAtTime(r->error_over_time, ts);
  r->outage_end_err = ErrorAtTime(r->error_over_time, te);
  r->err_10s_after = ErrorAtTime(r->error_over_time, te + 10.0);
  for (const auto& [t, err] : r->error_over_time)
    if (t >= te && err < 1.5) {
      r->recovery_s = t - te;
      break;
    }
  if (!vio_alone || vio_alone->empty()) return;
  // VIO alone over the same interval: its pose at the outage start put on the truth's.
  const int64_t t0 = seq.truth.t_ns.front();
  const auto a0 = vio_alone->InterpolateAt(t0 + static_cast<int64_t>(ts * 1e9));
  const auto a1 = vio_alone->InterpolateAt(t0 + static_cast<int64_t>(te * 1e9));
  const auto g0 = seq.truth.InterpolateAt(t0 + static_cast<int64_t>(ts * 1e9));
  const auto g1 = seq.truth.InterpolateAt(t0 + static_cast<int64_t>(te * 1e9));
  if (a0 && a1 && g0 && g1)
    r->vio_drift_over_outage = ((*g0 * a0->Inverse() * *a1).translation - g1->translation).norm();
}

// The run's error figures from its trajectories.
void Evaluate(const GnssBenchSequenceInfo& seq, const Trajectory* vio_alone, GnssRunResult* r) {
  if (!r->live.empty()) EvaluateLive(seq, r);
  const eval::SyncedPair synced = eval::Synchronize(seq.truth, r->estimate);
  r->ate_se3 = AteSe3(synced);
  r->ok = true;
  if (r->condition && !r->aligned) return;  // no global error in the world frame
  Trajectory global = synced.est;
  if (!r->condition) {  // no ENU frame: SE(3) alignment on the first 5 s only
    r->aligned = false;
    eval::AlignmentOptions a;
    a.mode = eval::AlignMode::kSe3;
    for (size_t i = 0; i < synced.est.size(); ++i)
      if (synced.est.t_ns[i] - synced.est.t_ns[0] <= 5'000'000'000) a.n_to_align = i + 1;
    eval::AlignTrajectory(synced.ref, &global, a);
  }
  r->error_over_time = ErrorOverTime(synced.ref, global, seq.truth.t_ns.front());
  r->global = global;
  r->global_rmse = RmseFrom(r->error_over_time, -INFINITY);
  r->global_rmse_10s = RmseFrom(r->error_over_time, 10.0);
  if (const auto window = OutageWindow(seq, *r))
    EvaluateOutage(seq, vio_alone, window->first, window->second, r);
}

// Runs the VIO on a condition (none: no GNSS), or reuses the run's files, and evaluates it. A
// failure is recorded in the result.
GnssRunResult RunOne(const GnssBenchSequenceInfo& seq, std::optional<GnssCondition> condition,
                     std::optional<vio::GnssNorm> norm, int seed, const Trajectory* vio_alone,
                     const GnssBenchOptions& options) {
  GnssRunResult r;
  r.sequence = seq.name;
  r.condition = condition;
  r.norm = condition ? norm : std::nullopt;
  r.seed = seed;
  const fs::path stem = fs::path(options.out_dir) / "runs" / RunFileStem(r);
  r.reused = options.reuse && !seq.rendered && LoadRun(stem, options.fusion, &r);
  if (options.merge && !r.reused)
    throw Error("no finished run to merge (merge runs nothing)", {.file = stem.string() + ".json"});
  try {
    if (!r.reused) {
      RunVio(seq, options.fusion, &r);
      SaveRun(stem, options.fusion, r);
      // Evaluated from the files, as a reused run is: a merge gives the same figures, to the bit.
      r.estimate = io::ReadTrajectory(stem.string() + ".tum");
      if (!r.live.empty()) r.live = io::ReadTrajectory(stem.string() + ".live.tum");
    }
    Evaluate(seq, vio_alone, &r);
  } catch (const std::exception& ex) {
    r.error = ex.what();
  }
  return r;
}

// ---------------------------------------------------------------------------------------------
// The driver.

struct Job {
  const GnssBenchSequenceInfo* seq;
  GnssCondition condition;
  vio::GnssNorm norm;
  int seed;
};

std::string RunLine(const GnssRunResult& r, size_t done, size_t total) {
  return StringPrintf(
      "bench gnss: [%zu/%zu] %s, %s, %s, seed %d: %s%s", done, total, r.sequence.c_str(),
      ConditionLabel(r.condition).c_str(), NormLabel(r.norm).c_str(), r.seed,
      r.reused ? "(reused) " : "",
      r.ok ? fmt::format("ATE {:.3f} m, global {:.3f} m", r.ate_se3, r.global_rmse).c_str()
           : ("failed: " + r.error).c_str());
}

// Every job on `options.jobs` threads; results in the order of `todo`.
std::vector<GnssRunResult> RunJobs(const std::vector<Job>& todo,
                                   const std::map<std::string, Trajectory>& alone,
                                   const GnssBenchOptions& options,
                                   const GnssBenchProgress& progress) {
  std::vector<GnssRunResult> results(todo.size());
  std::atomic<size_t> next{0};
  size_t done = 0;
  std::mutex print;
  const auto worker = [&] {
    for (size_t i; (i = next++) < todo.size();) {
      const Job& j = todo[i];
      results[i] = RunOne(*j.seq, j.condition, j.norm, j.seed, &alone.at(j.seq->name), options);
      std::lock_guard lock(print);
      ++done;
      if (progress) progress(RunLine(results[i], done, todo.size()));
    }
  };
  std::vector<std::thread> threads;
  for (int k = 0; k < options.jobs; ++k) threads.emplace_back(worker);
  for (std::thread& t : threads) t.join();
  return results;
}

void WriteResults(const GnssBenchOptions& options, const GnssBenchResult& result) {
  const fs::path out = options.out_dir;
  io::WriteFileAtomically((out / "results.csv").string(), internal::GnssBenchCsv(result.runs));
  io::WriteFileAtomically(
      (out / "results.json").string(),
      internal::GnssBenchJson(result.sequences, result.runs, result.never_worse).dump(2) + "\n");
  io::WriteFileAtomically((out / "tables.md").string(), result.tables);
  for (const GnssBenchSequenceInfo& s : result.sequences)
    internal::WriteGnssErrorPlot((out / ("error_" + s.name + ".svg")).string(), result.runs, s);
  nlohmann::json settings = {{"seeds", options.seeds},
                             {"scale", options.scale},
                             {"duration_s", options.duration_s},
                             {"jobs", options.jobs},
                             {"fusion", FusionSettings(options.fusion)}};
  for (GnssBenchSequence q : options.sequences)
    settings["sequences"].push_back(GnssBenchSequenceName(q));
  for (GnssCondition c : options.conditions) settings["conditions"].push_back(ConditionSpec(c).key);
  for (vio::GnssNorm n : options.norms) settings["norms"].push_back(NormLabel(n));
  internal::WriteGnssBenchReportDocument(ReportDocumentPath(options.out_dir), result.sequences,
                                         result.runs, settings, result.tables);
}

}  // namespace

namespace {

// The runs in RunGnssBench's order: per sequence the VIO alone, then sequence x condition x norm x
// seed. sequence: index into options.sequences.
struct PlannedRun {
  size_t sequence;
  std::optional<GnssCondition> condition;
  std::optional<vio::GnssNorm> norm;
  int seed;
};

std::vector<PlannedRun> PlannedRuns(const GnssBenchOptions& o) {
  std::vector<PlannedRun> out;
  for (size_t s = 0; s < o.sequences.size(); ++s) out.push_back({s, std::nullopt, std::nullopt, 0});
  for (size_t s = 0; s < o.sequences.size(); ++s)
    for (GnssCondition c : o.conditions)
      for (vio::GnssNorm n : o.norms)
        for (int seed = 1; seed <= o.seeds; ++seed) out.push_back({s, c, n, seed});
  return out;
}

void ThrowIfInvalid(const GnssBenchOptions& options) {
  if (const std::string e = options.Check(); !e.empty()) {
    const size_t space = e.find(' ');  // the message starts with the flag at fault
    throw Error(e.substr(space + 1), {.field = e.substr(0, space)});
  }
}

}  // namespace

std::vector<PlannedTask> GnssBenchTasks(const GnssBenchOptions& options) {
  std::vector<PlannedTask> out;
  for (const PlannedRun& p : PlannedRuns(options)) {
    GnssRunResult r;
    r.sequence = GnssBenchSequenceName(options.sequences[p.sequence]);
    r.condition = p.condition;
    r.norm = p.norm;
    r.seed = p.seed;
    const std::string stem = (fs::path(options.out_dir) / "runs" / RunFileStem(r)).string();
    out.push_back({fmt::format("{}, {}, {}, seed {}", r.sequence, ConditionLabel(r.condition),
                               NormLabel(r.norm), r.seed),
                   {stem + ".tum", stem + ".json"}});
  }
  return out;
}

SlurmResources GnssBenchTaskResources(const GnssBenchOptions& o) {
  // Measured on the 2-core VM (bench/RESULTS.md, "Slurm", 2026-11-26), the drone camera's
  // 752x480 (0.361 Mpx) at 20 Hz, 20 s of the room: rendering 127 ms per frame (done by the first
  // task that needs the sequence), the unthreaded VIO 61 ms; peak memory 121 MB. Per frame
  // 0.01 s + 0.52 s/Mpx covers both. Asked: 512 MB + 256 MB/Mpx; time 3x, 10 min at least.
  const double megapixels = 0.361 * o.scale * o.scale;
  double seconds = 0;
  for (GnssBenchSequence s : o.sequences)
    seconds = std::max(seconds, o.duration_s > 0                ? o.duration_s
                                : s == GnssBenchSequence::kRoom ? 100.0
                                                                : 200.0);
  const double frames = seconds * 20;
  const double estimate_s = frames * (0.01 + 0.52 * megapixels);
  return BenchTaskResources(
      1, megapixels, estimate_s,
      fmt::format("1 CPU (unthreaded VIO); memory 512 MB + 256 MB/Mpx (measured peak ~120 MB); "
                  "time 3 x {:.0f} frames x (0.01 + 0.52 s/Mpx at {:.3f} Mpx) = 3 x {:.0f} s "
                  "(rendering and VIO), 10 min at least",
                  frames, megapixels, estimate_s));
}

GnssBenchResult RunGnssBench(const GnssBenchOptions& options, const GnssBenchProgress& progress) {
  ThrowIfInvalid(options);
  if (options.merge) {
    const std::optional<SlurmPlan> plan = ReadSlurmPlan(options.out_dir);
    if (!plan)
      throw Error("no Slurm plan to merge (plan.json; made by --plan slurm)",
                  {.file = options.out_dir});
    ThrowIfUnfinished(*plan);
  }
  if (options.html) report::LoadLeafletAssets();  // missing: say so before the runs, not after
  fs::create_directories(fs::path(options.out_dir) / "runs");
  if (options.task >= 0) {  // one task of a planned sweep: its run files, no tables
    const std::vector<PlannedRun> runs = PlannedRuns(options);
    if (static_cast<size_t>(options.task) >= runs.size())
      throw Error(fmt::format("task {} does not exist (the plan has {} tasks: 0-{})", options.task,
                              runs.size(), runs.size() - 1),
                  {.field = "--task"});
    const PlannedRun& p = runs[options.task];
    GnssBenchResult result;
    result.sequences.push_back(PrepareSequence(options.sequences[p.sequence], options, progress));
    result.runs.push_back(
        RunOne(result.sequences[0], p.condition, p.norm, p.seed, nullptr, options));
    const GnssRunResult& r = result.runs[0];
    if (!r.ok) throw Error("task " + std::to_string(options.task) + " failed: " + r.error);
    if (progress) progress(RunLine(r, 1, 1));
    return result;
  }
  GnssBenchResult result;
  for (GnssBenchSequence s : options.sequences)
    result.sequences.push_back(PrepareSequence(s, options, progress));

  // VIO alone first (the reference of every row), then every condition x norm x seed.
  std::map<std::string, Trajectory> alone;
  for (const GnssBenchSequenceInfo& s : result.sequences) {
    result.runs.push_back(RunOne(s, std::nullopt, std::nullopt, 0, nullptr, options));
    const GnssRunResult& r = result.runs.back();
    if (!r.ok) throw Error("VIO alone failed: " + r.error, {.file = s.dir});
    if (progress)
      progress(StringPrintf(
          "bench gnss: %s (%.0f m): VIO alone ATE %.3f m, global (first 5 s aligned) %.3f m, %zu "
          "lost interval(s)",
          s.name.c_str(), s.length_m, r.ate_se3, r.global_rmse, r.lost));
    alone[s.name] = r.estimate;
  }
  std::vector<Job> todo;
  for (const GnssBenchSequenceInfo& s : result.sequences)
    for (GnssCondition c : options.conditions)
      for (vio::GnssNorm n : options.norms)
        for (int seed = 1; seed <= options.seeds; ++seed) todo.push_back({&s, c, n, seed});
  const std::vector<GnssRunResult> fused = RunJobs(todo, alone, options, progress);
  result.runs.insert(result.runs.end(), fused.begin(), fused.end());

  result.tables = internal::GnssBenchTables(result.sequences, options.conditions, options.norms,
                                            result.runs, &result.never_worse);
  WriteResults(options, result);
  if (options.html) result.html = WriteHtmlReport(options.out_dir);
  return result;
}

}  // namespace optinav::app
