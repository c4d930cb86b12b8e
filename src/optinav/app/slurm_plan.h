// Planned runs on a Slurm cluster (`--plan slurm`), shared by `bench weather`, `bench gnss` and
// `map build`: the work split into independent tasks, written as DIR/plan.json (every task with its
// exact command line and the files it writes), DIR/submit.sbatch (a job array, one array task per
// task) and DIR/merge.sbatch (the merge, queued by the array's first task with an `afterok`
// dependency on the whole array). Each task runs the same optinav binary on one task and writes
// only its own files, atomically; the merge reads them and makes the same outputs a
// single-machine run makes. A merge that finds tasks unfinished lists them with their logs and the
// command that re-submits just those (`sbatch --array=3,7 DIR/submit.sbatch`). docs/SLURM.md.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace optinav::app {

// What one array task asks of Slurm. Derived per command from the work (frame size, tiles);
// --slurm-args overrides any of it (and adds partition, account, ...).
struct SlurmResources {
  int cpus_per_task = 1;
  int mem_mb = 1024;
  int time_min = 60;
  std::string derivation;  // how the figures were derived, for plan.json and the script
};

// The resources of a benchmark task from its measured cost: `cpus` CPUs, 512 MB + 256 MB per
// megapixel of image (rounded up to 64 MB), 3x the estimated seconds (slower or shared nodes),
// 10 minutes at least; `derivation` says how the estimate was made.
SlurmResources BenchTaskResources(int cpus, double megapixels, double estimate_s,
                                  std::string derivation);

// One task: a label for people and the files it writes (all present = finished; each written
// atomically, the last one last).
struct PlannedTask {
  std::string label;
  std::vector<std::string> outputs;
};

struct SlurmPlan {
  std::string kind;      // "bench weather", "bench gnss", "map build"
  std::string dir;       // plan folder (absolute): plan.json, *.sbatch, logs/
  std::string job_name;  // Slurm job name of the array ("-merge" appended for the merge)
  // A task's command line (argv, the binary first); "{task}" in any argument is the task index.
  std::vector<std::string> task_command;
  std::vector<std::string> merge_command;
  // The planned options as a command line after the binary (no --task, --reuse, --plan): a merge
  // given only `--out DIR --reuse` takes them (PlannedMergeArgs).
  std::vector<std::string> args;
  std::vector<PlannedTask> tasks;
  SlurmResources task_resources, merge_resources;
  std::string slurm_args;  // --slurm-args: extra sbatch options, after (so over) the derived ones
  std::vector<std::string> env;  // NAME=VALUE exported by the scripts (e.g. GDAL_CACHEMAX=256)
  std::string Check() const;     // "" when valid
};

// Writes DIR/plan.json, DIR/submit.sbatch and DIR/merge.sbatch (atomically) and creates DIR/logs.
// Throws Error on an invalid plan or --slurm-args (field "--slurm-args").
void WriteSlurmPlan(const SlurmPlan& plan);

// A task's command line: task_command with "{task}" replaced by the index.
std::vector<std::string> TaskCommand(const SlurmPlan& plan, int index);
// DIR/logs/task_<index>.log: where submit.sbatch sends the task's output.
std::string TaskLogPath(const std::string& dir, int index);

// The plan in DIR/plan.json, nullopt when there is none. Throws Error naming the file when it
// exists but cannot be read.
std::optional<SlurmPlan> ReadSlurmPlan(const std::string& dir);

struct UnfinishedTask {
  int index = 0;
  std::string label, log;
  std::vector<std::string> missing;  // outputs not there
  std::string last_log_line;         // the log's last line ("" when there is no log)
};
std::vector<UnfinishedTask> UnfinishedTasks(const SlurmPlan& plan);
// Throws Error (file: DIR/plan.json) listing every unfinished task with its missing output and
// log, and the command that re-submits them alone; returns when all are finished.
void ThrowIfUnfinished(const SlurmPlan& plan);

// `--slurm-args "--mem=8G --partition gpu"` as sbatch options, one per line ("--mem=8G",
// "--partition gpu"). Throws Error (field "--slurm-args") on a token that is not an option.
std::vector<std::string> SplitSlurmArgs(const std::string& slurm_args);

// A command line for the plan from the user's (after the command's name): drops `drop_valued`
// flags with their values and `drop_flags` flags, makes `path_flags` values absolute; both
// "--flag value" and "--flag=value".
std::vector<std::string> PlanArgs(const std::vector<std::string>& argv,
                                  const std::vector<std::string>& drop_valued,
                                  const std::vector<std::string>& drop_flags,
                                  const std::vector<std::string>& path_flags);

// A merge given as `PREFIX --out DIR --reuse [--log-level L]` and nothing else, where DIR holds a
// plan of this kind: the plan's options with --reuse (and the --log-level); else nullopt.
std::optional<std::vector<std::string>> PlannedMergeArgs(const std::string& kind,
                                                         const std::vector<std::string>& argv);

// The running binary (absolute), for the planned command lines.
std::string SelfExecutable();

// POSIX shell single-quoting when needed.
std::string ShellQuote(const std::string& s);

}  // namespace optinav::app

namespace optinav::app {

// A benchmark sweep's plan (`optinav bench weather|gnss ... --plan slurm`): `kind` is the command
// ("bench weather"), `given_args` the user's flags after it. Tasks run `optinav KIND ARGS --task N
// --reuse`, the merge `optinav KIND ARGS --reuse`, where ARGS are the given flags without --plan,
// --slurm-args, --task, --jobs, --reuse and --log-level and with --out made absolute. Writes the
// plan (WriteSlurmPlan) into out_dir and returns it.
SlurmPlan WriteSweepPlan(const std::string& kind, const std::string& out_dir,
                         const std::vector<std::string>& given_args, std::vector<PlannedTask> tasks,
                         const SlurmResources& task_resources, const std::string& slurm_args);

// True when `KIND given_args` (with --reuse, no --task, no --plan) is the merge of a plan in
// out_dir; false when out_dir holds no plan of this kind. Throws Error (field "--out") when it
// holds one made with other options.
bool IsPlannedMerge(const std::string& kind, const std::string& out_dir,
                    const std::vector<std::string>& given_args);

}  // namespace optinav::app
