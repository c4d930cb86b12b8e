#include "optinav/app/mission_experiment.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <utility>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/app/html_report.h"
#include "optinav/io/text_parse.h"
#include "optinav/maploc/map_db.h"
#include "optinav/nav/frame_effects.h"
#include "optinav/report/geo_export.h"
#include "optinav/report/html_report.h"
#include "optinav/report/map_overlay.h"
#include "optinav/report/map_plot.h"
#include "optinav/sim/weather.h"
#include "optinav/util/error.h"
#include "optinav/util/logging.h"
#include "optinav/util/progress.h"
#include "optinav/util/string_printf.h"

namespace optinav::app {
namespace {

namespace fs = std::filesystem;

// The median, or null when there is nothing to take it of.
nlohmann::json MedianOrNull(const std::vector<double>& v, double divide_by = 1.0) {
  if (v.empty()) return nullptr;
  return Median(v) / divide_by;
}

nlohmann::json ErrorStatsJson(const Statistics& s) {
  return {{"n", s.n},     {"mean", s.mean}, {"median", s.median},
          {"p95", s.p95}, {"max", s.max},   {"rmse", s.rmse}};
}

nlohmann::json MeanStdJson(const Statistics& s) { return {{"mean", s.mean}, {"std", s.std}}; }

std::string StepsCsv(const nav::MissionResult& r) {
  std::string s =
      "step,t_s,true_lat,true_lon,est_lat,est_lon,est_error_m,est_sigma_m,fix_found,"
      "fix_accepted,fix_method,fix_lat,fix_lon,fix_error_m,inliers,odometry_ok,global_search,"
      "command_heading_deg,truth_heading_deg,altitude_m,roll_deg,pitch_deg,synthesis_ms,"
      "extraction_ms,matching_ms,"
      "estimation_ms,odometry_ms,navigation_ms,reason\n";
  for (const nav::StepLog& l : r.steps) {
    std::string reason = l.fix_reason;
    std::replace(reason.begin(), reason.end(), '"', '\'');
    s += fmt::format(
        "{},{:.3f},{:.8f},{:.8f},{:.8f},{:.8f},{:.2f},{:.2f},{:d},{:d},{},{},{},{},{},{:d},{:d},"
        "{:.2f},{:.2f},{:.1f},{:.2f},{:.2f},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},\"{}\"\n",
        l.step, l.t_s, l.truth.lat_deg, l.truth.lon_deg, l.estimate.lat_deg, l.estimate.lon_deg,
        l.estimate_error_m, l.estimate_sigma_m, l.fix_found, l.fix_accepted, l.fix_method,
        l.fix_found ? fmt::format("{:.8f}", l.fix.lat_deg) : "",
        l.fix_found ? fmt::format("{:.8f}", l.fix.lon_deg) : "",
        l.fix_found ? fmt::format("{:.2f}", l.fix_error_m) : "", l.inliers, l.odometry_ok,
        l.global_search, l.command_heading_deg, l.truth_heading_deg, l.altitude_m, l.roll_deg,
        l.pitch_deg, l.times.synthesis_ms, l.times.extraction_ms, l.times.matching_ms,
        l.times.estimation_ms, l.times.odometry_ms, l.times.navigation_ms, reason);
  }
  return s;
}

// The map image for pictures, at most `max_side` pixels across, and its scale.
struct Background {
  cv::Mat image;
  double scale = 1;  // picture px per map px
};
Background LoadBackground(const maploc::MapDatabase& db, const std::string& ortho, int max_side,
                          bool lighten = true) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(ortho);
  Background b;
  b.scale = std::min(1.0, max_side / static_cast<double>(std::max(db.width, db.height)));
  const int w = std::max(1, static_cast<int>(db.width * b.scale));
  const int h = std::max(1, static_cast<int>(db.height * b.scale));
  b.image = raster.ReadGray(0, 0, db.width, db.height, w, h);
  // Lighten so the paths stand out.
  if (lighten) b.image.convertTo(b.image, CV_8U, 0.6, 90);
  return b;
}

const report::Rgb kTruth{20, 160, 60}, kEstimate{230, 110, 20}, kFix{200, 40, 200},
    kStart{30, 90, 220}, kTarget{220, 30, 30};

std::vector<Eigen::Vector2d> ToPicture(nav::Mission& m, const Background& bg,
                                       const std::vector<geo::LatLon>& ll) {
  std::vector<Eigen::Vector2d> px;
  px.reserve(ll.size());
  for (const geo::LatLon& p : ll) px.push_back(m.locator().LatLonToPixel(p) * bg.scale);
  return px;
}

struct RunPaths {
  std::vector<geo::LatLon> truth, estimate;
};
RunPaths Paths(const nav::MissionResult& r) {
  RunPaths p;
  for (const nav::StepLog& l : r.steps) {
    p.truth.push_back(l.truth);
    p.estimate.push_back(l.estimate);
  }
  return p;
}

// Errors over time, drawn under the map (the paths overlap at map scale when all goes well).
std::vector<report::ChartSeries> ErrorChart(const nav::MissionResult& r) {
  report::ChartSeries est{"estimate error", kEstimate, {}, {}, false};
  report::ChartSeries fix{"fix error", kFix, {}, {}, true};
  report::ChartSeries sigma{"estimate sigma", {150, 150, 150}, {}, {}, false};
  for (const nav::StepLog& l : r.steps) {
    est.x.push_back(l.t_s);
    est.y.push_back(l.estimate_error_m);
    sigma.x.push_back(l.t_s);
    sigma.y.push_back(l.estimate_sigma_m);
    if (l.fix_found) {
      fix.x.push_back(l.t_s);
      fix.y.push_back(std::min(l.fix_error_m, 100.0));  // wrong fixes pinned to the top
    }
  }
  return {sigma, est, fix};
}

void WriteRunPicture(const fs::path& dir, const MissionRunOutcome& run, nav::Mission& m,
                     const Background& bg, const RunPaths& p) {
  const nav::MissionResult& r = run.mission;
  report::MapPlot plot;
  plot.background = bg.image;
  plot.title = fmt::format("mission run {}: {} ({:.0f} m to target at the end)", run.run,
                           r.reached ? "reached" : "NOT reached", r.final_distance_m);
  int fixes = 0;
  for (const auto& l : r.steps) fixes += l.fix_accepted;
  plot.notes.push_back(
      fmt::format("{:.0f} m straight, {:.0f} m flown in {:.0f} s, {} steps, "
                  "{} accepted fixes",
                  r.straight_distance_m, r.flown_m, r.duration_s, r.steps.size(), fixes));
  plot.paths.push_back({"true path", kTruth, ToPicture(m, bg, p.truth), 2.5});
  plot.paths.push_back({"estimated path", kEstimate, ToPicture(m, bg, p.estimate), 1.5, true});
  const auto mark = [&](const std::string& label, const report::Rgb& c, const geo::LatLon& ll,
                        char shape) {
    plot.markers.push_back({label, c, m.locator().LatLonToPixel(ll) * bg.scale, shape});
  };
  mark("start", kStart, run.start, 'o');
  mark("target", kTarget, run.target, '*');
  // Label the end only when it is apart from the target (a reached target speaks for itself).
  mark(r.final_distance_m > 20 * m.map_gsd_m() / bg.scale ? "end" : "", kTruth,
       r.steps.back().truth, 'x');
  plot.chart = ErrorChart(r);
  plot.chart_x_label = "time (s)";
  plot.chart_y_label = "error (m)";
  report::WriteMapPlot((dir / "path").string(), plot);
}

// run_NNN/: steps.csv, paths.geojson/.kml, the picture (when `bg`) and the frames (when kept).
void WriteRunOutputs(const fs::path& dir, MissionRunOutcome& run, nav::Mission& m,
                     const Background* bg) {
  fs::create_directories(dir);
  const nav::MissionResult& r = run.mission;
  io::WriteFileAtomically((dir / "steps.csv").string(), StepsCsv(r));
  const RunPaths p = Paths(r);
  const std::string n = std::to_string(run.run);
  const std::vector<report::GeoLine> lines = {
      {"true path", p.truth, kTruth.Hex(), {{"run", n}}},
      {"estimated path", p.estimate, kEstimate.Hex(), {{"run", n}}}};
  const std::vector<report::GeoPoint> points = {
      {"start", run.start}, {"target", run.target}, {"end", r.steps.back().truth}};
  io::WriteFileAtomically((dir / "paths.geojson").string(), report::ToGeoJson(lines, points));
  io::WriteFileAtomically(
      (dir / "paths.kml").string(),
      report::ToKml(fmt::format("optinav mission run {}", run.run), lines, points));
  if (bg) WriteRunPicture(dir, run, m, *bg, p);
  if (run.mission.frames.empty()) return;
  fs::create_directories(dir / "frames");
  for (size_t k = 0; k < run.mission.frames.size(); ++k) {
    const std::string f = (dir / "frames" / fmt::format("step_{:04d}.png", k)).string();
    if (!cv::imwrite(f, run.mission.frames[k])) throw Error("cannot write frame", {.file = f});
  }
  run.mission.frames.clear();
}

// The map, the frame source, the mission and every run's leg: set up and checked before anything
// is written. Not movable (the mission keeps references to the map and the frames).
struct Setup {
  sim::WeatherSpec weather;
  maploc::MapDatabase db;
  std::string ortho;
  std::unique_ptr<geo::GeoRaster> frames;  // the GeoRaster is only made by Open
  std::unique_ptr<nav::Mission> mission;
  std::vector<std::pair<geo::LatLon, geo::LatLon>> legs;
};

std::unique_ptr<Setup> PrepareSetup(const MissionExperimentOptions& opt) {
  auto s = std::make_unique<Setup>();
  s->weather = sim::ParseWeather(opt.weather);
  s->weather.distance_scale = 0;  // nadir camera: scaled to the altitude (nav::MakeWeatherHook)
  s->db = maploc::LoadMapDatabase(opt.map_path);
  s->ortho = opt.ortho_path.empty() ? s->db.ortho_path : opt.ortho_path;
  if (!fs::exists(s->ortho)) {
    throw Error("the map's orthophoto is not there (moved? give --ortho)", {.file = s->ortho});
  }
  s->frames = std::make_unique<geo::GeoRaster>(
      geo::GeoRaster::Open(opt.frames_from.empty() ? s->ortho : opt.frames_from));
  maploc::LocateOptions lo;
  lo.ortho_path = s->ortho;
  lo.model_path = opt.model_path;
  s->mission = std::make_unique<nav::Mission>(s->db, *s->frames, lo);
  for (int i = 0; i < opt.runs; ++i) {
    if (opt.start) {
      s->legs.emplace_back(*opt.start, *opt.target);
    } else {
      s->legs.push_back(nav::RandomStartTarget(s->db, opt.min_distance_m, opt.margin_m,
                                               opt.mission.seed * 7919 + i));
    }
    nav::MissionOptions o = opt.mission;
    o.start = s->legs.back().first;
    o.target = s->legs.back().second;
    if (const std::string e = s->mission->Check(o); !e.empty()) throw Error(e);
  }
  return s;
}

// Per-step samples pooled over every run.
struct Samples {
  std::vector<double> fix_errors, est_errors, finals, extraction, matching, estimation, fix_total,
      odometry, navigation, synthesis;
};

MissionRunOutcome FlyRun(const MissionExperimentOptions& opt, Setup& s, int i, Samples& samples,
                         MissionExperimentResult& result) {
  nav::MissionOptions o = opt.mission;
  o.start = s.legs[i].first;
  o.target = s.legs[i].second;
  o.seed = opt.mission.seed + i;
  o.weather = nav::MakeWeatherHook(s.weather, o.seed);
  o.keep_frames = opt.save_frames;
  MissionRunOutcome run{.run = i + 1, .start = o.start, .target = o.target};
  run.mission = s.mission->Run(o);
  std::vector<double> run_fix;
  int run_found = 0;
  for (const nav::StepLog& l : run.mission.steps) {
    ++result.steps;
    run_found += l.fix_found;
    result.fixes_accepted += l.fix_accepted;
    if (l.fix_found) {
      samples.fix_errors.push_back(l.fix_error_m);
      run_fix.push_back(l.fix_error_m);
    }
    samples.est_errors.push_back(l.estimate_error_m);
    samples.extraction.push_back(l.times.extraction_ms);
    samples.matching.push_back(l.times.matching_ms);
    samples.estimation.push_back(l.times.estimation_ms);
    samples.fix_total.push_back(l.times.extraction_ms + l.times.matching_ms +
                                l.times.estimation_ms + l.times.locate_ms);
    samples.odometry.push_back(l.times.odometry_ms);
    samples.navigation.push_back(l.times.navigation_ms);
    samples.synthesis.push_back(l.times.synthesis_ms);
  }
  result.fixes_found += run_found;
  result.reached += run.mission.reached;
  samples.finals.push_back(run.mission.final_distance_m);
  run.fix_rate = static_cast<double>(run_found) / run.mission.steps.size();
  run.median_fix_error_m = Median(run_fix);
  return run;
}

nlohmann::json RunJson(const MissionRunOutcome& run) {
  const nav::MissionResult& r = run.mission;
  return {{"run", run.run},
          {"start", {run.start.lat_deg, run.start.lon_deg}},
          {"target", {run.target.lat_deg, run.target.lon_deg}},
          {"straight_distance_m", r.straight_distance_m},
          {"reached", r.reached},
          {"end_reason", r.end_reason},
          {"final_distance_m", r.final_distance_m},
          {"flown_m", r.flown_m},
          {"duration_s", r.duration_s},
          {"steps", r.steps.size()},
          {"fix_rate", run.fix_rate},
          {"median_fix_error_m", std::isnan(run.median_fix_error_m)
                                     ? nlohmann::json(nullptr)
                                     : nlohmann::json(run.median_fix_error_m)}};
}

void Summarize(const Samples& s, MissionExperimentResult& result) {
  if (!s.fix_errors.empty()) result.fix_error_m = ComputeStatistics(s.fix_errors);
  result.estimate_error_m = ComputeStatistics(s.est_errors);
  result.final_distance_m = ComputeStatistics(s.finals);
  MissionTimings& t = result.timing_ms;
  t.extraction = ComputeStatistics(s.extraction);
  t.matching = ComputeStatistics(s.matching);
  t.estimation = ComputeStatistics(s.estimation);
  t.localization = ComputeStatistics(s.fix_total);
  t.odometry = ComputeStatistics(s.odometry);
  t.navigation = ComputeStatistics(s.navigation);
  t.synthesis = ComputeStatistics(s.synthesis);
  result.navigation_steps_per_second = t.navigation.mean > 0 ? 1000.0 / t.navigation.mean : 0.0;
}

nlohmann::json SettingsJson(const MissionExperimentOptions& opt, const Setup& s) {
  const nav::MissionOptions& o = opt.mission;
  return {{"map", opt.map_path},
          {"frames_from", s.frames->path()},
          {"map_gsd_m", s.db.map_gsd_m},
          {"speed_m_s", o.speed_m_s},
          {"altitude_m", o.altitude_m > 0 ? o.altitude_m : s.db.options.altitude_m},
          {"step_s", o.step_s},
          {"arrive_radius_m", o.arrive_radius_m},
          {"success_radius_m", o.success_radius_m},
          {"weather", s.weather.ToString()},
          {"odometry", o.use_odometry},
          {"wind_m_s", o.wind_m_s},
          {"compass_bias_deg", o.compass_bias_deg},
          {"max_tilt_deg", o.effects.max_tilt_deg},
          {"attitude_noise_deg", o.attitude_noise_deg},
          {"estimator", o.estimator},
          {"nadir_camera", o.estimator == "nav" ? nlohmann::json{{"width", o.nadir.width},
                                                                 {"height", o.nadir.height},
                                                                 {"hfov_deg", o.nadir.hfov_deg},
                                                                 {"rate_hz", o.nadir.rate_hz}}
                                                : nlohmann::json(nullptr)},
          {"seed", o.seed}};
}

nlohmann::json SummaryJson(const MissionExperimentOptions& opt, const Setup& s,
                           const Samples& samples, const MissionExperimentResult& r) {
  nlohmann::json runs = nlohmann::json::array();
  for (const MissionRunOutcome& run : r.runs) runs.push_back(RunJson(run));
  const MissionTimings& t = r.timing_ms;
  return {{"runs", opt.runs},
          {"reached", r.reached},
          {"success_rate", static_cast<double>(r.reached) / opt.runs},
          {"median_fix_error_m", MedianOrNull(samples.fix_errors)},
          {"median_fix_error_map_px", MedianOrNull(samples.fix_errors, s.db.map_gsd_m)},
          {"fix_rate", static_cast<double>(r.fixes_found) / r.steps},
          {"accepted_fix_rate", static_cast<double>(r.fixes_accepted) / r.steps},
          {"steps", r.steps},
          {"fix_error_m", r.fix_error_m ? ErrorStatsJson(*r.fix_error_m) : nlohmann::json(nullptr)},
          {"estimate_error_m", ErrorStatsJson(r.estimate_error_m)},
          {"final_distance_m", ErrorStatsJson(r.final_distance_m)},
          {"timing_ms",
           {{"feature_extraction", MeanStdJson(t.extraction)},
            {"matching", MeanStdJson(t.matching)},
            {"position_estimation", MeanStdJson(t.estimation)},
            {"localization", MeanStdJson(t.localization)},
            {"odometry", MeanStdJson(t.odometry)},
            {"navigation_step", MeanStdJson(t.navigation)},
            {"frame_synthesis", MeanStdJson(t.synthesis)}}},
          {"navigation_steps_per_second", r.navigation_steps_per_second},
          {"settings", SettingsJson(opt, s)},
          {"per_run", runs}};
}

// paths.geojson/.kml with every run, and the summary picture (when `bg`).
void WriteAllRunsOutputs(const MissionExperimentOptions& opt, Setup& s, const Background* bg,
                         const MissionExperimentResult& r) {
  const fs::path out(opt.out_dir);
  std::vector<report::GeoLine> lines;
  std::vector<report::GeoPoint> points;
  report::MapPlot plot;
  if (bg) plot.background = bg->image;
  nav::Mission& m = *s.mission;
  for (size_t i = 0; i < r.runs.size(); ++i) {
    const RunPaths p = Paths(r.runs[i].mission);
    const std::string run = std::to_string(i + 1);
    lines.push_back({"true path " + run, p.truth, kTruth.Hex(), {{"run", run}}});
    lines.push_back({"estimated path " + run, p.estimate, kEstimate.Hex(), {{"run", run}}});
    points.push_back({"start " + run, s.legs[i].first});
    points.push_back({"target " + run, s.legs[i].second});
    if (!bg) continue;
    plot.paths.push_back({i == 0 ? "true paths" : "", kTruth, ToPicture(m, *bg, p.truth), 2});
    plot.paths.push_back(
        {i == 0 ? "estimated paths" : "", kEstimate, ToPicture(m, *bg, p.estimate), 1, true});
    plot.markers.push_back(
        {"", kStart, m.locator().LatLonToPixel(s.legs[i].first) * bg->scale, 'o'});
    plot.markers.push_back({r.runs[i].mission.reached ? "" : "missed " + run, kTarget,
                            m.locator().LatLonToPixel(s.legs[i].second) * bg->scale, '*'});
  }
  io::WriteFileAtomically((out / "paths.geojson").string(), report::ToGeoJson(lines, points));
  io::WriteFileAtomically((out / "paths.kml").string(),
                          report::ToKml("optinav mission runs", lines, points));
  if (!bg) return;
  const double median_fix = r.fix_error_m ? r.fix_error_m->median : std::nan("");
  plot.title = fmt::format("{} mission(s): {} reached the target (within {:.0f} m)", opt.runs,
                           r.reached, opt.mission.success_radius_m);
  plot.notes.push_back(fmt::format(
      "map {}, frames {}, {} m/s, weather {}; median fix error {:.1f} m, fix rate {:.0f} %",
      fs::path(s.db.ortho_path).filename().string(), fs::path(s.frames->path()).filename().string(),
      opt.mission.speed_m_s, s.weather.ToString(), median_fix, 100.0 * r.fixes_found / r.steps));
  plot.notes.push_back("o start   * target   (blue circles, red stars)");
  report::WriteMapPlot((out / "summary").string(), plot);
}

// ---------------------------------------------------------------------------------------------
// The report document (report.json + report_map.jpg) for `optinav report` / --html.

std::string Fmt(double v, int decimals) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : std::string("n/a");
}

report::ReportTable SummaryTable(const MissionExperimentResult& r) {
  const double steps = r.steps;
  report::ReportTable t{"Key figures", {"figure", "value"}, {}};
  const auto row = [&](const std::string& k, const std::string& v) { t.rows.push_back({k, v}); };
  row("runs reached / flown", fmt::format("{} / {}", r.reached, r.runs.size()));
  row("success radius (m)", Fmt(r.success_radius_m, 0));
  row("steps", std::to_string(r.steps));
  row("fixes found (% of steps)", Fmt(100.0 * r.fixes_found / steps, 1));
  row("fixes accepted (% of steps)", Fmt(100.0 * r.fixes_accepted / steps, 1));
  row("fix error median / p95 / max (m)",
      r.fix_error_m ? fmt::format("{} / {} / {}", Fmt(r.fix_error_m->median, 2),
                                  Fmt(r.fix_error_m->p95, 2), Fmt(r.fix_error_m->max, 2))
                    : std::string("no fix"));
  row("estimate error median / p95 / max (m)",
      fmt::format("{} / {} / {}", Fmt(r.estimate_error_m.median, 2), Fmt(r.estimate_error_m.p95, 2),
                  Fmt(r.estimate_error_m.max, 2)));
  row("final distance to target median / max (m)",
      fmt::format("{} / {}", Fmt(r.final_distance_m.median, 1), Fmt(r.final_distance_m.max, 1)));
  row("localization per step (ms, mean)", Fmt(r.timing_ms.localization.mean, 2));
  row("navigation step (ms, mean)", Fmt(r.timing_ms.navigation.mean, 2));
  return t;
}

report::ReportTable RunsTable(const MissionExperimentResult& r) {
  report::ReportTable t{"Runs",
                        {"run", "straight (m)", "flown (m)", "steps", "reached", "end",
                         "final distance (m)", "fix rate", "median fix error (m)"},
                        {}};
  for (const MissionRunOutcome& run : r.runs) {
    const nav::MissionResult& m = run.mission;
    t.rows.push_back({std::to_string(run.run), Fmt(m.straight_distance_m, 0), Fmt(m.flown_m, 0),
                      std::to_string(m.steps.size()), m.reached ? "yes" : "NO", m.end_reason,
                      Fmt(m.final_distance_m, 1), Fmt(run.fix_rate, 2),
                      Fmt(run.median_fix_error_m, 2)});
  }
  return t;
}

Eigen::Vector2d LatLonPoint(const geo::LatLon& ll) { return {ll.lat_deg, ll.lon_deg}; }

void WriteMissionReport(const MissionExperimentOptions& opt, Setup& s,
                        const MissionExperimentResult& r) {
  const fs::path out(opt.out_dir);
  nav::Mission& m = *s.mission;
  // The orthophoto, resampled to Web Mercator so Leaflet places it exactly.
  const Background bg = LoadBackground(s.db, s.ortho, 1400, /*lighten=*/false);
  const report::MercatorImage merc = report::ToMercatorImage(
      bg.image,
      [&](const geo::LatLon& ll) -> Eigen::Vector2d {
        const Eigen::Vector2d map_px = m.locator().LatLonToPixel(ll);
        return {map_px.x() * bg.scale, map_px.y() * bg.scale};
      },
      [&](const Eigen::Vector2d& px) {
        return m.locator().PixelToLatLon({px.x() / bg.scale, px.y() / bg.scale});
      },
      std::min(1400, std::max(bg.image.cols, bg.image.rows)));
  report::WriteJpeg((out / "report_map.jpg").string(), merc.image, 80);

  report::ReportView v;
  v.name = fmt::format("{} over {}", r.runs.size() == 1 ? "the mission" : "every run",
                       fs::path(s.db.ortho_path).filename().string());
  v.image = report::ReportImage{"report_map.jpg", LatLonPoint(merc.south_west),
                                LatLonPoint(merc.north_east)};
  report::ReportChart chart{"error over time", "time (s)", "error (m)", {}};
  report::ReportSeries fixes{"fix error (found fixes)", kFix.Hex(), {}, {}, true};
  for (const MissionRunOutcome& run : r.runs) {
    const std::string n = std::to_string(run.run);
    const RunPaths p = Paths(run.mission);
    report::ReportPath truth{
        "true paths", "run " + n + ": true path", kTruth.Hex(), 2.5, false, {}};
    report::ReportPath est{
        "estimated paths", "run " + n + ": estimated path", kEstimate.Hex(), 1.5, true, {}};
    for (const geo::LatLon& ll : p.truth) truth.points.push_back(LatLonPoint(ll));
    for (const geo::LatLon& ll : p.estimate) est.points.push_back(LatLonPoint(ll));
    v.paths.push_back(std::move(truth));
    v.paths.push_back(std::move(est));
    report::ReportSeries err{run.run == 1 ? "estimate error" : "", kEstimate.Hex(), {}, {}, false};
    for (const nav::StepLog& l : run.mission.steps) {
      err.x.push_back(l.t_s);
      err.y.push_back(l.estimate_error_m);
      if (!l.fix_found) continue;
      fixes.x.push_back(l.t_s);
      fixes.y.push_back(l.fix_error_m);
      v.fixes.push_back({"fixes", "run " + n + ", step " + std::to_string(l.step),
                         LatLonPoint(l.fix), l.t_s, l.fix_error_m, l.fix_method, l.inliers,
                         l.fix_accepted, l.fix_accepted ? "" : l.fix_reason});
    }
    chart.series.push_back(std::move(err));
    v.markers.push_back({"start / target", "start " + n, "start", LatLonPoint(run.start)});
    v.markers.push_back({"start / target", "target " + n + (run.mission.reached ? "" : " (missed)"),
                         "target", LatLonPoint(run.target)});
    if (!run.mission.reached)
      v.markers.push_back({"start / target",
                           fmt::format("end {} ({:.0f} m short)", n, run.mission.final_distance_m),
                           "end", LatLonPoint(run.mission.steps.back().truth)});
  }
  chart.series.insert(chart.series.begin(), std::move(fixes));  // under the lines
  v.chart = std::move(chart);
  report::ReportDocument doc;
  doc.kind = "mission";
  doc.title =
      fmt::format("optinav mission: {} run(s), {} reached the target", r.runs.size(), r.reached);
  doc.notes.push_back(fmt::format(
      "map {}, frames from {}, weather {}, {} m/s; fixes are coloured by their error (click one "
      "for time, error, method, inliers)",
      opt.map_path, s.frames->path(), s.weather.ToString(), opt.mission.speed_m_s));
  doc.views.push_back(std::move(v));
  doc.tables = {SummaryTable(r), RunsTable(r)};
  doc.settings = r.summary.at("settings");
  report::WriteReportDocument(ReportDocumentPath(opt.out_dir), doc);
}

}  // namespace

std::string MissionExperimentOptions::Check() const {
  if (map_path.empty()) return "--map must name a map database";
  if (out_dir.empty()) return "--out must name an output folder";
  if (runs < 1 || runs > 10000) return fmt::format("--runs must be in [1, 10000], got {}", runs);
  if (pictures != "all" && pictures != "summary" && pictures != "none") {
    return "--pictures expected all|summary|none, got '" + pictures + "'";
  }
  if (start.has_value() != target.has_value()) {
    return "--start and --target: give both as LAT,LON, or both as 'random'";
  }
  return "";
}

MissionExperimentResult RunMissionExperiment(
    const MissionExperimentOptions& opt,
    const std::function<void(const MissionRunOutcome&)>& on_run) {
  if (const std::string e = opt.Check(); !e.empty()) throw Error(e);
  if (opt.html) report::LoadLeafletAssets();  // missing: say so before the runs, not after
  const std::unique_ptr<Setup> s = PrepareSetup(opt);
  io::PrepareOutputDir(opt.out_dir, opt.force, io::OnForce::kWriteInto, "--out", "summary.json");
  io::MarkInProgress(opt.out_dir, "optinav mission");
  const fs::path out(opt.out_dir);
  std::unique_ptr<Background> bg;
  if (opt.pictures != "none") {
    bg = std::make_unique<Background>(LoadBackground(s->db, s->ortho, 1000));
  }
  spdlog::info("mission: {} run(s), map {} ({} tiles), frames from {}, speed {} m/s, step {} s",
               opt.runs, opt.map_path, s->db.tiles.size(), s->frames->path(), opt.mission.speed_m_s,
               opt.mission.step_s);
  MissionExperimentResult result;
  result.success_radius_m = opt.mission.success_radius_m;
  result.map_gsd_m = s->db.map_gsd_m;
  result.out_dir = opt.out_dir;
  result.estimator = opt.mission.estimator;
  Samples samples;
  ProgressBar bar(opt.runs, "missions");
  for (int i = 0; i < opt.runs; ++i) {
    MissionRunOutcome run = FlyRun(opt, *s, i, samples, result);
    if (on_run) on_run(run);
    WriteRunOutputs(out / fmt::format("run_{:03d}", i + 1), run, *s->mission,
                    opt.pictures == "all" ? bg.get() : nullptr);
    result.runs.push_back(std::move(run));
    bar.Advance();
  }
  bar.Finish();
  Summarize(samples, result);
  result.summary = SummaryJson(opt, *s, samples, result);
  WriteAllRunsOutputs(opt, *s, bg.get(), result);
  WriteMissionReport(opt, *s, result);
  if (opt.html) result.html = WriteHtmlReport(opt.out_dir);
  // Written last: the folder's completion marker (a folder without it is an interrupted run).
  io::ClearInProgress(opt.out_dir);
  io::WriteFileAtomically((out / "summary.json").string(), result.summary.dump(2) + "\n");
  return result;
}

std::string FormatMissionRunHeader() {
  return StringPrintf("%4s %9s %6s %8s %10s %8s %10s\n", "run", "dist_m", "steps", "reached",
                      "final_m", "fix_rate", "fix_med_m");
}

std::string FormatMissionRunRow(const MissionRunOutcome& run) {
  const nav::MissionResult& r = run.mission;
  return StringPrintf("%4d %9.0f %6zu %8s %10.1f %8.2f %10.2f\n", run.run, r.straight_distance_m,
                      r.steps.size(), r.reached ? "yes" : "NO", r.final_distance_m, run.fix_rate,
                      run.median_fix_error_m);
}

std::string FormatMissionSummary(const MissionExperimentResult& r) {
  const double steps = r.steps;
  const double fix_med = r.fix_error_m ? r.fix_error_m->median : std::nan("");
  const double fix_p95 = r.fix_error_m ? r.fix_error_m->p95 : std::nan("");
  const MissionTimings& t = r.timing_ms;
  // The right-hand column: the published ORB pipeline's timings (s, on a Colab CPU) that these
  // stages are compared with (bench/RESULTS.md).
  return StringPrintf(
      "\nreached %d/%d (within %.0f m); final distance median %.1f m, max %.1f m\n"
      "fixes: %.1f %% of %d steps found, %.1f %% accepted; fix error median %.2f m (%.2f map "
      "px), p95 %.2f m\n"
      "estimate error: median %.2f m, p95 %.2f m, max %.2f m\n\n"
      "timing per step (ms, mean +- std)      optinav        reference ORB (s)\n"
      "  feature extraction                %7.2f +- %-6.2f   0.113 +- 0.029\n"
      "  matching                          %7.2f +- %-6.2f   0.313 +- 0.048\n"
      "  position estimation               %7.2f +- %-6.2f\n"
      "  localization (the three)          %7.2f +- %-6.2f   0.507 +- 0.152\n"
      "  frame-to-frame odometry           %7.2f +- %-6.2f\n"
      "  navigation step (all of it)       %7.2f +- %-6.2f   -> %.0f steps/s on one core\n"
      "%s"
      "wrote %s/summary.json, summary.png/.svg, paths.geojson/.kml, report.json, run_NNN/\n",
      r.reached, static_cast<int>(r.runs.size()), r.success_radius_m, r.final_distance_m.median,
      r.final_distance_m.max, 100.0 * r.fixes_found / steps, r.steps,
      100.0 * r.fixes_accepted / steps, fix_med, fix_med / r.map_gsd_m, fix_p95,
      r.estimate_error_m.median, r.estimate_error_m.p95, r.estimate_error_m.max, t.extraction.mean,
      t.extraction.std, t.matching.mean, t.matching.std, t.estimation.mean, t.estimation.std,
      t.localization.mean, t.localization.std, t.odometry.mean, t.odometry.std, t.navigation.mean,
      t.navigation.std, r.navigation_steps_per_second,
      r.estimator == "nav"
          ? "  (estimator nav: a step is step_s of flight, its nadir frames and IMU; the "
            "map fix is timed whole,\n   the window's solve is in the navigation "
            "step)\n"
          : "",
      r.out_dir.c_str());
}

}  // namespace optinav::app
