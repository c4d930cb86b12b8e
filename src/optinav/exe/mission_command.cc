// optinav mission: GNSS-denied flights to a target over an orthophoto map, repeated over seeded
// runs, with a summary table, JSON, pictures (PNG + SVG) and GIS exports (GeoJSON, KML).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/exe/cli_common.h"
#include "optinav/exe/commands.h"
#include "optinav/exe/mission_experiment.h"
#include "optinav/io/text_parse.h"
#include "optinav/nav/mission.h"
#include "optinav/report/geo_export.h"
#include "optinav/report/map_plot.h"
#include "optinav/util/logging.h"
#include "optinav/util/progress.h"
#include "optinav/util/timer.h"

namespace optinav {
namespace {

namespace fs = std::filesystem;

struct MeanStd {
  double mean = 0, std = 0;
};
MeanStd Stats(const std::vector<double>& v) {
  MeanStd s;
  if (v.empty()) return s;
  s.mean = std::accumulate(v.begin(), v.end(), 0.0) / v.size();
  double ss = 0;
  for (double x : v) ss += (x - s.mean) * (x - s.mean);
  s.std = v.size() > 1 ? std::sqrt(ss / (v.size() - 1)) : 0.0;
  return s;
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const size_t i = static_cast<size_t>(pos);
  const double f = pos - i;
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

// The median, or null when there is nothing to take it of.
nlohmann::json MedianOrNull(const std::vector<double>& v, double divide_by = 1.0) {
  if (v.empty()) return nullptr;
  return Quantile(v, 0.5) / divide_by;
}

nlohmann::json ErrorStats(const std::vector<double>& v) {
  if (v.empty()) return nullptr;
  double ss = 0;
  for (double x : v) ss += x * x;
  return {{"n", v.size()},
          {"mean", Stats(v).mean},
          {"median", Quantile(v, 0.5)},
          {"p95", Quantile(v, 0.95)},
          {"max", *std::max_element(v.begin(), v.end())},
          {"rmse", std::sqrt(ss / v.size())}};
}

std::string StepsCsv(const nav::MissionResult& r) {
  std::string s =
      "step,t_s,true_lat,true_lon,est_lat,est_lon,est_error_m,est_sigma_m,fix_found,"
      "fix_accepted,fix_method,fix_lat,fix_lon,fix_error_m,inliers,odometry_ok,global_search,"
      "command_heading_deg,truth_heading_deg,altitude_m,synthesis_ms,extraction_ms,matching_ms,"
      "estimation_ms,odometry_ms,navigation_ms,reason\n";
  for (const nav::StepLog& l : r.steps) {
    std::string reason = l.fix_reason;
    std::replace(reason.begin(), reason.end(), '"', '\'');
    s += fmt::format(
        "{},{:.3f},{:.8f},{:.8f},{:.8f},{:.8f},{:.2f},{:.2f},{:d},{:d},{},{},{},{},{},{:d},{:d},"
        "{:.2f},{:.2f},{:.1f},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},\"{}\"\n",
        l.step, l.t_s, l.truth.lat_deg, l.truth.lon_deg, l.estimate.lat_deg, l.estimate.lon_deg,
        l.estimate_error_m, l.estimate_sigma_m, l.fix_found, l.fix_accepted, l.fix_method,
        l.fix_found ? fmt::format("{:.8f}", l.fix.lat_deg) : "",
        l.fix_found ? fmt::format("{:.8f}", l.fix.lon_deg) : "",
        l.fix_found ? fmt::format("{:.2f}", l.fix_error_m) : "", l.inliers, l.odometry_ok,
        l.global_search, l.command_heading_deg, l.truth_heading_deg, l.altitude_m,
        l.times.synthesis_ms, l.times.extraction_ms, l.times.matching_ms, l.times.estimation_ms,
        l.times.odometry_ms, l.times.navigation_ms, reason);
  }
  return s;
}

// The map image for pictures, at most `max_side` pixels across, and its scale.
struct Background {
  cv::Mat image;
  double scale = 1;  // picture px per map px
};
Background LoadBackground(const maploc::MapDatabase& db, const std::string& ortho, int max_side) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(ortho);
  Background b;
  b.scale = std::min(1.0, max_side / static_cast<double>(std::max(db.width, db.height)));
  const int w = std::max(1, static_cast<int>(db.width * b.scale));
  const int h = std::max(1, static_cast<int>(db.height * b.scale));
  b.image = raster.ReadGray(0, 0, db.width, db.height, w, h);
  // Lighten so the paths stand out.
  b.image.convertTo(b.image, CV_8U, 0.6, 90);
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

void WriteRunOutputs(const fs::path& dir, int run, nav::Mission& m, const Background* bg,
                     const nav::MissionOptions& o, const nav::MissionResult& r) {
  fs::create_directories(dir);
  io::WriteFileAtomically((dir / "steps.csv").string(), StepsCsv(r));
  const RunPaths p = Paths(r);
  const std::vector<report::GeoLine> lines = {
      {"true path", p.truth, kTruth.Hex(), {{"run", std::to_string(run)}}},
      {"estimated path", p.estimate, kEstimate.Hex(), {{"run", std::to_string(run)}}}};
  const std::vector<report::GeoPoint> points = {
      {"start", o.start}, {"target", o.target}, {"end", r.steps.back().truth}};
  io::WriteFileAtomically((dir / "paths.geojson").string(), report::ToGeoJson(lines, points));
  io::WriteFileAtomically((dir / "paths.kml").string(),
                          report::ToKml(fmt::format("optinav mission run {}", run), lines, points));
  if (!bg) return;
  report::MapPlot plot;
  plot.background = bg->image;
  plot.title = fmt::format("mission run {}: {} ({:.0f} m to target at the end)", run,
                           r.reached ? "reached" : "NOT reached", r.final_distance_m);
  int fixes = 0;
  for (const auto& l : r.steps) fixes += l.fix_accepted;
  plot.notes.push_back(
      fmt::format("{:.0f} m straight, {:.0f} m flown in {:.0f} s, {} steps, "
                  "{} accepted fixes",
                  r.straight_distance_m, r.flown_m, r.duration_s, r.steps.size(), fixes));
  plot.paths.push_back({"true path", kTruth, ToPicture(m, *bg, p.truth), 2.5});
  plot.paths.push_back({"estimated path", kEstimate, ToPicture(m, *bg, p.estimate), 1.5, true});
  const auto mark = [&](const std::string& label, const report::Rgb& c, const geo::LatLon& ll,
                        char shape) {
    plot.markers.push_back({label, c, m.locator().LatLonToPixel(ll) * bg->scale, shape});
  };
  mark("start", kStart, o.start, 'o');
  mark("target", kTarget, o.target, '*');
  // Label the end only when it is apart from the target (a reached target speaks for itself).
  mark(r.final_distance_m > 20 * m.map_gsd_m() / bg->scale ? "end" : "", kTruth,
       r.steps.back().truth, 'x');
  // Errors over time under the map (the paths overlap at map scale when all goes well).
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
  plot.chart = {sigma, est, fix};
  plot.chart_x_label = "time (s)";
  plot.chart_y_label = "error (m)";
  report::WriteMapPlot((dir / "path").string(), plot);
}

}  // namespace

int RunMissionExperiment(MissionExperiment& a) {
  if (a.runs < 1 || a.runs > 10000) throw Error("must be in [1, 10000]", {.field = "--runs"});
  if (a.pictures != "all" && a.pictures != "summary" && a.pictures != "none") {
    throw Error("expected all|summary|none, got '" + a.pictures + "'", {.field = "--pictures"});
  }
  sim::WeatherSpec weather = sim::ParseWeather(a.weather);
  weather.distance_scale = 0;  // nadir camera: scaled to the altitude (nav::MakeWeatherHook)
  const maploc::MapDatabase db = maploc::LoadMapDatabase(a.map);
  const std::string ortho = a.ortho.empty() ? db.ortho_path : a.ortho;
  if (!fs::exists(ortho)) {
    throw Error("the map's orthophoto is not there (moved? give --ortho)", {.file = ortho});
  }
  const geo::GeoRaster frames = geo::GeoRaster::Open(a.frames_from.empty() ? ortho : a.frames_from);
  maploc::LocateOptions lo;
  lo.ortho_path = ortho;
  nav::Mission mission(db, frames, lo);
  a.o.use_odometry = !a.no_odometry;

  // Start and target per run: fixed, or seeded random pairs.
  const bool random_start = a.start == "random", random_target = a.target == "random";
  if (random_start != random_target) {
    throw Error("give both --start and --target as LAT,LON, or both as 'random'",
                {.field = "--start"});
  }
  std::vector<std::pair<geo::LatLon, geo::LatLon>> legs;
  for (int i = 0; i < a.runs; ++i) {
    if (random_start) {
      legs.push_back(nav::RandomStartTarget(db, a.min_distance_m, a.margin_m, a.o.seed * 7919 + i));
    } else {
      legs.emplace_back(ParseLatLon(a.start, "--start"), ParseLatLon(a.target, "--target"));
    }
    nav::MissionOptions o = a.o;
    o.start = legs.back().first;
    o.target = legs.back().second;
    if (const std::string e = mission.Check(o); !e.empty()) throw Error(e);
  }
  io::PrepareOutputDir(a.out, a.force);
  const fs::path out(a.out);
  std::unique_ptr<Background> bg;
  if (a.pictures != "none") bg = std::make_unique<Background>(LoadBackground(db, ortho, 1000));

  spdlog::info("mission: {} run(s), map {} ({} tiles), frames from {}, speed {} m/s, step {} s",
               a.runs, a.map, db.tiles.size(), frames.path(), a.o.speed_m_s, a.o.step_s);
  ProgressBar bar(a.runs, "missions");
  std::vector<nav::MissionResult> results;
  std::vector<double> fix_errors, est_errors, finals, extraction, matching, estimation, fix_total,
      odometry, navigation, synthesis;
  int reached = 0, steps = 0, found = 0, accepted = 0;
  nlohmann::json runs_json = nlohmann::json::array();
  std::printf("%4s %9s %6s %8s %10s %8s %10s\n", "run", "dist_m", "steps", "reached", "final_m",
              "fix_rate", "fix_med_m");
  for (int i = 0; i < a.runs; ++i) {
    nav::MissionOptions o = a.o;
    o.start = legs[i].first;
    o.target = legs[i].second;
    o.seed = a.o.seed + i;
    o.weather = nav::MakeWeatherHook(weather, o.seed);
    o.keep_frames = a.save_frames;
    nav::MissionResult r = mission.Run(o);
    std::vector<double> run_fix;
    int run_found = 0;
    for (const nav::StepLog& l : r.steps) {
      ++steps;
      run_found += l.fix_found;
      accepted += l.fix_accepted;
      if (l.fix_found) {
        fix_errors.push_back(l.fix_error_m);
        run_fix.push_back(l.fix_error_m);
      }
      est_errors.push_back(l.estimate_error_m);
      extraction.push_back(l.times.extraction_ms);
      matching.push_back(l.times.matching_ms);
      estimation.push_back(l.times.estimation_ms);
      fix_total.push_back(l.times.extraction_ms + l.times.matching_ms + l.times.estimation_ms);
      odometry.push_back(l.times.odometry_ms);
      navigation.push_back(l.times.navigation_ms);
      synthesis.push_back(l.times.synthesis_ms);
    }
    found += run_found;
    reached += r.reached;
    finals.push_back(r.final_distance_m);
    const double run_fix_rate = static_cast<double>(run_found) / r.steps.size();
    std::printf("%4d %9.0f %6zu %8s %10.1f %8.2f %10.2f\n", i + 1, r.straight_distance_m,
                r.steps.size(), r.reached ? "yes" : "NO", r.final_distance_m, run_fix_rate,
                Quantile(run_fix, 0.5));
    const fs::path run_dir = out / fmt::format("run_{:03d}", i + 1);
    WriteRunOutputs(run_dir, i + 1, mission, a.pictures == "all" ? bg.get() : nullptr, o, r);
    if (a.save_frames) {
      fs::create_directories(run_dir / "frames");
      for (size_t k = 0; k < r.frames.size(); ++k) {
        const std::string f = (run_dir / "frames" / fmt::format("step_{:04d}.png", k)).string();
        if (!cv::imwrite(f, r.frames[k])) throw Error("cannot write frame", {.file = f});
      }
      r.frames.clear();
    }
    runs_json.push_back({{"run", i + 1},
                         {"start", {o.start.lat_deg, o.start.lon_deg}},
                         {"target", {o.target.lat_deg, o.target.lon_deg}},
                         {"straight_distance_m", r.straight_distance_m},
                         {"reached", r.reached},
                         {"end_reason", r.end_reason},
                         {"final_distance_m", r.final_distance_m},
                         {"flown_m", r.flown_m},
                         {"duration_s", r.duration_s},
                         {"steps", r.steps.size()},
                         {"fix_rate", run_fix_rate},
                         {"median_fix_error_m", MedianOrNull(run_fix)}});
    results.push_back(std::move(r));
    bar.Advance();
  }
  bar.Finish();

  auto row = [](const std::vector<double>& v) {
    const MeanStd s = Stats(v);
    return nlohmann::json{{"mean", s.mean}, {"std", s.std}};
  };
  const double nav_mean_ms = Stats(navigation).mean;
  nlohmann::json summary = {
      {"runs", a.runs},
      {"reached", reached},
      {"success_rate", static_cast<double>(reached) / a.runs},
      {"median_fix_error_m", MedianOrNull(fix_errors)},
      {"median_fix_error_map_px", MedianOrNull(fix_errors, db.map_gsd_m)},
      {"fix_rate", static_cast<double>(found) / steps},
      {"accepted_fix_rate", static_cast<double>(accepted) / steps},
      {"steps", steps},
      {"fix_error_m", ErrorStats(fix_errors)},
      {"estimate_error_m", ErrorStats(est_errors)},
      {"final_distance_m", ErrorStats(finals)},
      {"timing_ms",
       {{"feature_extraction", row(extraction)},
        {"matching", row(matching)},
        {"position_estimation", row(estimation)},
        {"localization", row(fix_total)},
        {"odometry", row(odometry)},
        {"navigation_step", row(navigation)},
        {"frame_synthesis", row(synthesis)}}},
      {"navigation_steps_per_second", nav_mean_ms > 0 ? 1000.0 / nav_mean_ms : 0.0},
      {"settings",
       {{"map", a.map},
        {"frames_from", frames.path()},
        {"map_gsd_m", db.map_gsd_m},
        {"speed_m_s", a.o.speed_m_s},
        {"altitude_m", a.o.altitude_m > 0 ? a.o.altitude_m : db.options.altitude_m},
        {"step_s", a.o.step_s},
        {"arrive_radius_m", a.o.arrive_radius_m},
        {"success_radius_m", a.o.success_radius_m},
        {"weather", weather.ToString()},
        {"odometry", a.o.use_odometry},
        {"wind_m_s", a.o.wind_m_s},
        {"compass_bias_deg", a.o.compass_bias_deg},
        {"seed", a.o.seed}}},
      {"per_run", runs_json}};
  io::WriteFileAtomically((out / "summary.json").string(), summary.dump(2) + "\n");

  // One GeoJSON/KML with every run, and the summary picture.
  std::vector<report::GeoLine> lines;
  std::vector<report::GeoPoint> points;
  report::MapPlot plot;
  if (bg) plot.background = bg->image;
  for (size_t i = 0; i < results.size(); ++i) {
    const RunPaths p = Paths(results[i]);
    const std::string run = std::to_string(i + 1);
    lines.push_back({"true path " + run, p.truth, kTruth.Hex(), {{"run", run}}});
    lines.push_back({"estimated path " + run, p.estimate, kEstimate.Hex(), {{"run", run}}});
    points.push_back({"start " + run, legs[i].first});
    points.push_back({"target " + run, legs[i].second});
    if (bg) {
      plot.paths.push_back(
          {i == 0 ? "true paths" : "", kTruth, ToPicture(mission, *bg, p.truth), 2});
      plot.paths.push_back({i == 0 ? "estimated paths" : "", kEstimate,
                            ToPicture(mission, *bg, p.estimate), 1, true});
      plot.markers.push_back(
          {"", kStart, mission.locator().LatLonToPixel(legs[i].first) * bg->scale, 'o'});
      plot.markers.push_back({results[i].reached ? "" : "missed " + run, kTarget,
                              mission.locator().LatLonToPixel(legs[i].second) * bg->scale, '*'});
    }
  }
  io::WriteFileAtomically((out / "paths.geojson").string(), report::ToGeoJson(lines, points));
  io::WriteFileAtomically((out / "paths.kml").string(),
                          report::ToKml("optinav mission runs", lines, points));
  if (bg) {
    plot.title = fmt::format("{} mission(s): {} reached the target (within {:.0f} m)", a.runs,
                             reached, a.o.success_radius_m);
    plot.notes.push_back(fmt::format(
        "map {}, frames {}, {} m/s, weather {}; median fix error {:.1f} m, fix rate {:.0f} %",
        fs::path(db.ortho_path).filename().string(), fs::path(frames.path()).filename().string(),
        a.o.speed_m_s, weather.ToString(), Quantile(fix_errors, 0.5), 100.0 * found / steps));
    plot.notes.push_back("o start   * target   (blue circles, red stars)");
    report::WriteMapPlot((out / "summary").string(), plot);
  }

  const MeanStd ex = Stats(extraction), ma = Stats(matching), es = Stats(estimation),
                lz = Stats(fix_total), od = Stats(odometry), nv = Stats(navigation);
  std::printf(
      "\nreached %d/%d (within %.0f m); final distance median %.1f m, max %.1f m\n"
      "fixes: %.1f %% of %d steps found, %.1f %% accepted; fix error median %.2f m (%.2f map "
      "px), p95 %.2f m\n"
      "estimate error: median %.2f m, p95 %.2f m, max %.2f m\n\n"
      "timing per step (ms, mean +- std)      optinav        document (ORB, s)\n"
      "  feature extraction                %7.2f +- %-6.2f   0.113 +- 0.029\n"
      "  matching                          %7.2f +- %-6.2f   0.313 +- 0.048\n"
      "  position estimation               %7.2f +- %-6.2f\n"
      "  localization (the three)          %7.2f +- %-6.2f   0.507 +- 0.152\n"
      "  frame-to-frame odometry           %7.2f +- %-6.2f\n"
      "  navigation step (all of it)       %7.2f +- %-6.2f   -> %.0f steps/s on one core\n"
      "wrote %s/summary.json, summary.png/.svg, paths.geojson/.kml, run_NNN/\n",
      reached, a.runs, a.o.success_radius_m, Quantile(finals, 0.5),
      *std::max_element(finals.begin(), finals.end()), 100.0 * found / steps, steps,
      100.0 * accepted / steps, Quantile(fix_errors, 0.5), Quantile(fix_errors, 0.5) / db.map_gsd_m,
      Quantile(fix_errors, 0.95), Quantile(est_errors, 0.5), Quantile(est_errors, 0.95),
      *std::max_element(est_errors.begin(), est_errors.end()), ex.mean, ex.std, ma.mean, ma.std,
      es.mean, es.std, lz.mean, lz.std, od.mean, od.std, nv.mean, nv.std,
      nv.mean > 0 ? 1000.0 / nv.mean : 0.0, a.out.c_str());
  return reached == a.runs ? 0 : 3;
}

int RunMission(int argc, char** argv) {
  CLI::App app{
      "Fly GNSS-denied missions to a target over an orthophoto map: camera frames are "
      "synthesised at the true pose, localized against the map database, blended with "
      "frame-to-frame odometry, and the drone turns towards the target."};
  app.name("optinav mission");
  MissionExperiment a;
  std::string log_level = "info";
  app.add_option("--map", a.map, "map database (optinav map build)")->required();
  app.add_option("--start", a.start, "start LAT,LON, or 'random'")->required();
  app.add_option("--target", a.target, "target LAT,LON, or 'random'")->required();
  app.add_option("--out", a.out, "output folder")->required();
  app.add_flag("--force", a.force, "write into a non-empty output folder");
  app.add_option("--runs", a.runs, "number of runs (seeds seed..seed+runs-1)")
      ->capture_default_str();
  app.add_option("--seed", a.o.seed, "first seed")->capture_default_str();
  app.add_option("--speed", a.o.speed_m_s, "ground speed (m/s)")->capture_default_str();
  app.add_option("--altitude", a.o.altitude_m, "altitude above ground (m; default: the map's)");
  app.add_option("--step", a.o.step_s, "time between frames (s)")->capture_default_str();
  app.add_option("--frames-from", a.frames_from,
                 "synthesise frames from another orthophoto of the area (e.g. a later year)");
  app.add_option("--ortho", a.ortho, "the map's orthophoto, if moved since the build");
  app.add_option("--weather", a.weather, "none | fog:50 | dust:50 | ...")->capture_default_str();
  app.add_option("--min-distance", a.min_distance_m, "random start/target: at least this far (m)")
      ->capture_default_str();
  app.add_option("--margin", a.margin_m, "random start/target: distance from the map edge (m)")
      ->capture_default_str();
  app.add_option("--arrive-radius", a.o.arrive_radius_m,
                 "the mission ends when the estimate is this close to the target (m)")
      ->capture_default_str();
  app.add_option("--success-radius", a.o.success_radius_m,
                 "a run succeeds when the true drone ends this close (m)")
      ->capture_default_str();
  app.add_option("--time-limit", a.o.time_limit_s, "seconds (0: 3x straight-line time + 120 s)")
      ->capture_default_str();
  app.add_option("--wind", a.o.wind_m_s, "constant wind speed, seeded direction (m/s)")
      ->capture_default_str();
  app.add_option("--compass-bias", a.o.compass_bias_deg, "heading-hold error, +- deg per run")
      ->capture_default_str();
  app.add_option("--tilt", a.o.effects.max_tilt_deg, "max camera tilt (deg)")
      ->capture_default_str();
  app.add_option("--blur", a.o.effects.motion_blur_px, "max motion blur (px)")
      ->capture_default_str();
  app.add_option("--exposure", a.o.effects.exposure_variation, "exposure change (+- fraction)")
      ->capture_default_str();
  app.add_option("--altitude-variation", a.o.effects.altitude_variation,
                 "altitude change (+- fraction)")
      ->capture_default_str();
  app.add_flag("--no-odometry", a.no_odometry,
               "the document's loop: fixes only, keep the last bearing when a fix fails");
  app.add_option("--pictures", a.pictures, "all | summary | none")->capture_default_str();
  app.add_flag("--save-frames", a.save_frames, "write every camera frame to run_NNN/frames/");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error")->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    SetLogLevel(log_level);
    return RunMissionExperiment(a);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}

}  // namespace optinav
