// optinav bench gnss: the GNSS fusion benchmark (app/gnss_bench.h) from the command line.
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "optinav/app/gnss_bench.h"
#include "optinav/app/slurm_plan.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"
#include "optinav/exe/gnss_flags.h"

namespace optinav {
namespace {

// The flags that are lists, resolved after parsing.
struct BenchFlags {
  std::string sequences = "room,outdoor", norms = "l2,huber,tukey";
  std::string conditions = "ideal,sigma0.5,sigma1.5,sigma3,outliers,outage";
  cli::GnssFusionFlags fusion;
  std::string plan, slurm_args;
};

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

void AddFlags(CLI::App& app, app::GnssBenchOptions* o, BenchFlags* f) {
  app.add_option("--out", o->out_dir, "output folder (sequences/, results.csv/.json, plot)")
      ->required();
  app.add_option("--seeds", o->seeds, "GNSS noise seeds per condition")->capture_default_str();
  app.add_option("--sequences", f->sequences, "room,outdoor (comma separated)")
      ->capture_default_str();
  app.add_option("--norms", f->norms, "l2,huber,tukey (comma separated)")->capture_default_str();
  app.add_option("--conditions", f->conditions, "GNSS conditions (comma separated)")
      ->capture_default_str();
  cli::AddGnssFusionFlags(app, &f->fusion);
  app.add_option("--scale", o->scale, "image size factor of the rendered sequences")
      ->capture_default_str();
  app.add_option("--duration", o->duration_s,
                 "seconds of each sequence to render (0: room 100 s, outdoor 200 s)")
      ->capture_default_str();
  app.add_option("--jobs", o->jobs, "runs in parallel (each VIO run is single-threaded)")
      ->capture_default_str();
  app.add_flag(
      "--reuse", o->reuse,
      "reuse complete sequences in OUT/sequences and finished runs in OUT/runs (resume, add "
      "seeds; in a planned folder: merge the tasks' runs)");
  app.add_option(
      "--plan", f->plan,
      "slurm: write OUT/plan.json and OUT/submit.sbatch (a job array) instead of running");
  app.add_option("--slurm-args", f->slurm_args,
                 "extra sbatch options for the planned tasks (override the derived resources)");
  app.add_option("--task", o->task, "run only task N of the plan (OUT/plan.json)");
  app.add_flag("--html", o->html, "also write the HTML report OUT/report.html (optinav report)");
}

// The list and fusion flags into `o`, then o->Check().
void ApplyFlags(const BenchFlags& f, app::GnssBenchOptions* o) {
  o->sequences.clear();
  for (const std::string& s : SplitList(f.sequences)) {
    const auto sequence = app::ParseGnssBenchSequence(s);
    if (!sequence) throw cli::UsageError("unknown sequence '" + s + "'", "--sequences");
    o->sequences.push_back(*sequence);
  }
  o->norms.clear();
  for (const std::string& n : SplitList(f.norms)) {
    const auto norm = vio::ParseGnssNorm(n);
    if (!norm) throw cli::UsageError("unknown norm '" + n + "'", "--norms");
    o->norms.push_back(*norm);
  }
  o->conditions.clear();
  for (const std::string& k : SplitList(f.conditions)) {
    const auto condition = app::ParseGnssCondition(k);
    if (!condition)
      throw cli::UsageError(
          "unknown condition '" + k + "' (ideal, sigma0.5, sigma1.5, sigma3, outliers, outage)",
          "--conditions");
    o->conditions.push_back(*condition);
  }
  f.fusion.ApplyTo(&o->fusion);
  cli::ThrowIfCheckFailed(o->Check());
}

int RunGnssBenchArgs(int argc, char** argv) {
  CLI::App app{
      "GNSS fusion benchmark: RMSE ATE per GNSS condition (noise, outliers, an outage) of the "
      "fused VIO on simulated flights",
      "optinav bench gnss"};
  app::GnssBenchOptions options;
  BenchFlags flags;
  AddFlags(app, &options, &flags);
  const std::vector<std::string> given(argv + 1, argv + argc);
  const auto run = [&] {
    ApplyFlags(flags, &options);
    if (!flags.plan.empty()) {
      cli::PlanSweep("bench gnss", flags.plan, options.task, options.out_dir, given,
                     app::GnssBenchTasks(options), app::GnssBenchTaskResources(options),
                     flags.slurm_args);
      return 0;
    }
    if (options.reuse && options.task < 0)
      options.merge = app::IsPlannedMerge("bench gnss", options.out_dir, given);
    const app::GnssBenchResult result = app::RunGnssBench(options, [](const std::string& line) {
      std::printf("%s\n", line.c_str());
      std::fflush(stdout);
    });
    if (options.task >= 0) return 0;  // run files only
    std::printf("\n%s", result.tables.c_str());
    std::printf("never worse than VIO alone (every row, every seed, 5 %% margin): %s\n",
                result.never_worse ? "yes" : "NO");
    std::printf(
        "bench gnss: results.csv, results.json, tables.md, error_*.svg, report.json, "
        "runs/*.tum+json -> %s\n",
        options.out_dir.c_str());
    if (result.html) PrintHtmlReportLine(*result.html);
    return 0;
  };
  return cli::RunCli(app, argc, argv, run, {.default_log_level = "warn"});
}

int RunGnssBench(int argc, char** argv) {
  // `--out DIR --reuse` alone in a planned folder: the merge, with the plan's options.
  return cli::RunWithPlannedOptions("bench gnss", argc, argv, RunGnssBenchArgs);
}

}  // namespace

int RunBench(int argc, char** argv) {
  if (argc >= 2 && std::string(argv[1]) == "gnss") return RunGnssBench(argc - 1, argv + 1);
  if (argc >= 2 && std::string(argv[1]) == "weather") return RunWeatherBench(argc - 1, argv + 1);
  if (argc >= 2 && std::string(argv[1]) == "nav") return RunNavBench(argc - 1, argv + 1);
  const bool help = argc >= 2 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h");
  std::fprintf(help ? stdout : stderr,
               "usage: optinav bench gnss --out DIR [options]      (optinav bench gnss --help)\n"
               "       optinav bench weather --out DIR [options]   (optinav bench weather --help)\n"
               "       optinav bench nav --out DIR [options]       (optinav bench nav --help)\n");
  return help ? 0 : 2;
}

}  // namespace optinav
