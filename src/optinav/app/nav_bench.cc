#include "optinav/app/nav_bench.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <random>
#include <thread>

#include <fmt/format.h>

#include "optinav/app/nav_run.h"
#include "optinav/geo/raster.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/maploc/map_db.h"
#include "optinav/report/map_plot.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/error.h"

namespace optinav::app {

namespace fs = std::filesystem;

const std::vector<std::string>& NavBenchConfigs() {
  static const std::vector<std::string> configs = {"map",        "fog50",  "gap60",
                                                   "outliers10", "no-map", "gnss3"};
  return configs;
}

std::string NavBenchOptions::Check() const {
  if (out_dir.empty()) return "--out is required";
  if (map_ortho.empty() || flight_ortho.empty())
    return "--map-ortho and --flight-ortho are required";
  if (flights < 1 || flights > 20) return "--flights must be in [1, 20]";
  if (!(flight_length_m >= 500 && flight_length_m <= 20000))
    return "--flight-length must be in [500, 20000] m";
  if (jobs < 1) return "--jobs must be >= 1";
  if (!(fix_rate_hz >= 0)) return "--fix-rate must be >= 0";
  if (configs.empty()) return "--configs needs at least one configuration";
  for (const std::string& c : configs)
    if (std::find(NavBenchConfigs().begin(), NavBenchConfigs().end(), c) == NavBenchConfigs().end())
      return "--configs: unknown configuration '" + c +
             "' (map, fog50, gap60, outliers10, no-map, gnss3)";
  return "";
}

namespace {

constexpr double kGapStartS = 40, kGapDurationS = 60;

// A seeded flight plan inside the orthophoto (world ENU about its centre): waypoints every
// ~250 m, heading turning up to +-45 deg per waypoint and bouncing off the borders, altitude
// 350-600 m changing at most 60 m per waypoint.
std::vector<Eigen::Vector3d> FlightPlan(const Eigen::Vector2d& half_extent, double length_m,
                                        uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  const Eigen::Vector2d limit = half_extent - Eigen::Vector2d(700, 700);
  Eigen::Vector2d p(limit.x() * (2 * u(rng) - 1) * 0.5, limit.y() * (2 * u(rng) - 1) * 0.5);
  double heading = 2 * M_PI * u(rng);
  double altitude = 350 + 250 * u(rng);
  std::vector<Eigen::Vector3d> plan{{p.x(), p.y(), altitude}};
  const double step = 250;
  for (double flown = 0; flown < length_m; flown += step) {
    heading += (u(rng) - 0.5) * M_PI / 2;
    for (int tries = 0; tries < 16; ++tries) {
      const Eigen::Vector2d next = p + step * Eigen::Vector2d(std::cos(heading), std::sin(heading));
      if (std::abs(next.x()) <= limit.x() && std::abs(next.y()) <= limit.y()) break;
      heading += M_PI / 4;  // turn away from the border
    }
    p += step * Eigen::Vector2d(std::cos(heading), std::sin(heading));
    p = p.cwiseMax(-limit).cwiseMin(limit);
    altitude = std::clamp(altitude + (u(rng) - 0.5) * 120, 350.0, 600.0);
    plan.emplace_back(p.x(), p.y(), altitude);
  }
  return plan;
}

struct Flight {
  std::string name;  // flight1, flight1_fog50
  std::string dir;
  double speed_m_s = 20;
  Eigen::Vector2d wind_m_s = Eigen::Vector2d::Zero();  // east, north
};

// Multirotor air drag of the flights (1/s): with the flights' 15-25 m/s and 3-6 m/s of wind the
// drone leans 9-13 deg (median) into its air speed, up to 16-20 deg on the fastest stretches
// (bench/RESULTS.md, 2026-11-29; SimulationOptions::drag_per_s).
constexpr double kFlightDragPerS = 0.1;

// The largest tilt (body z from the vertical, deg) of a rendered flight's ground truth.
double MaxTiltDeg(const std::string& flight_dir) {
  const Trajectory gt =
      io::ReadTrajectory(flight_dir + "/mav0/state_groundtruth_estimate0/data.csv");
  double worst = 0;
  for (const Eigen::Matrix3d& r : gt.rotations)
    worst = std::max(worst, std::acos(std::clamp(r(2, 2), -1.0, 1.0)) * 180 / M_PI);
  return worst;
}

// Renders a flight unless complete (reuse).
void RenderFlight(const NavBenchOptions& o, const std::string& waypoints, const Flight& f, bool fog,
                  uint64_t seed) {
  sim::SimulationOptions s;
  s.world.kind = sim::WorldKind::kOrtho;
  s.world.ortho_path = o.flight_ortho;
  s.route = "drone:" + waypoints;
  s.speed_m_s = f.speed_m_s;
  s.drag_per_s = kFlightDragPerS;
  s.wind_m_s = f.wind_m_s;
  s.scale = 0.25;  // the stereo pair is not used by nav: keep it small
  s.seed = seed;
  s.out_dir = f.dir;
  s.force = true;
  s.gnss.sigma_m = 3.0;
  s.nadir.enabled = true;
  s.baro.enabled = true;
  if (fog) {
    s.weather.kind = sim::WeatherKind::kFog;
    s.weather.intensity = 0.5;
    s.weather.distance_scale = 475.0 / 20;  // the simulator's advice for a nadir camera
  }
  if (o.reuse && sim::IsRenderingOf(f.dir, s)) return;
  sim::RunSimulation(s);
}

NavBenchRun RunOne(const NavBenchOptions& o, const std::string& map_path, const Flight& flight,
                   const std::string& config, const fs::path& runs_dir) {
  NavBenchRun run;
  run.flight = flight.name;
  run.config = config;
  NavRunSettings st;
  st.dataset = flight.dir;
  st.map_path = map_path;
  st.nav.fix_rate_hz = o.fix_rate_hz;
  st.nav.drag_per_s = o.drag ? kFlightDragPerS : 0.0;  // the drones' calibrated drag
  const std::string stem = (runs_dir / (flight.name + "_" + config)).string();
  st.out = stem + ".tum";
  st.stats_path = stem + ".json";
  if (config == "gap60") st.blank.emplace_back(kGapStartS, kGapDurationS);
  if (config == "outliers10") {
    st.nav.inject_outlier_fraction = 0.1;
    st.nav.outlier_seed = o.seed;
  }
  if (config == "no-map" || config == "gnss3") {
    st.no_map = true;
    st.nav.start = ReadSimTruth(flight.dir).value().Start();
    st.gnss = config == "gnss3";
    st.gnss_sigma_m = 3.0;
  }
  try {
    const NavRunReport r = RunNav(st);
    run.ok = r.error.has_value();
    if (!r.error) run.error = "no ground truth";
    if (r.error) {
      run.rmse_m = r.error->rmse_m;
      run.max_m = r.error->max_m;
      run.final_m = r.error->final_m;
      run.altitude_rmse_m = r.error->altitude_rmse_m;
    }
    run.realtime_factor = r.wall_s > 0 ? r.duration_s / r.wall_s : 0;
    run.duration_s = r.duration_s;
    run.fixes_tried = r.stats.fixes_tried;
    run.fixes_accepted = r.stats.fixes_accepted;
    run.outliers_injected = r.stats.outliers_injected;
    run.outliers_accepted = r.stats.outliers_accepted;
    if (!r.poses.empty())
      run.initialised_after_s = (r.poses.front().t_ns - r.first_frame_ns) * 1e-9;
    if (config == "gap60" && !r.errors_m.empty()) {
      // Gap times relative to the first nadir frame (the blanking's reference).
      const int64_t gap_end =
          r.first_frame_ns + static_cast<int64_t>((kGapStartS + kGapDurationS) * 1e9);
      std::optional<int64_t> first_fix;  // found (the confirmation may accept only the next)
      for (const nav::FixLog& f : r.fixes)
        if (f.found && f.t_ns >= gap_end) {
          first_fix = f.t_ns;
          break;
        }
      for (size_t i = 0; i < r.error_t_ns.size(); ++i) {
        if (r.error_t_ns[i] < gap_end) run.gap_end_error_m = r.errors_m[i];
        if (first_fix && run.recovery_s < 0 && r.error_t_ns[i] >= *first_fix &&
            r.errors_m[i] < 10.0)
          run.recovery_s = (r.error_t_ns[i] - *first_fix) * 1e-9;
      }
    }
  } catch (const std::exception& e) {
    run.ok = false;
    run.error = e.what();
  }
  return run;
}

std::string Cell(double v, int digits = 1) {
  return std::isfinite(v) && v >= 0 ? fmt::format("{:.{}f}", v, digits) : "-";
}

// Paths on the orthophoto and the error over time of one flight's runs.
void WriteFlightPlot(const NavBenchOptions& o, const maploc::MapDatabase& db, const Flight& flight,
                     const std::vector<NavBenchRun>& runs, const fs::path& runs_dir,
                     const fs::path& out_stem) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(o.flight_ortho);
  const double scale = std::min(1.0, 900.0 / std::max(db.width, db.height));
  report::MapPlot plot;
  plot.background =
      raster.ReadGray(0, 0, db.width, db.height, std::max(1, static_cast<int>(db.width * scale)),
                      std::max(1, static_cast<int>(db.height * scale)));
  plot.background.convertTo(plot.background, CV_8U, 0.6, 90);
  plot.title = fmt::format("optinav bench nav: {} (map NAIP 2009, frames 2017)", flight.name);
  const geo::CrsTransform crs(db.crs_wkt);
  const geo::LatLon origin =
      crs.ToLatLon(db.transform.PixelToCrs(Eigen::Vector2d(db.width / 2.0, db.height / 2.0)));
  const geo::LocalEnu enu(origin, 0.0);
  auto to_px = [&](const Eigen::Vector3d& p) {
    return Eigen::Vector2d(db.transform.CrsToPixel(crs.FromLatLon(enu.FromEnu(p))) * scale);
  };
  // Truth: the ground truth in the simulator's frame, through lat/lon (read once per flight).
  const SimTruth sim = ReadSimTruth(flight.dir).value();
  const geo::LocalEnu sim_enu(sim.origin, 0.0);
  const Trajectory& gt = sim.groundtruth;
  {
    report::MapPath truth{"truth", {20, 160, 60}, {}, 2.5, false};
    for (size_t i = 0; i < gt.size(); i += 50) {
      const Eigen::Vector3d p = enu.ToEnu(sim_enu.FromEnu(gt.positions[i]), 0.0);
      truth.px.push_back(to_px(p));
    }
    plot.paths.push_back(truth);
  }
  const report::Rgb colours[] = {{230, 110, 20}, {40, 90, 220}, {200, 40, 200},
                                 {120, 70, 20},  {90, 90, 90},  {0, 160, 170}};
  int k = 0;
  plot.chart_x_label = "time (s)";
  plot.chart_y_label = "horizontal error (m)";
  for (const NavBenchRun& r : runs) {
    if (r.flight != flight.name && r.flight != flight.name + "_fog50") continue;
    const report::Rgb c = colours[k++ % 6];
    const fs::path stem = runs_dir / (r.flight + "_" + r.config);
    if (!fs::exists(stem.string() + ".tum")) continue;
    const Trajectory est = io::ReadTrajectory(stem.string() + ".tum");
    // Each run's ENU origin (the map's centre; the start for the runs without a map).
    geo::LatLon run_origin = origin;
    if (std::ifstream stats(stem.string() + ".json"); stats) {
      const nlohmann::json js = nlohmann::json::parse(stats);
      run_origin = {js["origin"][0].get<double>(), js["origin"][1].get<double>()};
    }
    const geo::LocalEnu run_enu(run_origin, 0.0);
    auto in_map_enu = [&](const Eigen::Vector3d& p) {
      return enu.ToEnu(run_enu.FromEnu(Eigen::Vector3d(p.x(), p.y(), 0)), 0.0);
    };
    report::MapPath path{r.config, c, {}, 1.5, r.config != "map"};
    for (size_t i = 0; i < est.size(); i += 5)
      path.px.push_back(to_px(in_map_enu(est.positions[i])));
    plot.paths.push_back(path);
    // The error series from the run's statistics is not stored per pose; recompute from the
    // trajectory against the truth at its stamps.
    report::ChartSeries series{r.config + (r.config == "gap60" ? " (blank 40-100 s)" : ""), c};
    size_t g = 0;
    for (size_t i = 0; i < est.size(); ++i) {
      while (g + 1 < gt.size() && gt.t_ns[g] < est.t_ns[i]) ++g;
      const Eigen::Vector3d truth = enu.ToEnu(sim_enu.FromEnu(gt.positions[g]), 0.0);
      series.x.push_back((est.t_ns[i] - gt.t_ns.front()) * 1e-9);
      series.y.push_back((in_map_enu(est.positions[i]).head<2>() - truth.head<2>()).norm());
    }
    plot.chart.push_back(series);
  }
  report::WriteMapPlot(out_stem.string(), plot);
}

}  // namespace

NavBenchResult RunNavBench(const NavBenchOptions& o,
                           const std::function<void(const std::string&)>& progress) {
  const std::string problem = o.Check();
  if (!problem.empty()) throw Error(problem);
  const fs::path out(o.out_dir), flights_dir = out / "flights", runs_dir = out / "runs";
  fs::create_directories(flights_dir);
  fs::create_directories(runs_dir);

  // The map: NAIP 2009 as issue 20 specifies it (256x256, 90 deg, 640 m).
  const std::string map_path = (out / "map.db").string();
  if (!o.reuse || !fs::exists(map_path)) {
    maploc::MapBuildOptions mb;
    mb.frame_width = mb.frame_height = 256;
    mb.hfov_deg = 90;
    mb.altitude_m = 640;
    maploc::BuildMapDatabase(o.map_ortho, mb, map_path);
  }
  const maploc::MapDatabase db = maploc::LoadMapDatabase(map_path);
  const double gsd = db.map_gsd_m;
  const Eigen::Vector2d half_extent(db.width * gsd / 2, db.height * gsd / 2);

  // Flights (and their fog versions when asked for).
  const bool want_fog = std::find(o.configs.begin(), o.configs.end(), "fog50") != o.configs.end();
  std::vector<Flight> clear, fog;
  std::mt19937_64 speed_rng(o.seed), wind_rng(o.seed + 7919);
  for (int i = 1; i <= o.flights; ++i) {
    const uint64_t seed = o.seed * 1000 + i;
    const std::string name = fmt::format("flight{}", i);
    const std::string waypoints = (flights_dir / (name + ".waypoints.txt")).string();
    std::string text = "# optinav bench nav flight plan: x east, y north (m), altitude (m)\n";
    for (const Eigen::Vector3d& w : FlightPlan(half_extent, o.flight_length_m, seed))
      text += fmt::format("{:.1f}, {:.1f}, {:.1f}\n", w.x(), w.y(), w.z());
    io::WriteFileAtomically(waypoints, text);
    const double speed = std::uniform_real_distribution<double>(15, 25)(speed_rng);
    const double wind_from = std::uniform_real_distribution<double>(0, 2 * M_PI)(wind_rng);
    const double wind_speed = std::uniform_real_distribution<double>(3, 6)(wind_rng);
    // Blowing from `wind_from` (clockwise from north, as a wind is named) towards the opposite.
    const Eigen::Vector2d wind =
        -wind_speed * Eigen::Vector2d(std::sin(wind_from), std::cos(wind_from));
    clear.push_back({name, (flights_dir / name).string(), speed, wind});
    RenderFlight(o, waypoints, clear.back(), false, seed);
    if (progress) {
      progress(fmt::format(
          "rendered {} ({:.0f} m/s, wind {:.1f} m/s from {:.0f} deg, tilt up to "
          "{:.1f} deg)",
          name, speed, wind_speed, wind_from * 180 / M_PI, MaxTiltDeg(clear.back().dir)));
    }
    if (want_fog) {
      fog.push_back({name + "_fog50", (flights_dir / (name + "_fog50")).string(), speed, wind});
      RenderFlight(o, waypoints, fog.back(), true, seed);
      if (progress) progress(fmt::format("rendered {}_fog50", name));
    }
  }

  // Runs, `jobs` at a time.
  struct Task {
    Flight flight;
    std::string config;
  };
  std::vector<Task> tasks;
  for (int i = 0; i < o.flights; ++i)
    for (const std::string& c : o.configs) tasks.push_back({c == "fog50" ? fog[i] : clear[i], c});
  std::vector<NavBenchRun> runs(tasks.size());
  std::atomic<size_t> next{0};
  std::mutex mutex;
  auto worker = [&] {
    for (size_t k; (k = next++) < tasks.size();) {
      runs[k] = RunOne(o, map_path, tasks[k].flight, tasks[k].config, runs_dir);
      std::lock_guard<std::mutex> lock(mutex);
      if (progress)
        progress(runs[k].ok ? fmt::format("{} {}: RMSE {:.2f} m, max {:.2f} m ({:.1f}x real time)",
                                          runs[k].flight, runs[k].config, runs[k].rmse_m,
                                          runs[k].max_m, runs[k].realtime_factor)
                            : fmt::format("{} {}: failed: {}", runs[k].flight, runs[k].config,
                                          runs[k].error));
    }
  };
  std::vector<std::thread> threads;
  for (int j = 0; j < std::min<int>(o.jobs, static_cast<int>(tasks.size())); ++j)
    threads.emplace_back(worker);
  for (auto& t : threads) t.join();

  NavBenchResult result;
  result.runs = runs;
  std::string md =
      "| flight | config | RMSE (m) | max (m) | final (m) | altitude RMSE (m) | real time | fixes "
      "accepted / tried | outliers accepted / injected | gap end error (m) | back < 10 m after "
      "(s) | first estimate at (s) |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const NavBenchRun& r : runs) {
    if (!r.ok) {
      md += fmt::format("| {} | {} | failed: {} ||||||||||\n", r.flight, r.config, r.error);
      continue;
    }
    md += fmt::format(
        "| {} | {} | {} | {} | {} | {} | {:.1f}x | {} / {} | {} | {} | {} | {} |\n", r.flight,
        r.config, Cell(r.rmse_m, 2), Cell(r.max_m), Cell(r.final_m), Cell(r.altitude_rmse_m, 2),
        r.realtime_factor, r.fixes_accepted, r.fixes_tried,
        r.config == "outliers10" ? fmt::format("{} / {}", r.outliers_accepted, r.outliers_injected)
                                 : "-",
        Cell(r.gap_end_error_m), Cell(r.recovery_s), Cell(r.initialised_after_s));
  }
  // Per configuration over all flights: RMSE over all poses (from the per-flight RMSEs weighted by
  // duration), worst max.
  md +=
      "\n| config | RMSE over flights (m) | worst max (m) | altitude RMSE (m) | slowest real time "
      "|\n|---|---|---|---|---|\n";
  for (const std::string& c : o.configs) {
    double sum2 = 0, dur = 0, worst = 0, alt2 = 0, slowest = 1e9;
    for (const NavBenchRun& r : runs) {
      if (r.config != c || !r.ok) continue;
      sum2 += r.rmse_m * r.rmse_m * r.duration_s;
      alt2 += r.altitude_rmse_m * r.altitude_rmse_m * r.duration_s;
      dur += r.duration_s;
      worst = std::max(worst, r.max_m);
      slowest = std::min(slowest, r.realtime_factor);
    }
    if (dur <= 0) continue;
    md += fmt::format("| {} | {:.2f} | {:.1f} | {:.2f} | {:.1f}x |\n", c, std::sqrt(sum2 / dur),
                      worst, std::sqrt(alt2 / dur), slowest);
  }
  result.table_md = md;
  io::WriteFileAtomically((out / "table.md").string(), md);
  io::WriteFileAtomically((out / "results.json").string(), result.ToJson().dump(2) + "\n");
  for (const Flight& f : clear)
    WriteFlightPlot(o, db, f, runs, runs_dir, out / (f.name + "_paths"));
  return result;
}

nlohmann::json NavBenchResult::ToJson() const {
  nlohmann::json j;
  j["generator"] = "optinav bench nav";
  nlohmann::json rows = nlohmann::json::array();
  for (const NavBenchRun& r : runs) {
    rows.push_back({{"flight", r.flight},
                    {"config", r.config},
                    {"ok", r.ok},
                    {"error", r.error},
                    {"rmse_m", r.rmse_m},
                    {"max_m", r.max_m},
                    {"final_m", r.final_m},
                    {"altitude_rmse_m", r.altitude_rmse_m},
                    {"realtime_factor", r.realtime_factor},
                    {"duration_s", r.duration_s},
                    {"fixes_tried", r.fixes_tried},
                    {"fixes_accepted", r.fixes_accepted},
                    {"outliers_injected", r.outliers_injected},
                    {"outliers_accepted", r.outliers_accepted},
                    {"gap_end_error_m", r.gap_end_error_m},
                    {"recovery_s", r.recovery_s},
                    {"initialised_after_s", r.initialised_after_s}});
  }
  j["runs"] = rows;
  return j;
}

}  // namespace optinav::app
