// optinav bench weather: the weather benchmark (app/weather_bench.h) from the command line.
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "optinav/app/slurm_plan.h"
#include "optinav/app/weather_bench.h"
#include "optinav/exe/cli_common.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"
#include "optinav/util/error.h"

namespace optinav {
namespace {

// The flags that are lists, resolved after parsing ("" conditions: the suite's, per world).
struct WeatherFlags {
  std::string worlds = "urban,terrain", conditions, modes = "stereo";
  std::string plan, slurm_args, vehicle = "auto", asphalt = "varied";
  std::string camera_noise = "on";
};

void AddFlags(CLI::App& app, app::WeatherBenchOptions* o, WeatherFlags* f) {
  app.add_option("--out", o->out_dir,
                 "output folder (sequences/, runs/, results.json, table.md/.csv, plot)")
      ->required();
  app.add_option("--scale", o->scale, "image size factor (1: the document's 800x600)")
      ->capture_default_str();
  app.add_option("--worlds", f->worlds, "urban,terrain (comma separated)")->capture_default_str();
  app.add_option("--conditions", f->conditions,
                 "none,rain:50,...,fog:25,...,dust:100 (KIND:PERCENT as `sim --weather`; default: "
                 "the weather suite's 24 urban and 12 terrain conditions; road-* urban only)");
  app.add_option("--modes", f->modes, "stereo,stereo-imu (comma separated)")->capture_default_str();
  app.add_option("--seeds", o->seeds, "simulation seeds 1..N per sequence")->capture_default_str();
  app.add_option("--jobs", o->jobs, "sequences in parallel (each VIO run is threaded)")
      ->capture_default_str();
  app.add_flag("--reuse", o->reuse,
               "keep complete sequences in OUT/sequences and finished runs in OUT/runs (resume; "
               "in a planned folder: merge the tasks' runs)");
  app.add_option("--config", o->vio_config,
                 "YAML vio options for every run (as `optinav vio --config`; default: built in)");
  app.add_option("--vehicle", f->vehicle,
                 "auto|ground|free: the motion model of every run (as `optinav vio --vehicle`; "
                 "auto: ground on the car route)")
      ->capture_default_str();
  app.add_option("--asphalt", f->asphalt,
                 "varied|tiled: the urban road's asphalt (as `optinav sim --asphalt`)")
      ->capture_default_str();
  app.add_option("--camera-noise", f->camera_noise,
                 "on|off|READ:SHOT: the cameras' noise (as `optinav sim --camera-noise`)")
      ->capture_default_str();
  app.add_option("--duration", o->duration_s, "seconds of the car route (0: all of it)")
      ->capture_default_str();
  app.add_option(
      "--plan", f->plan,
      "slurm: write OUT/plan.json and OUT/submit.sbatch (a job array) instead of running");
  app.add_option("--slurm-args", f->slurm_args,
                 "extra sbatch options for the planned tasks (override the derived resources)");
  app.add_option("--task", o->task, "run only task N of the plan (OUT/plan.json)");
  app.add_flag("--html", o->html, "also write the HTML report OUT/report.html (optinav report)");
}

void ApplyFlags(const WeatherFlags& f, app::WeatherBenchOptions* o) {
  o->vehicle = ParseVehicle(f.vehicle, "--vehicle");
  try {
    o->varied_asphalt = sim::ParseAsphalt(f.asphalt, "--asphalt");
    o->camera_noise = sim::ParseCameraNoise(f.camera_noise, "--camera-noise");
    app::ParseWeatherBenchLists(f.worlds, f.conditions, f.modes, o);
  } catch (const Error& e) {
    throw cli::UsageError(e.message(), e.context().field);
  }
  cli::ThrowIfCheckFailed(o->Check());
}

int RunWeatherBenchArgs(int argc, char** argv) {
  CLI::App app{
      "Weather benchmark: the weather document's table (mean localization error of stereo "
      "odometry on the car route per weather condition), ours beside ORB-SLAM3's",
      "optinav bench weather"};
  app::WeatherBenchOptions options;
  WeatherFlags flags;
  AddFlags(app, &options, &flags);
  const std::vector<std::string> given(argv + 1, argv + argc);
  const auto run = [&] {
    ApplyFlags(flags, &options);
    if (!flags.plan.empty()) {
      cli::PlanSweep("bench weather", flags.plan, options.task, options.out_dir, given,
                     app::WeatherBenchTasks(options), app::WeatherBenchTaskResources(options),
                     flags.slurm_args);
      return 0;
    }
    if (options.reuse && options.task < 0)
      options.merge = app::IsPlannedMerge("bench weather", options.out_dir, given);
    const app::WeatherBenchResult result =
        app::RunWeatherBench(options, [](const std::string& line) {
          std::printf("%s\n", line.c_str());
          std::fflush(stdout);
        });
    if (options.task >= 0) return 0;  // run files only
    std::printf("\n%s\n", result.table.c_str());
    std::printf(
        "bench weather: %zu runs in %.0f s; results.json, table.md, table.csv, "
        "weather_error.svg/.png, report.json -> %s\n",
        result.runs.size(), result.wall_s, options.out_dir.c_str());
    if (result.html) PrintHtmlReportLine(*result.html);
    return 0;
  };
  return cli::RunCli(app, argc, argv, run, {.default_log_level = "warn"});
}

}  // namespace

int RunWeatherBench(int argc, char** argv) {
  // `--out DIR --reuse` alone in a planned folder: the merge, with the plan's options.
  return cli::RunWithPlannedOptions("bench weather", argc, argv, RunWeatherBenchArgs);
}

}  // namespace optinav
