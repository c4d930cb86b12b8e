#include "optinav/exe/cli_runner.h"

#include <algorithm>
#include <cstdio>
#include <vector>

#include "optinav/app/slurm_plan.h"
#include "optinav/io/text_parse.h"
#include "optinav/util/logging.h"

namespace optinav::cli {

UsageError::UsageError(const std::string& message, const std::string& flag)
    : Error(message, {.field = flag}) {}

void ThrowIfInvalid(const std::string& check_message, const std::string& flag) {
  if (!check_message.empty()) throw UsageError(check_message, flag);
}

void ThrowIfCheckFailed(const std::string& check_message) {
  if (check_message.empty()) return;
  const size_t space = check_message.find(' ');
  if (space == std::string::npos || check_message.rfind("--", 0) != 0)
    throw UsageError(check_message, "");
  throw UsageError(check_message.substr(space + 1), check_message.substr(0, space));
}

namespace {

void AddLogLevel(CLI::App& app, std::string* level) {
  app.add_option("--log-level", *level, "trace|debug|info|warn|error|off")->capture_default_str();
  for (CLI::App* sub : app.get_subcommands({})) AddLogLevel(*sub, level);
}

// The options marked by OutputFile (compared by address with the parsed app's own).
std::vector<const CLI::Option*>& OutputOptions() {
  static std::vector<const CLI::Option*> options;
  return options;
}

void CheckOutputFiles(const CLI::App& app) {
  for (const CLI::Option* o : app.get_options()) {
    if (o->count() == 0 ||
        std::find(OutputOptions().begin(), OutputOptions().end(), o) == OutputOptions().end())
      continue;
    for (const std::string& path : o->results()) io::CheckOutputFile(path, o->get_name());
  }
  for (const CLI::App* sub : app.get_subcommands()) CheckOutputFiles(*sub);
}

void PrintError(const CLI::App& app, const std::string& message, bool usage) {
  std::fprintf(stderr, "%s: error: %s\n", app.get_name().c_str(), message.c_str());
  if (usage) std::fprintf(stderr, "run '%s --help' for the options\n", app.get_name().c_str());
  std::fflush(stderr);
}

}  // namespace

CLI::Option* OutputFile(CLI::Option* option) {
  OutputOptions().push_back(option);
  return option;
}

int RunCli(CLI::App& app, int argc, char** argv, const std::function<int()>& run,
           const RunnerOptions& options) {
  std::string level = options.default_log_level;
  AddLogLevel(app, &level);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    PrintError(app, e.what(), true);
    return 2;
  }
  try {
    SetLogLevel(level);
    CheckOutputFiles(app);
    return run();
  } catch (const UsageError& e) {
    PrintError(app, e.what(), true);
    return 2;
  } catch (const Error& e) {
    // SetLogLevel throws a plain Error for an unknown level: that is a usage error too.
    const bool usage = e.context().field == "--log-level";
    PrintError(app, e.what(), usage);
    return usage ? 2 : 1;
  } catch (const std::exception& e) {
    // Anything else (OpenCV, the standard library) is still an error, never std::terminate.
    PrintError(app, std::string("internal error: ") + e.what(), false);
    return 1;
  }
}

void OutputDirOptions::Add(CLI::App& app, const std::string& out_help,
                           const std::string& force_help) {
  app.add_option("--out", dir, out_help)->required();
  app.add_flag("--force", force, force_help);
}

}  // namespace optinav::cli

namespace optinav::cli {

int RunWithPlannedOptions(const std::string& kind, int argc, char** argv,
                          const std::function<int(int, char**)>& command) {
  const auto merge = app::PlannedMergeArgs(kind, {argv + 1, argv + argc});
  if (!merge) return command(argc, argv);
  std::vector<std::string> args = {argv[0]};
  args.insert(args.end(), merge->begin(), merge->end());
  std::vector<char*> ptrs;
  for (std::string& a : args) ptrs.push_back(a.data());
  return command(static_cast<int>(ptrs.size()), ptrs.data());
}

void PlanSweep(const std::string& kind, const std::string& plan, int task,
               const std::string& out_dir, const std::vector<std::string>& given,
               const std::vector<app::PlannedTask>& tasks, const app::SlurmResources& resources,
               const std::string& slurm_args) {
  if (plan != "slurm") throw UsageError("takes 'slurm'", "--plan");
  if (task >= 0) throw UsageError("is not used with --plan", "--task");
  const app::SlurmPlan written =
      app::WriteSweepPlan(kind, out_dir, given, tasks, resources, slurm_args);
  std::printf(
      "%s: planned %zu task(s) -> %s/plan.json\n  submit: sbatch %s/submit.sbatch (the merge "
      "follows when all succeed)\n  merge by hand: optinav %s --out %s --reuse\n",
      kind.c_str(), written.tasks.size(), written.dir.c_str(), written.dir.c_str(), kind.c_str(),
      written.dir.c_str());
}

}  // namespace optinav::cli
