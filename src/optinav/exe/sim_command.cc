// optinav sim: synthetic stereo + IMU + GNSS sequences with weather, in EuRoC or AirSim format
// (issue 4). `optinav sim suite` writes the weather document's 36 sequences.
#include <cstdio>
#include <filesystem>
#include <memory>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "optinav/exe/commands.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/logging.h"
#include "optinav/util/progress.h"
#include "optinav/util/timer.h"

namespace optinav {
namespace {

// The raw command-line values, converted into SimulationOptions by Build().
struct SimArgs {
  std::string world = "urban", route = "car", weather = "none", format = "euroc", out;
  double duration_s = 0, speed = 5, altitude = 20, scale = 1;
  uint64_t seed = 1;
  double gnss_rate = 5, gnss_sigma = 1;
  std::string gnss_outliers;
  std::vector<std::string> gnss_outages;
  bool force = false;

  // Throws optinav::Error naming the option on any invalid value.
  sim::SimulationOptions Build() const {
    sim::SimulationOptions o;
    o.world = sim::ParseWorld(world);
    o.weather = sim::ParseWeather(weather);
    o.route = route;
    if (format == "euroc") {
      o.format = sim::DatasetFormat::kEuroc;
    } else if (format == "airsim") {
      o.format = sim::DatasetFormat::kAirsim;
    } else {
      throw Error(fmt::format("unknown format '{}' (euroc or airsim)", format),
                  {.field = "--format"});
    }
    o.out_dir = out;
    o.duration_s = duration_s;
    o.speed_m_s = speed;
    o.altitude_m = altitude;
    o.scale = scale;
    o.seed = seed;
    o.force = force;
    o.gnss.rate_hz = gnss_rate;
    o.gnss.sigma_m = gnss_sigma;
    if (!gnss_outliers.empty()) {
      const auto [fraction, magnitude] = sim::ParseOutlierSpec(gnss_outliers, "--gnss-outliers");
      o.gnss.outlier_fraction = fraction;
      o.gnss.outlier_magnitude_m = magnitude;
    }
    for (const std::string& s : gnss_outages) {
      o.gnss.outages.push_back(sim::ParseOutageSpec(s, "--gnss-outage"));
    }
    if (const std::string m = o.Check(); !m.empty()) throw Error(m);
    return o;
  }
};

void AddCommonOptions(CLI::App& app, SimArgs& a) {
  app.add_option("--out", a.out, "output folder (must not exist or be empty)")->required();
  app.add_option("--format", a.format, "euroc | airsim")->capture_default_str();
  app.add_option("--duration", a.duration_s,
                 "seconds to simulate (0: the whole car route; 60 s "
                 "for drones)")
      ->capture_default_str();
  app.add_option("--seed", a.seed, "random seed (same seed: byte-identical output)")
      ->capture_default_str();
  app.add_option("--scale", a.scale, "image size factor, e.g. 0.5 for half resolution")
      ->capture_default_str();
  app.add_flag("--force", a.force, "replace the contents of a non-empty output folder");
}

int Fail(const Error& e, int code) {
  spdlog::error("{}", e.what());
  return code;
}

int RunSuite(int argc, char** argv) {
  CLI::App app{"Write the weather document's 36 sequences (24 urban, 12 terrain)",
               "optinav sim suite"};
  SimArgs a;
  a.format = "airsim";
  AddCommonOptions(app, a);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(a.out, ec) && !fs::is_empty(a.out, ec) && !a.force) {
    return Fail(Error("output folder exists and is not empty (use --force to replace its "
                      "contents)",
                      {.file = a.out, .field = "out"}),
                1);
  }
  const auto suite = sim::WeatherSuite();
  Timer timer;
  size_t frames = 0;
  for (size_t i = 0; i < suite.size(); ++i) {
    SimArgs s = a;
    s.out = (fs::path(a.out) / suite[i].name).string();
    sim::SimulationOptions o;
    try {
      o = s.Build();
    } catch (const Error& e) {
      return Fail(e, 2);
    }
    o.world.kind = suite[i].world;
    o.weather = suite[i].weather;
    o.force = true;  // the suite folder as a whole was checked above
    std::unique_ptr<ProgressBar> bar;
    try {
      const sim::SimulationSummary sum = sim::RunSimulation(o, [&](size_t, size_t total) {
        if (!bar) {
          bar = std::make_unique<ProgressBar>(
              total, fmt::format("[{}/{}] {}", i + 1, suite.size(), suite[i].name));
        }
        bar->Advance();
      });
      if (bar) bar->Finish();
      frames += sum.frames;
      std::printf("%-24s %5zu stereo frames, %.0f m, %.1f s\n", suite[i].name.c_str(), sum.frames,
                  sum.path_length_m, sum.wall_s);
      std::fflush(stdout);
    } catch (const Error& e) {
      return Fail(e, 1);
    }
  }
  std::printf("suite: %zu sequences, %zu stereo frames in %.1f s -> %s\n", suite.size(), frames,
              timer.ElapsedSeconds(), a.out.c_str());
  return 0;
}

}  // namespace

int RunSim(int argc, char** argv) {
  if (argc >= 2 && std::string(argv[1]) == "suite") {
    std::string program = "optinav sim suite";
    argv[1] = program.data();
    return RunSuite(argc - 1, argv + 1);
  }
  CLI::App app{
      "Simulate a stereo + IMU + GNSS sequence with weather (EuRoC or AirSim format).\n"
      "`optinav sim suite --out DIR` writes the weather document's 36 sequences.",
      "optinav sim"};
  SimArgs a;
  app.add_option("--world", a.world, "urban | terrain | ortho:GEOTIFF")->capture_default_str();
  app.add_option("--route", a.route,
                 "car (the document's route) | drone (seeded random) | "
                 "drone:FILE (x, y, altitude[, yaw_deg] per line)")
      ->capture_default_str();
  app.add_option("--weather", a.weather,
                 "none | KIND:PERCENT, KIND = rain snow leaves fog dust road-wetness road-snow "
                 "road-leaves, PERCENT 0-100")
      ->capture_default_str();
  AddCommonOptions(app, a);
  app.add_option("--speed", a.speed, "drone speed (m/s)")->capture_default_str();
  app.add_option("--altitude", a.altitude, "drone altitude above ground (m)")
      ->capture_default_str();
  app.add_option("--gnss-rate", a.gnss_rate, "GNSS rate (Hz)")->capture_default_str();
  app.add_option("--gnss-sigma", a.gnss_sigma, "GNSS noise sigma per axis (m)")
      ->capture_default_str();
  app.add_option("--gnss-outliers", a.gnss_outliers, "FRACTION:MAGNITUDE_M, e.g. 0.05:20");
  app.add_option("--gnss-outage", a.gnss_outages,
                 "START_S:DURATION_S, no GNSS in that window (repeatable)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  sim::SimulationOptions o;
  try {
    o = a.Build();
  } catch (const Error& e) {
    return Fail(e, 2);
  }
  try {
    std::unique_ptr<ProgressBar> bar;
    const sim::SimulationSummary s = sim::RunSimulation(o, [&](size_t, size_t total) {
      if (!bar) bar = std::make_unique<ProgressBar>(total, "sim");
      bar->Advance();
    });
    if (bar) bar->Finish();
    std::printf(
        "optinav sim: %s world (%zu triangles), %s route %.0f m in %.1f s, weather %s: %zu "
        "stereo frames %dx%d, %zu IMU, %zu GNSS samples -> %s (%s) in %.1f s\n",
        a.world.c_str(), s.world_triangles, a.route.c_str(), s.path_length_m, s.duration_s,
        o.weather.ToString().c_str(), s.frames, s.width, s.height, s.imu_samples, s.gnss_samples,
        o.out_dir.c_str(), a.format.c_str(), s.wall_s);
  } catch (const Error& e) {
    return Fail(e, 1);
  }
  return 0;
}

}  // namespace optinav
