// The one way a subcommand runs (docs/ARCHITECTURE.md, "exe"): parse the flags, apply
// --log-level, call one driver, map failures to exit codes with one message format.
//
//   exit 0  success (or --help)
//   exit 1  optinav::Error from the run: bad input files, I/O, a failed run
//   exit 2  usage: a CLI11 parse error, or a UsageError (a flag value that is out of range or
//           inconsistent, including an Options::Check() failure)
//
// Every message goes to stderr as "<program>: error: <message>" (the message names the file, line
// or flag at fault); usage errors add a pointer to --help. Errors are printed whatever the log
// level, so `--log-level off` still explains a failure.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "optinav/app/slurm_plan.h"
#include "optinav/util/error.h"

namespace optinav::cli {

// A bad flag value: exit 2 like a parse error. Carries the flag as ErrorContext::field.
class UsageError : public Error {
 public:
  UsageError(const std::string& message, const std::string& flag);
};

// Throws UsageError naming `flag` when `check_message` (an Options::Check() result) is not empty.
void ThrowIfInvalid(const std::string& check_message, const std::string& flag);
// The same for a Check() message that starts with the flag at fault ("--runs must be >= 1"):
// that flag becomes the error's field.
void ThrowIfCheckFailed(const std::string& check_message);

struct RunnerOptions {
  std::string default_log_level = "info";  // bench drivers default to "warn"
};

// Adds --log-level to `app` and every subcommand of it (recursively), parses argv, applies the
// level and calls `run`, whose return value is the exit code. See the table above.
int RunCli(CLI::App& app, int argc, char** argv, const std::function<int()>& run,
           const RunnerOptions& options = {});

// Marks `option` as naming an output file: before the run, RunCli refuses (exit 1, through
// io::CheckOutputFile) a value that is a folder or lies in a folder that cannot be written.
CLI::Option* OutputFile(CLI::Option* option);

// Output-folder options: --out DIR (required) and --force (write into / replace a non-empty
// folder). Prepare() makes the folder ready through io::PrepareOutputDir.
struct OutputDirOptions {
  std::string dir;
  bool force = false;
  void Add(CLI::App& app, const std::string& out_help, const std::string& force_help);
};

}  // namespace optinav::cli

namespace optinav::cli {

// `optinav KIND --out DIR --reuse` alone where DIR holds a Slurm plan of that kind: `command` runs
// on the plan's options (app::PlannedMergeArgs: the merge); otherwise on argv as given. argv[0]
// is the command's name.
int RunWithPlannedOptions(const std::string& kind, int argc, char** argv,
                          const std::function<int(int, char**)>& command);

// `optinav KIND ... --plan PLAN` of a sweep (bench gnss|weather): checks --plan and --task, writes
// the Slurm plan of `tasks` (app::WriteSweepPlan) and prints how to submit and merge it.
void PlanSweep(const std::string& kind, const std::string& plan, int task,
               const std::string& out_dir, const std::vector<std::string>& given,
               const std::vector<app::PlannedTask>& tasks, const app::SlurmResources& resources,
               const std::string& slurm_args);

}  // namespace optinav::cli
