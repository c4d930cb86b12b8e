// optinav sim: synthetic stereo + IMU + GNSS sequences with weather, in EuRoC or AirSim format
// (issue 4). `optinav sim suite` writes the weather suite: 36 sequences, 24 urban and 12 terrain.
#include <cstdio>
#include <tuple>

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <fmt/format.h>

#include "optinav/app/sim_suite.h"
#include "optinav/exe/cli_common.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/timer.h"

namespace optinav {
namespace {

// The raw flag values, turned into SimulationOptions by ToOptions().
struct SimFlags {
  std::string world = "urban", route = "car", weather = "none", format = "euroc";
  cli::OutputDirOptions out;
  double duration_s = 0, speed = 5, altitude = 20, scale = 1;
  uint64_t seed = 1;
  double gnss_rate = 5, gnss_sigma = 1;
  std::string gnss_outliers;
  std::vector<std::string> gnss_outages;
  std::string nadir_camera = "auto", baro = "auto";
  double nadir_hfov = 90, nadir_rate = 5;
  double drag = 0;
  std::string wind = "0,0";
  bool particles_still = false;
  std::string asphalt;  // "" = the default: varied on the urban world
  std::string camera_noise = "on";
};

// "auto" (on for drone routes), "off", or WxH.
void ParseNadirCamera(const std::string& spec, bool drone, sim::NadirCameraOptions* o) {
  if (spec == "auto" || spec == "off") {
    o->enabled = spec == "auto" && drone;
    return;
  }
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(spec.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || x != 'x') {
    throw cli::UsageError(fmt::format("'{}' is not WxH (e.g. 640x480), auto or off", spec),
                          "--nadir-camera");
  }
  o->enabled = true;
  o->width = w;
  o->height = h;
}

// The options the flags give; throws UsageError (exit 2) naming the flag on any invalid value.
sim::SimulationOptions ToOptions(const SimFlags& f) {
  sim::SimulationOptions o;
  try {
    o.world = sim::ParseWorld(f.world);
    o.weather = sim::ParseWeather(f.weather);
    o.weather.particles_still = f.particles_still;
    // "" (not given): varied on the urban world; elsewhere there is no road to vary.
    const bool varied = f.asphalt.empty() || sim::ParseAsphalt(f.asphalt, "--asphalt");
    if (varied && !f.asphalt.empty() && o.world.kind != sim::WorldKind::kUrban) {
      throw Error("--asphalt varied needs the urban world (only it has roads)",
                  {.field = "--asphalt"});
    }
    o.world.varied_asphalt = varied && o.world.kind == sim::WorldKind::kUrban;
    o.camera_noise = sim::ParseCameraNoise(f.camera_noise, "--camera-noise");
    if (f.format != "euroc" && f.format != "airsim") {
      throw Error(fmt::format("unknown format '{}' (euroc or airsim)", f.format),
                  {.field = "--format"});
    }
    if (!f.gnss_outliers.empty()) {
      std::tie(o.gnss.outlier_fraction, o.gnss.outlier_magnitude_m) =
          sim::ParseOutlierSpec(f.gnss_outliers, "--gnss-outliers");
    }
    for (const std::string& s : f.gnss_outages) {
      o.gnss.outages.push_back(sim::ParseOutageSpec(s, "--gnss-outage"));
    }
  } catch (const Error& e) {
    throw cli::UsageError(e.message(), e.context().field);
  }
  o.format = f.format == "euroc" ? sim::DatasetFormat::kEuroc : sim::DatasetFormat::kAirsim;
  o.route = f.route;
  o.out_dir = f.out.dir;
  o.force = f.out.force;
  o.duration_s = f.duration_s;
  o.speed_m_s = f.speed;
  o.altitude_m = f.altitude;
  o.drag_per_s = f.drag;
  const std::vector<double> wind = ParseNumbers(f.wind, 2, "EAST,NORTH in m/s", "--wind");
  o.wind_m_s = {wind[0], wind[1]};
  o.scale = f.scale;
  o.seed = f.seed;
  o.gnss.rate_hz = f.gnss_rate;
  o.gnss.sigma_m = f.gnss_sigma;
  const bool drone = f.route != "car";
  ParseNadirCamera(f.nadir_camera, drone, &o.nadir);
  o.nadir.hfov_deg = f.nadir_hfov;
  o.nadir.rate_hz = f.nadir_rate;
  if (f.baro != "auto" && f.baro != "on" && f.baro != "off") {
    throw cli::UsageError(fmt::format("'{}' is not auto, on or off", f.baro), "--baro");
  }
  o.baro.enabled = f.baro == "on" || (f.baro == "auto" && drone);
  cli::ThrowIfInvalid(o.Check(), "");
  return o;
}

void AddCommonFlags(CLI::App& app, SimFlags& f) {
  f.out.Add(app, "output folder (must not exist or be empty)",
            "replace the contents of a non-empty output folder");
  app.add_option("--format", f.format, "euroc | airsim")->capture_default_str();
  app.add_option("--duration", f.duration_s,
                 "seconds to simulate (0: the whole car route; 60 s for drones)")
      ->capture_default_str();
  app.add_option("--seed", f.seed, "random seed (same seed: byte-identical output)")
      ->capture_default_str();
  app.add_option("--scale", f.scale, "image size factor, e.g. 0.5 for half resolution")
      ->capture_default_str();
  app.add_option("--camera-noise", f.camera_noise,
                 "on | off | READ:SHOT: the cameras' noise before 8-bit rounding, sigma^2 = READ^2 "
                 "+ SHOT * grey level (on: 0.8:0.02, measured on EuRoC's cam0; off: as rendered "
                 "before 2026-12-07)")
      ->capture_default_str();
}

void AddSimFlags(CLI::App& app, SimFlags& f) {
  app.add_option("--world", f.world, "urban | terrain | ortho:GEOTIFF")->capture_default_str();
  app.add_option("--route", f.route,
                 "car (the scripted car route through the world) | drone (seeded random) | "
                 "drone:FILE (x, y, altitude[, yaw_deg] per line)")
      ->capture_default_str();
  app.add_option("--weather", f.weather,
                 "none | KIND:PERCENT, KIND = rain snow leaves fog dust road-wetness road-snow "
                 "road-leaves, PERCENT 0-100")
      ->capture_default_str();
  app.add_flag("--particles-still", f.particles_still,
               "diagnostics: rain, snow, leaves and dust particles frozen as at t = 0 (they hide "
               "the scene but do not move)");
  app.add_option("--asphalt", f.asphalt,
                 "urban road: varied (the default: 8 asphalt variants, one per 8 m, picked by a "
                 "hash, no exact repetition) | tiled (one texture repeating every 8 m, as "
                 "rendered before 2026-12-06)");
  AddCommonFlags(app, f);
  app.add_option("--speed", f.speed, "drone speed (m/s)")->capture_default_str();
  app.add_option("--altitude", f.altitude, "drone altitude above ground (m)")
      ->capture_default_str();
  app.add_option("--drag", f.drag,
                 "drone air drag (1/s; 0: none): the drone leans into its air speed and the wind")
      ->capture_default_str();
  app.add_option("--wind", f.wind, "steady wind EAST,NORTH (m/s; drone routes, with --drag)")
      ->capture_default_str();
  app.add_option("--gnss-rate", f.gnss_rate, "GNSS rate (Hz)")->capture_default_str();
  app.add_option("--gnss-sigma", f.gnss_sigma, "GNSS noise sigma per axis (m)")
      ->capture_default_str();
  app.add_option("--gnss-outliers", f.gnss_outliers, "FRACTION:MAGNITUDE_M, e.g. 0.05:20");
  app.add_option("--gnss-outage", f.gnss_outages,
                 "START_S:DURATION_S, no GNSS in that window (repeatable)");
  app.add_option("--nadir-camera", f.nadir_camera,
                 "nadir mapping camera mav0/cam2: WxH, off, or auto (640x480 on drone routes)")
      ->capture_default_str();
  app.add_option("--nadir-hfov", f.nadir_hfov, "nadir camera horizontal field of view (deg)")
      ->capture_default_str();
  app.add_option("--nadir-rate", f.nadir_rate, "nadir camera frame rate (Hz)")
      ->capture_default_str();
  app.add_option("--baro", f.baro, "barometer mav0/baro0: on, off, or auto (on for drone routes)")
      ->capture_default_str();
}

int RunSuite(const SimFlags& f) {
  Timer timer;
  const size_t frames = app::RunWeatherSuite(
      ToOptions(f), [](size_t, const sim::SuiteEntry& e, const sim::SimulationSummary& s) {
        std::printf("%-24s %5zu stereo frames, %.0f m, %.1f s\n", e.name.c_str(), s.frames,
                    s.path_length_m, s.wall_s);
        std::fflush(stdout);
      });
  std::printf("suite: %zu sequences, %zu stereo frames in %.1f s -> %s\n",
              sim::WeatherSuite().size(), frames, timer.ElapsedSeconds(), f.out.dir.c_str());
  return 0;
}

int RunOne(const SimFlags& f) {
  const sim::SimulationOptions o = ToOptions(f);
  const sim::SimulationSummary s = app::SimulateWithProgress(o, "sim");
  std::printf(
      "optinav sim: %s world (%zu triangles), %s route %.0f m in %.1f s, weather %s: %zu "
      "stereo frames %dx%d, %zu IMU, %zu GNSS samples%s -> %s (%s) in %.1f s\n",
      f.world.c_str(), s.world_triangles, f.route.c_str(), s.path_length_m, s.duration_s,
      o.weather.ToString().c_str(), s.frames, s.width, s.height, s.imu_samples, s.gnss_samples,
      (o.nadir.enabled || o.baro.enabled)
          ? fmt::format(", {} nadir frames, {} barometer samples", s.nadir_frames, s.baro_samples)
                .c_str()
          : "",
      o.out_dir.c_str(), f.format.c_str(), s.wall_s);
  return 0;
}

}  // namespace

int RunSim(int argc, char** argv) {
  SimFlags f;
  if (argc >= 2 && std::string(argv[1]) == "suite") {
    CLI::App app{
        "Write the weather suite: 36 sequences (24 urban, 12 terrain), each weather kind "
        "at its intensities",
        "optinav sim suite"};
    f.format = "airsim";
    AddCommonFlags(app, f);
    std::string program = "optinav sim suite";
    argv[1] = program.data();
    return cli::RunCli(app, argc - 1, argv + 1, [&] { return RunSuite(f); });
  }
  CLI::App app{
      "Simulate a stereo + IMU + GNSS sequence with weather (EuRoC or AirSim format).\n"
      "`optinav sim suite --out DIR` writes the weather suite: 36 sequences, 24 urban and 12 "
      "terrain.",
      "optinav sim"};
  AddSimFlags(app, f);
  return cli::RunCli(app, argc, argv, [&] { return RunOne(f); });
}

}  // namespace optinav
