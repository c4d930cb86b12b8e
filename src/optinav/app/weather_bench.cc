#include "optinav/app/weather_bench.h"

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <mutex>
#include <optional>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "optinav/app/internal/weather_bench_report.h"
#include "optinav/app/vio_run.h"
#include "optinav/eval/metrics.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/report/html_report.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/error.h"
#include "optinav/util/file_lock.h"
#include "optinav/util/timer.h"

namespace fs = std::filesystem;

namespace optinav::app {
namespace {

bool IsRoad(const sim::WeatherSpec& w) {
  return w.kind == sim::WeatherKind::kRoadWetness || w.kind == sim::WeatherKind::kRoadSnow ||
         w.kind == sim::WeatherKind::kRoadLeaves;
}

bool SameCondition(const sim::WeatherSpec& a, const sim::WeatherSpec& b) {
  return a.ToString() == b.ToString();
}

// The document's figures (SEEDS.md part 1, "Results (mean error, m; urban / terrain)"): ORB-SLAM3
// stereo on the AirSim weather dataset, 800x600. Rain, snow and falling leaves have one figure
// each, which the suite renders at 50 % (sim::WeatherSuite()); fog and dust have four levels.
// NAN with lost = true: "local map lost" (terrain, dust 75 and 100 %).
struct DocumentRow {
  sim::WorldKind world;
  const char* condition;  // as sim::WeatherSpec::ToString() writes it
  double mean_error_m;
  bool lost;
};
constexpr DocumentRow kDocument[] = {
    {sim::WorldKind::kUrban, "none", 1.71, false},
    {sim::WorldKind::kUrban, "rain:50", 1.94, false},
    {sim::WorldKind::kUrban, "snow:50", 2.38, false},
    {sim::WorldKind::kUrban, "leaves:50", 1.65, false},
    {sim::WorldKind::kUrban, "fog:25", 2.05, false},
    {sim::WorldKind::kUrban, "fog:50", 1.70, false},
    {sim::WorldKind::kUrban, "fog:75", 1.54, false},
    {sim::WorldKind::kUrban, "fog:100", 3.76, false},
    {sim::WorldKind::kUrban, "dust:25", 1.28, false},
    {sim::WorldKind::kUrban, "dust:50", 1.84, false},
    {sim::WorldKind::kUrban, "dust:75", 1.97, false},
    {sim::WorldKind::kUrban, "dust:100", 2.68, false},
    {sim::WorldKind::kTerrain, "none", 20.93, false},
    {sim::WorldKind::kTerrain, "rain:50", 13.03, false},
    {sim::WorldKind::kTerrain, "snow:50", 357.86, false},
    {sim::WorldKind::kTerrain, "leaves:50", 49.37, false},
    {sim::WorldKind::kTerrain, "fog:25", 17.3, false},
    {sim::WorldKind::kTerrain, "fog:50", 78.15, false},
    {sim::WorldKind::kTerrain, "fog:75", 106.38, false},
    {sim::WorldKind::kTerrain, "fog:100", 140.83, false},
    {sim::WorldKind::kTerrain, "dust:25", 18.73, false},
    {sim::WorldKind::kTerrain, "dust:50", 29.67, false},
    {sim::WorldKind::kTerrain, "dust:75", NAN, true},
    {sim::WorldKind::kTerrain, "dust:100", NAN, true},
};

// One rendered sequence and the runs made on it.
struct Sequence {
  sim::WorldKind world;
  sim::WeatherSpec condition;
  int seed;
  std::string name, dir;
};

// The suite's name when the condition is one of the suite's ("urban_default", "urban_fog_50"),
// else world_kind_level ("urban_fog_30").
std::string SequenceName(sim::WorldKind world, const sim::WeatherSpec& condition) {
  for (const sim::SuiteEntry& e : sim::WeatherSuite())
    if (e.world == world && SameCondition(e.weather, condition)) return e.name;
  std::string name = WeatherBenchWorldName(world) + "_" + condition.ToString();
  std::replace(name.begin(), name.end(), ':', '_');
  std::replace(name.begin(), name.end(), '-', '_');
  return name;
}

std::vector<Sequence> ListSequences(const WeatherBenchOptions& o) {
  // A shortened route renders into its own folder: the markers do not say what was asked.
  const std::string folder =
      o.duration_s > 0 ? fmt::format("seed{{}}_{:g}s", o.duration_s) : "seed{}";
  std::vector<Sequence> out;
  for (int seed = 1; seed <= o.seeds; ++seed) {
    for (sim::WorldKind w : o.worlds) {
      for (const sim::WeatherSpec& c : o.conditions.empty() ? SuiteConditions(w) : o.conditions) {
        if (IsRoad(c) && w != sim::WorldKind::kUrban) continue;  // road effects: urban only
        Sequence s{w, c, seed, SequenceName(w, c), ""};
        s.dir =
            (fs::path(o.out_dir) / "sequences" / fmt::format(fmt::runtime(folder), seed) / s.name)
                .string();
        out.push_back(s);
      }
    }
  }
  return out;
}

// Whether the sequences of `world` have the varied asphalt (only the urban world has roads).
bool VariedAsphalt(sim::WorldKind world, const WeatherBenchOptions& o) {
  return o.varied_asphalt && world == sim::WorldKind::kUrban;
}

sim::SimulationOptions SimOptions(const Sequence& s, const WeatherBenchOptions& o) {
  sim::SimulationOptions so;
  so.world.kind = s.world;
  so.weather = s.condition;
  so.route = "car";
  so.seed = static_cast<uint64_t>(s.seed);
  so.scale = o.scale;
  so.duration_s = o.duration_s;
  so.world.varied_asphalt = VariedAsphalt(s.world, o);
  so.camera_noise = o.camera_noise;
  so.format = sim::DatasetFormat::kEuroc;
  so.out_dir = s.dir;
  so.force = true;
  return so;
}

// True when the folder holds a complete rendering of these options (sim::IsRenderingOf: the
// completion marker, written last, names the same world, weather, seed, scale, duration and
// asphalt, with moving particles, by this renderer version).
bool CompleteRendering(const Sequence& s, const WeatherBenchOptions& o) {
  std::string why;
  if (sim::IsRenderingOf(s.dir, SimOptions(s, o), &why)) return true;
  if (fs::exists(fs::path(s.dir) / "sim_complete.json"))
    spdlog::info("bench weather: not reusing {}: {}", s.dir, why);
  return false;
}

// ---------------------------------------------------------------------------------------------
// Run files, OUT/runs/<stem>: .tum (the output), .odometry.tum (before loop closure),
// .stats.json (`optinav vio --stats`) and .json (this benchmark's record, written last: a run
// without it is not finished). The errors are always recomputed from the trajectories.

std::string RunStem(const Sequence& s, vio::VioMode mode) {
  return fmt::format("{}_{}_seed{}", s.name, vio::VioModeName(mode), s.seed);
}

// The settings `optinav vio --mode MODE` (threaded) gets for sequence `s`.
VioRunSettings RunSettings(const Sequence& s, const std::string& stem, const WeatherBenchOptions& o,
                           vio::VioMode mode) {
  VioRunSettings st;
  st.dataset = s.dir;
  st.mode = mode;
  st.config_path = o.vio_config;
  st.vehicle = o.vehicle;
  st.max_frames = o.max_frames;
  st.out = stem + ".tum";
  st.odometry_out = stem + ".odometry.tum";
  st.stats_path = stem + ".stats.json";
  return st;
}

// `config_text`: the text of --config ("" without one), read once per bench; `options_yaml`:
// every option of the run (EffectiveVioOptionsYaml), so that a binary with other defaults
// does not reuse the runs of an older one.
nlohmann::json RunRecord(const WeatherRunResult& r, const WeatherBenchOptions& o,
                         const std::string& config_text, const std::string& options_yaml) {
  nlohmann::json lost = nlohmann::json::array();
  for (const WeatherLost& l : r.lost)
    lost.push_back({{"start_s", l.start_s}, {"end_s", l.end_s}, {"reason", l.reason}});
  return {{"sequence", r.sequence},
          {"mode", vio::VioModeName(r.mode)},
          {"seed", r.seed},
          {"scale", o.scale},
          {"duration_s", o.duration_s},
          {"max_frames", o.max_frames},
          {"vio_config", config_text},
          {"vehicle_setting", VehicleModelName(o.vehicle)},
          {"asphalt", sim::AsphaltName(VariedAsphalt(r.world, o))},
          {"camera_noise", o.camera_noise.ToString()},
          {"vio_options_yaml", options_yaml},
          {"vehicle", r.vehicle},
          {"wall_s", r.wall_s},
          {"fps", r.fps},
          {"frames", r.frames},
          {"poses", r.poses},
          {"loops", r.loops},
          {"frame_median_ms", r.frame_median_ms},
          {"frame_p95_ms", r.frame_p95_ms},
          {"lost_intervals", lost}};
}

double Number(const nlohmann::json& j, const char* key) {
  return j.contains(key) && j.at(key).is_number() ? j.at(key).get<double>() : NAN;
}

// A finished run of the same sequence, mode, seed and settings; false when there is none.
bool LoadRun(const std::string& stem, const WeatherBenchOptions& o, const std::string& config_text,
             const std::string& options_yaml, WeatherRunResult* r) {
  const std::string path = stem + ".json";
  if (!fs::is_regular_file(path) || !fs::is_regular_file(stem + ".tum")) return false;
  try {
    const nlohmann::json j = nlohmann::json::parse(io::ReadFileToString(path));
    nlohmann::json expect = RunRecord(*r, o, config_text, options_yaml);
    for (const char* key : {"sequence", "mode", "seed", "scale", "duration_s", "max_frames"})
      if (j.at(key) != expect.at(key))
        throw Error(fmt::format("made with another {}", key), {.file = path});
    if (j.value("vio_config", std::string()) != config_text)
      throw Error("made with another --config", {.file = path});
    if (j.value("asphalt", std::string("tiled")) != expect.at("asphalt"))
      throw Error("made on another --asphalt", {.file = path});
    // Runs recorded before the camera noise (2026-12-07) ran on noise-free renderings.
    if (j.value("camera_noise", std::string("off")) != expect.at("camera_noise"))
      throw Error("made on another --camera-noise", {.file = path});
    if (j.value("vehicle_setting", std::string()) != VehicleModelName(o.vehicle))
      throw Error("made with another --vehicle (or before the setting)", {.file = path});
    if (j.value("vio_options_yaml", std::string()) != options_yaml)
      throw Error(
          "made with other VIO options (a binary with other defaults, or before the record "
          "kept them)",
          {.file = path});
    r->vehicle = j.value("vehicle", std::string());
    r->wall_s = Number(j, "wall_s");
    r->fps = Number(j, "fps");
    r->frame_median_ms = Number(j, "frame_median_ms");
    r->frame_p95_ms = Number(j, "frame_p95_ms");
    r->frames = j.at("frames").get<size_t>();
    r->poses = j.at("poses").get<size_t>();
    r->loops = j.at("loops").get<size_t>();
    for (const nlohmann::json& l : j.at("lost_intervals"))
      r->lost.push_back({l.at("start_s").get<double>(), l.at("end_s").get<double>(),
                         l.at("reason").get<std::string>()});
    return true;
  } catch (const std::exception& e) {
    spdlog::warn("bench weather: not reusing {}: {}", path, e.what());
    r->lost.clear();
    return false;
  }
}

// Runs the VIO with `st` (RunSettings) and records its figures.
void RunVio(const VioRunSettings& st, const std::string& stem, const WeatherBenchOptions& o,
            const std::string& config_text, int64_t t0_ns, WeatherRunResult* r) {
  fs::remove(stem + ".json");  // an earlier record must not outlive a run that fails now
  const Timer timer;
  const VioRunReport report = RunVioDataset(st);
  r->wall_s = timer.ElapsedSeconds();
  const vio::VioRunResult& v = report.run;
  r->frames = v.frames_processed;
  r->fps = v.frames_processed / r->wall_s;
  r->poses = v.estimates.size();
  r->loops = v.loops.size();
  r->vehicle = report.vehicle;
  if (v.timing.count("total")) {
    r->frame_median_ms = v.timing.at("total").median_s * 1e3;
    r->frame_p95_ms = v.timing.at("total").p95_s * 1e3;
  }
  for (const vio::LostInterval& l : v.lost)
    r->lost.push_back({(l.start_ns - t0_ns) * 1e-9, (l.end_ns - t0_ns) * 1e-9, l.reason});
  io::WriteFileAtomically(stem + ".json",
                          RunRecord(*r, o, config_text, report.vio_options_yaml).dump(2) + "\n");
}

// NaN when the SE(3) fit is undetermined (a straight stretch of route: the roll about it).
double AteSe3(const eval::SyncedPair& synced) {
  Trajectory aligned = synced.est;
  try {
    eval::AlignTrajectory(synced.ref, &aligned, {.mode = eval::AlignMode::kSe3});
  } catch (const Error& e) {
    spdlog::warn("bench weather: no APE after SE(3): {}", e.what());
    return NAN;
  }
  return eval::ComputeApe(synced.ref, aligned, eval::PoseRelation::kTranslation).stats.rmse;
}

}  // namespace

std::pair<size_t, size_t> LoopsOffTruth(const Trajectory& truth, const nlohmann::json& loops,
                                        double tolerance_m) {
  size_t checked = 0, off = 0;
  if (truth.empty() || !truth.has_timestamps()) return {0, 0};
  auto at = [&](const nlohmann::json& t_s) {
    return truth.InterpolateAt(static_cast<int64_t>(std::llround(t_s.get<double>() * 1e9)));
  };
  for (const nlohmann::json& l : loops) {
    if (!l.contains("old_body_from_new_body")) continue;
    const std::vector<double> v = l.at("old_body_from_new_body").get<std::vector<double>>();
    const std::optional<Rigid3d> old_pose = at(l.at("old_keyframe_s"));
    const std::optional<Rigid3d> new_pose = at(l.at("new_keyframe_s"));
    if (v.size() != 7 || !old_pose || !new_pose) continue;
    const Rigid3d truth_old_from_new = old_pose->Inverse() * *new_pose;
    ++checked;
    if ((Eigen::Vector3d(v[0], v[1], v[2]) - truth_old_from_new.translation).norm() > tolerance_m)
      ++off;
  }
  return {checked, off};
}

namespace {

void Evaluate(const Trajectory& truth, const std::string& stem, WeatherRunResult* r) {
  const eval::SyncedPair synced = eval::Synchronize(truth, io::ReadTrajectory(stem + ".tum"));
  r->mean_error_m = eval::MeanErrorAfterStartPose(synced.ref, synced.est);
  r->truth = synced.ref;
  r->aligned = synced.est;
  eval::AlignTrajectory(synced.ref, &r->aligned,
                        {.mode = eval::AlignMode::kNone, .align_origin = true});
  const eval::ErrorSeries e =
      eval::ComputeApe(synced.ref, r->aligned, eval::PoseRelation::kTranslation);
  for (size_t i = 0; i < e.errors.size(); ++i)
    r->error_over_time.emplace_back((synced.ref.t_ns[e.indices[i]] - truth.t_ns.front()) * 1e-9,
                                    e.errors[i]);
  r->ape_rmse_se3_m = AteSe3(synced);
  // The truth is at the IMU rate: the frames it covers are the estimate's possible poses.
  r->coverage = r->frames ? static_cast<double>(synced.est.size()) / r->frames : NAN;
  if (fs::is_regular_file(stem + ".stats.json")) {
    const nlohmann::json stats = nlohmann::json::parse(io::ReadFileToString(stem + ".stats.json"));
    if (stats.contains("loops"))
      std::tie(r->loops_checked, r->loops_off_truth) = LoopsOffTruth(truth, stats.at("loops"));
  }
  r->odometry_mean_error_m = r->mean_error_m;
  if (fs::is_regular_file(stem + ".odometry.tum")) {
    const eval::SyncedPair odo =
        eval::Synchronize(truth, io::ReadTrajectory(stem + ".odometry.tum"));
    r->odometry_mean_error_m = eval::MeanErrorAfterStartPose(odo.ref, odo.est);
  }
  r->ok = true;
}

std::string RunLine(const WeatherRunResult& r, size_t done, size_t total) {
  std::string figures = "failed: " + r.error;
  if (r.ok) {
    figures = fmt::format(
        "mean error {:.2f} m (odometry {:.2f} m), APE SE(3) {:.2f} m, {}, {} loop(s){}, {:.1f} "
        "fps",
        r.mean_error_m, r.odometry_mean_error_m, r.ape_rmse_se3_m,
        r.Lost() ? fmt::format("LOST ({} interval(s))", r.lost.size()) : "not lost", r.loops,
        r.loops_checked ? fmt::format(" ({} off the truth by > 1 m)", r.loops_off_truth) : "",
        r.fps);
  }
  return fmt::format("bench weather: [{}/{}] {}, {}, seed {}: {}{}", done, total, r.sequence,
                     vio::VioModeName(r.mode), r.seed, r.reused ? "(reused) " : "", figures);
}

// ---------------------------------------------------------------------------------------------
// The driver.

struct Shared {
  const WeatherBenchOptions& options;
  const WeatherBenchProgress& progress;
  std::string vio_config_text;  // of options.vio_config ("" without one), recorded with each run
  std::mutex mutex;             // progress lines and their counter
  size_t done = 0, total = 0;
  void Say(const std::string& line) {
    std::lock_guard lock(mutex);
    if (progress) progress(line);
  }
};

// Renders the sequence unless --reuse finds it complete; true when it was rendered now.
bool Prepare(const Sequence& s, Shared* sh) {
  // Tasks of a planned sweep that share a sequence take turns: the first renders it.
  std::optional<FileLock> lock;
  if (sh->options.task >= 0) {
    fs::create_directories(fs::path(s.dir).parent_path());
    lock.emplace(s.dir + ".lock");
  }
  if (sh->options.reuse && CompleteRendering(s, sh->options)) return false;
  if (sh->options.merge)
    throw Error("the sequence is not complete (merge renders nothing)", {.file = s.dir});
  sh->Say(fmt::format("bench weather: rendering {} (seed {}) -> {}", s.name, s.seed, s.dir));
  const sim::SimulationSummary sum = sim::RunSimulation(SimOptions(s, sh->options));
  sh->Say(fmt::format("bench weather: rendered {}: {} stereo frames {}x{}, {:.0f} m, {:.1f} s",
                      s.name, sum.frames, sum.width, sum.height, sum.path_length_m, sum.wall_s));
  return true;
}

// The modes on one sequence (rendered first; all of the options' unless `modes`); results in
// the order of the modes.
std::vector<WeatherRunResult> RunSequence(const Sequence& s, Shared* sh,
                                          const std::vector<vio::VioMode>* modes = nullptr) {
  const WeatherBenchOptions& o = sh->options;
  const bool rendered = Prepare(s, sh);
  const Trajectory truth = io::ReadTrajectory(
      (fs::path(s.dir) / "mav0" / "state_groundtruth_estimate0" / "data.csv").string());
  std::vector<WeatherRunResult> out;
  for (vio::VioMode mode : modes ? *modes : o.modes) {
    WeatherRunResult r;
    r.sequence = s.name;
    r.world = s.world;
    r.condition = s.condition;
    r.mode = mode;
    r.seed = s.seed;
    r.path_length_m = truth.PathLength();
    const std::string stem = (fs::path(o.out_dir) / "runs" / RunStem(s, mode)).string();
    const VioRunSettings st = RunSettings(s, stem, o, mode);
    // A run is only as current as its sequence: a fresh rendering is run again.
    r.reused = o.reuse && !rendered &&
               LoadRun(stem, o, sh->vio_config_text, EffectiveVioOptionsYaml(st), &r);
    if (o.merge && !r.reused)
      throw Error("no finished run to merge (merge runs nothing)", {.file = stem + ".json"});
    try {
      if (!r.reused) RunVio(st, stem, o, sh->vio_config_text, truth.t_ns.front(), &r);
      Evaluate(truth, stem, &r);
    } catch (const std::exception& e) {
      r.ok = false;
      r.error = e.what();
    }
    {
      std::lock_guard lock(sh->mutex);
      ++sh->done;
      if (sh->progress) sh->progress(RunLine(r, sh->done, sh->total));
    }
    out.push_back(std::move(r));
  }
  return out;
}

void ThrowIfInvalid(const WeatherBenchOptions& o) {
  if (const std::string e = o.Check(); !e.empty()) {
    const size_t space = e.find(' ');  // the message starts with the flag at fault
    throw Error(e.substr(space + 1), {.field = e.substr(0, space)});
  }
}

}  // namespace

std::optional<sim::WorldKind> ParseWeatherBenchWorld(const std::string& name) {
  if (name == "urban") return sim::WorldKind::kUrban;
  if (name == "terrain") return sim::WorldKind::kTerrain;
  return std::nullopt;
}

std::string WeatherBenchWorldName(sim::WorldKind world) {
  return world == sim::WorldKind::kUrban     ? "urban"
         : world == sim::WorldKind::kTerrain ? "terrain"
                                             : "ortho";
}

std::vector<sim::WeatherSpec> SuiteConditions(sim::WorldKind world) {
  std::vector<sim::WeatherSpec> out;
  for (const sim::SuiteEntry& e : sim::WeatherSuite())
    if (e.world == world) out.push_back(e.weather);
  return out;
}

std::optional<DocumentFigure> DocumentMeanError(sim::WorldKind world,
                                                const sim::WeatherSpec& condition) {
  const std::string key = condition.ToString();
  for (const DocumentRow& row : kDocument)
    if (row.world == world && key == row.condition)
      return DocumentFigure{row.mean_error_m, row.lost};
  return std::nullopt;
}

namespace {

std::vector<std::string> SplitList(const std::string& s) {
  std::vector<std::string> out;
  size_t start = 0;
  for (size_t comma; (comma = s.find(',', start)) != std::string::npos; start = comma + 1)
    if (comma > start) out.push_back(s.substr(start, comma - start));
  if (start < s.size()) out.push_back(s.substr(start));
  return out;
}

}  // namespace

void ParseWeatherBenchLists(const std::string& worlds, const std::string& conditions,
                            const std::string& modes, WeatherBenchOptions* o) {
  o->worlds.clear();
  for (const std::string& w : SplitList(worlds)) {
    const auto world = ParseWeatherBenchWorld(w);
    if (!world) throw Error("unknown world '" + w + "' (urban, terrain)", {.field = "--worlds"});
    o->worlds.push_back(*world);
  }
  o->conditions.clear();
  for (const std::string& c : SplitList(conditions)) {
    try {
      o->conditions.push_back(sim::ParseWeather(c));
    } catch (const Error& e) {
      throw Error(e.message(), {.field = "--conditions"});
    }
  }
  o->modes.clear();
  for (const std::string& m : SplitList(modes)) {
    const auto mode = vio::ParseVioMode(m);
    if (!mode) throw Error("unknown mode '" + m + "' (stereo, stereo-imu)", {.field = "--modes"});
    o->modes.push_back(*mode);
  }
}

std::string WeatherBenchOptions::Check() const {
  if (out_dir.empty()) return "--out must not be empty";
  if (!(scale >= 0.05 && scale <= 4))
    return fmt::format("--scale must be in [0.05, 4], got {}", scale);
  if (seeds < 1) return fmt::format("--seeds must be >= 1, got {}", seeds);
  if (jobs < 1) return fmt::format("--jobs must be >= 1, got {}", jobs);
  if (!vio_config.empty() && !fs::is_regular_file(vio_config))
    return fmt::format("--config {}: no such file", vio_config);
  if (worlds.empty()) return "--worlds must name at least one world (urban, terrain)";
  for (sim::WorldKind w : worlds)
    if (w != sim::WorldKind::kUrban && w != sim::WorldKind::kTerrain)
      return "--worlds takes urban and terrain only";
  if (modes.empty()) return "--modes must name at least one mode (stereo, stereo-imu)";
  const bool urban = std::count(worlds.begin(), worlds.end(), sim::WorldKind::kUrban) > 0;
  if (!conditions.empty() && !urban && std::all_of(conditions.begin(), conditions.end(), IsRoad))
    return "--conditions road-* apply to the urban world only (the document's road effects)";
  if (!(duration_s >= 0 && duration_s <= 3600))
    return fmt::format("duration_s must be in [0, 3600], got {}", duration_s);
  return "";
}

std::vector<WeatherCell> SummariseWeatherRuns(const WeatherBenchOptions& options,
                                              const std::vector<WeatherRunResult>& runs) {
  std::vector<WeatherCell> cells;
  for (sim::WorldKind w : options.worlds) {
    const std::vector<sim::WeatherSpec> conditions =
        options.conditions.empty() ? SuiteConditions(w) : options.conditions;
    for (const sim::WeatherSpec& c : conditions) {
      if (IsRoad(c) && w != sim::WorldKind::kUrban) continue;
      for (vio::VioMode m : options.modes) {
        WeatherCell cell{w, c, m};
        double sum = 0, odo = 0, ape = 0, fps = 0, mx = -INFINITY;
        for (const WeatherRunResult& r : runs) {
          if (r.world != w || r.mode != m || !SameCondition(r.condition, c)) continue;
          ++cell.runs;
          if (!r.ok) {
            ++cell.failed;
            continue;
          }
          cell.lost += r.Lost() ? 1 : 0;
          sum += r.mean_error_m, odo += r.odometry_mean_error_m, ape += r.ape_rmse_se3_m;
          fps += r.fps, mx = std::max(mx, r.mean_error_m);
        }
        if (const int n = cell.runs - cell.failed; n > 0) {
          cell.mean_error_m = sum / n, cell.odometry_mean_error_m = odo / n;
          cell.ape_rmse_se3_m = ape / n, cell.fps = fps / n, cell.mean_error_max_m = mx;
        }
        cell.document = DocumentMeanError(w, c);
        cells.push_back(cell);
      }
    }
  }
  // Ratios to clear of the same world and mode (ours), and of the same world (the document's).
  for (WeatherCell& cell : cells) {
    for (const WeatherCell& clear : cells) {
      if (clear.world != cell.world || clear.mode != cell.mode || !clear.condition.IsClear())
        continue;
      cell.ratio_to_clear = cell.mean_error_m / clear.mean_error_m;
      if (cell.document && clear.document)
        cell.document_ratio_to_clear = cell.document->mean_error_m / clear.document->mean_error_m;
      break;
    }
  }
  return cells;
}

std::vector<PlannedTask> WeatherBenchTasks(const WeatherBenchOptions& options) {
  std::vector<PlannedTask> out;
  for (const Sequence& s : ListSequences(options)) {
    for (vio::VioMode mode : options.modes) {
      const std::string stem = (fs::path(options.out_dir) / "runs" / RunStem(s, mode)).string();
      out.push_back(
          {fmt::format("{} {} seed {}", s.name, vio::VioModeName(mode), s.seed),
           {stem + ".tum", stem + ".odometry.tum", stem + ".stats.json", stem + ".json"}});
    }
  }
  return out;
}

SlurmResources WeatherBenchTaskResources(const WeatherBenchOptions& o) {
  // Measured on the 2-core VM (bench/RESULTS.md, "Slurm", 2026-11-26): per frame, rendering
  // 12.7 ms at 200x150 and 116 ms at 800x600, the threaded VIO 16.3 ms and 81 ms: both about
  // linear in the pixels, 0.018 s + 0.373 s/Mpx together. Peak memory 146-149 MB at every size
  // (frames are streamed to disk). The whole car route is 3,509 frames. Asked: 512 MB (3x the
  // peak) + 256 MB/Mpx; time 3x the estimate (slower or shared nodes), 10 min at least.
  const double megapixels = 0.48 * o.scale * o.scale;
  const double frames = o.duration_s > 0 ? std::min(3509.0, o.duration_s / 0.03 + 1) : 3509;
  const double vio_frames = o.max_frames > 0 ? std::min<double>(frames, o.max_frames) : frames;
  // A task renders its sequence (when no other task has) and runs one mode on it.
  const double estimate_s =
      frames * (0.0058 + 0.2296 * megapixels) + vio_frames * (0.0120 + 0.1433 * megapixels);
  return BenchTaskResources(
      2, megapixels, estimate_s,
      fmt::format("2 CPUs (threaded VIO); memory 512 MB + 256 MB/Mpx (measured peak ~150 MB); "
                  "time 3 x {:.0f} frames x (0.018 + 0.373 s/Mpx at {:.3f} Mpx) = 3 x {:.0f} s, "
                  "10 min at least",
                  frames, megapixels, estimate_s));
}

WeatherBenchResult RunWeatherBench(const WeatherBenchOptions& options,
                                   const WeatherBenchProgress& progress) {
  ThrowIfInvalid(options);
  if (options.html) report::LoadLeafletAssets();  // missing: say so before the runs, not after
  std::string config_text;  // read once: every run records the text its options came from
  if (!options.vio_config.empty()) {
    vio::LoadVioOptions(options.vio_config);  // a bad file: now, before anything is written
    config_text = io::ReadFileToString(options.vio_config);
  }
  const Timer timer;
  if (options.merge) {
    const std::optional<SlurmPlan> plan = ReadSlurmPlan(options.out_dir);
    if (!plan)
      throw Error("no Slurm plan to merge (plan.json; made by --plan slurm)",
                  {.file = options.out_dir});
    ThrowIfUnfinished(*plan);
  }
  fs::create_directories(fs::path(options.out_dir) / "runs");
  const std::vector<Sequence> sequences = ListSequences(options);
  Shared shared{options, progress};
  shared.vio_config_text = std::move(config_text);
  if (options.task >= 0) {  // one task of a planned sweep: its run files, no tables
    const size_t n_modes = options.modes.size();
    if (static_cast<size_t>(options.task) >= sequences.size() * n_modes)
      throw Error(fmt::format("task {} does not exist (the plan has {} tasks: 0-{})", options.task,
                              sequences.size() * n_modes, sequences.size() * n_modes - 1),
                  {.field = "--task"});
    const std::vector<vio::VioMode> mode = {options.modes[options.task % n_modes]};
    shared.total = 1;
    WeatherBenchResult result;
    result.runs = RunSequence(sequences[options.task / n_modes], &shared, &mode);
    if (!result.runs[0].ok)
      throw Error("task " + std::to_string(options.task) + " failed: " + result.runs[0].error);
    result.wall_s = timer.ElapsedSeconds();
    return result;
  }
  shared.total = sequences.size() * options.modes.size();
  std::vector<std::vector<WeatherRunResult>> per_sequence(sequences.size());
  std::atomic<size_t> next{0};
  std::exception_ptr failure;
  const auto worker = [&] {
    for (size_t i; (i = next++) < sequences.size();) {
      try {
        per_sequence[i] = RunSequence(sequences[i], &shared);
      } catch (...) {  // a sequence that cannot be rendered or read stops the benchmark
        std::lock_guard lock(shared.mutex);
        if (!failure) failure = std::current_exception();
        next = sequences.size();
      }
    }
  };
  std::vector<std::thread> threads;
  const int n_threads = std::min<int>(options.jobs, static_cast<int>(sequences.size()));
  for (int k = 0; k < n_threads; ++k) threads.emplace_back(worker);
  for (std::thread& t : threads) t.join();
  if (failure) std::rethrow_exception(failure);

  WeatherBenchResult result;
  for (auto& runs : per_sequence)
    for (WeatherRunResult& r : runs) result.runs.push_back(std::move(r));
  result.cells = SummariseWeatherRuns(options, result.runs);
  result.wall_s = timer.ElapsedSeconds();
  result.table = internal::WeatherBenchTable(options, result.cells, result.runs);
  internal::WriteWeatherBenchFiles(options, result);
  if (options.html) result.html = WriteHtmlReport(options.out_dir);
  return result;
}

}  // namespace optinav::app
