#include "optinav/app/slurm_plan.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "optinav/io/text_parse.h"
#include "optinav/util/error.h"

namespace fs = std::filesystem;

namespace optinav::app {
namespace {

constexpr int kPlanVersion = 1;

std::string Replace(std::string s, const std::string& from, const std::string& to) {
  for (size_t at = 0; (at = s.find(from, at)) != std::string::npos; at += to.size())
    s.replace(at, from.size(), to);
  return s;
}

std::string CommandLine(const std::vector<std::string>& argv) {
  std::string out;
  for (const std::string& a : argv) out += (out.empty() ? "" : " ") + ShellQuote(a);
  return out;
}

nlohmann::json ResourcesJson(const SlurmResources& r) {
  return {{"cpus_per_task", r.cpus_per_task},
          {"mem_mb", r.mem_mb},
          {"time_min", r.time_min},
          {"derivation", r.derivation}};
}

SlurmResources ResourcesFromJson(const nlohmann::json& j) {
  return {j.at("cpus_per_task"), j.at("mem_mb"), j.at("time_min"), j.value("derivation", "")};
}

std::string ResourceLines(const SlurmResources& r) {
  return fmt::format("#SBATCH --cpus-per-task={}\n#SBATCH --mem={}M\n#SBATCH --time={}\n",
                     r.cpus_per_task, r.mem_mb, r.time_min);
}

std::string LastLine(const std::string& path) {
  std::ifstream in(path);
  std::string line, last;
  while (std::getline(in, line))
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  return last;
}

}  // namespace

std::string SlurmPlan::Check() const {
  if (dir.empty() || !fs::path(dir).is_absolute()) return "the plan folder must be absolute";
  if (tasks.empty()) return "a plan needs at least one task";
  if (task_command.empty() || merge_command.empty()) return "a plan needs task and merge commands";
  for (const SlurmResources* r : {&task_resources, &merge_resources})
    if (r->cpus_per_task < 1 || r->mem_mb < 1 || r->time_min < 1)
      return "resources must be positive";
  return "";
}

std::string ShellQuote(const std::string& s) {
  if (!s.empty() && s.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                        "0123456789_-+=./:,@%{}") == std::string::npos)
    return s;
  return "'" + Replace(s, "'", "'\\''") + "'";
}

std::string SelfExecutable() { return fs::canonical("/proc/self/exe").string(); }

std::vector<std::string> TaskCommand(const SlurmPlan& plan, int index) {
  std::vector<std::string> out;
  for (const std::string& a : plan.task_command)
    out.push_back(Replace(a, "{task}", std::to_string(index)));
  return out;
}

std::string TaskLogPath(const std::string& dir, int index) {
  return (fs::path(dir) / "logs" / fmt::format("task_{}.log", index)).string();
}

std::vector<std::string> SplitSlurmArgs(const std::string& slurm_args) {
  std::vector<std::string> out;
  size_t i = 0;
  while (i < slurm_args.size()) {
    if (std::isspace(static_cast<unsigned char>(slurm_args[i]))) {
      ++i;
      continue;
    }
    const size_t end = slurm_args.find_first_of(" \t\n", i);
    const std::string token = slurm_args.substr(i, end == std::string::npos ? end : end - i);
    i = end == std::string::npos ? slurm_args.size() : end;
    if (token.find_first_of("'\"\\$`;|&<>") != std::string::npos)
      throw Error("'" + token + "' has shell characters (quotes, $, ;, ...): give plain options",
                  {.field = "--slurm-args"});
    if (token[0] == '-') {
      out.push_back(token);
    } else if (!out.empty() && out.back().find('=') == std::string::npos &&
               out.back().find(' ') == std::string::npos) {
      out.back() += " " + token;  // "--partition gpu"
    } else {
      throw Error("'" + token + "' is not an sbatch option (--name=VALUE or --name VALUE)",
                  {.field = "--slurm-args"});
    }
  }
  return out;
}

void WriteSlurmPlan(const SlurmPlan& p) {
  if (const std::string e = p.Check(); !e.empty()) throw Error(e, {.file = p.dir});
  const std::vector<std::string> extra = SplitSlurmArgs(p.slurm_args);
  fs::create_directories(fs::path(p.dir) / "logs");
  const std::string submit = (fs::path(p.dir) / "submit.sbatch").string();
  const std::string merge = (fs::path(p.dir) / "merge.sbatch").string();
  const int n = static_cast<int>(p.tasks.size());

  nlohmann::json tasks = nlohmann::json::array();
  for (int i = 0; i < n; ++i) {
    tasks.push_back({{"index", i},
                     {"label", p.tasks[i].label},
                     {"command", TaskCommand(p, i)},
                     {"command_line", CommandLine(TaskCommand(p, i))},
                     {"outputs", p.tasks[i].outputs},
                     {"log", TaskLogPath(p.dir, i)}});
  }
  const nlohmann::json j = {{"format", "optinav slurm plan"},
                            {"version", kPlanVersion},
                            {"kind", p.kind},
                            {"dir", p.dir},
                            {"job_name", p.job_name},
                            {"args", p.args},
                            {"task_command", p.task_command},
                            {"merge_command", p.merge_command},
                            {"merge_command_line", CommandLine(p.merge_command)},
                            {"task_resources", ResourcesJson(p.task_resources)},
                            {"merge_resources", ResourcesJson(p.merge_resources)},
                            {"slurm_args", p.slurm_args},
                            {"env", p.env},
                            {"submit", submit},
                            {"tasks", tasks}};

  std::string extra_lines;
  for (const std::string& e : extra) extra_lines += "#SBATCH " + e + "\n";
  std::string env_lines;
  for (const std::string& e : p.env) env_lines += "export " + ShellQuote(e) + "\n";
  const std::string log_pattern = (fs::path(p.dir) / "logs" / "task_%a.log").string();
  std::string s = fmt::format(
      "#!/bin/bash\n"
      "# optinav {kind}: {n} task(s) as a Slurm job array (plan: {dir}/plan.json).\n"
      "#   sbatch {submit}                  every task, then the merge\n"
      "#   sbatch --array=3,7 {submit}      tasks 3 and 7 alone (then the merge)\n"
      "# Resources: {why}\n"
      "#SBATCH --job-name={job}\n"
      "#SBATCH --array=0-{last}\n"
      "{res}"
      "#SBATCH --output={log}\n"
      "#SBATCH --open-mode=append\n"
      "{extra}"
      "set -euo pipefail\n"
      "{env}"
      "# The first task of a submission queues the merge, to start once every task of the array\n"
      "# has succeeded (cancelled when one fails: run the merge by hand to see which).\n"
      "if [[ \"${{SLURM_ARRAY_TASK_ID}}\" == \"${{SLURM_ARRAY_TASK_MIN}}\" ]]; then\n"
      "  sbatch --parsable --dependency=afterok:${{SLURM_ARRAY_JOB_ID}} --kill-on-invalid-dep=yes "
      "{merge}\n"
      "fi\n"
      "echo \"optinav task ${{SLURM_ARRAY_TASK_ID}} on $(hostname) at $(date -u +%FT%TZ)\"\n"
      "exec {command}\n",
      fmt::arg("kind", p.kind), fmt::arg("n", n), fmt::arg("dir", p.dir),
      fmt::arg("submit", ShellQuote(submit)), fmt::arg("why", p.task_resources.derivation),
      fmt::arg("job", p.job_name), fmt::arg("last", n - 1),
      fmt::arg("res", ResourceLines(p.task_resources)), fmt::arg("log", log_pattern),
      fmt::arg("extra", extra_lines), fmt::arg("env", env_lines),
      fmt::arg("merge", ShellQuote(merge)),
      fmt::arg("command",
               Replace(CommandLine(p.task_command), "{task}", "\"${SLURM_ARRAY_TASK_ID}\"")));
  std::string m = fmt::format(
      "#!/bin/bash\n"
      "# optinav {kind}: the merge of {dir}/plan.json's tasks (queued by submit.sbatch; by hand:\n"
      "# sbatch {self}, or run the command below). Lists unfinished tasks and exits 1 if any.\n"
      "#SBATCH --job-name={job}-merge\n"
      "{res}"
      "#SBATCH --output={log}\n"
      "#SBATCH --open-mode=append\n"
      "{extra}"
      "set -euo pipefail\n"
      "exec {command}\n",
      fmt::arg("kind", p.kind), fmt::arg("dir", p.dir), fmt::arg("self", ShellQuote(merge)),
      fmt::arg("job", p.job_name), fmt::arg("res", ResourceLines(p.merge_resources)),
      fmt::arg("log", (fs::path(p.dir) / "logs" / "merge.log").string()),
      fmt::arg("extra", extra_lines), fmt::arg("command", CommandLine(p.merge_command)));
  io::WriteFileAtomically((fs::path(p.dir) / "plan.json").string(), j.dump(2) + "\n");
  io::WriteFileAtomically(submit, s);
  io::WriteFileAtomically(merge, m);
  fs::permissions(submit, fs::perms::owner_exec | fs::perms::group_exec, fs::perm_options::add);
  fs::permissions(merge, fs::perms::owner_exec | fs::perms::group_exec, fs::perm_options::add);
}

std::optional<SlurmPlan> ReadSlurmPlan(const std::string& dir) {
  const std::string path = (fs::path(dir) / "plan.json").string();
  if (!fs::is_regular_file(path)) return std::nullopt;
  try {
    const nlohmann::json j = nlohmann::json::parse(io::ReadFileToString(path));
    if (j.at("format") != "optinav slurm plan" || j.at("version") != kPlanVersion)
      throw std::invalid_argument("not an optinav slurm plan of version " +
                                  std::to_string(kPlanVersion));
    SlurmPlan p;
    p.kind = j.at("kind");
    p.dir = j.at("dir");
    p.job_name = j.at("job_name");
    p.args = j.at("args").get<std::vector<std::string>>();
    p.task_command = j.at("task_command").get<std::vector<std::string>>();
    p.merge_command = j.at("merge_command").get<std::vector<std::string>>();
    p.task_resources = ResourcesFromJson(j.at("task_resources"));
    p.merge_resources = ResourcesFromJson(j.at("merge_resources"));
    p.slurm_args = j.at("slurm_args");
    p.env = j.value("env", std::vector<std::string>{});
    for (const nlohmann::json& t : j.at("tasks"))
      p.tasks.push_back({t.at("label"), t.at("outputs").get<std::vector<std::string>>()});
    return p;
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(std::string("cannot read the Slurm plan: ") + e.what(), {.file = path});
  }
}

std::vector<UnfinishedTask> UnfinishedTasks(const SlurmPlan& plan) {
  std::vector<UnfinishedTask> out;
  for (int i = 0; i < static_cast<int>(plan.tasks.size()); ++i) {
    UnfinishedTask u{i, plan.tasks[i].label, TaskLogPath(plan.dir, i), {}, ""};
    for (const std::string& f : plan.tasks[i].outputs)
      if (!fs::is_regular_file(f)) u.missing.push_back(f);
    if (u.missing.empty()) continue;
    u.last_log_line = LastLine(u.log);
    out.push_back(std::move(u));
  }
  return out;
}

void ThrowIfUnfinished(const SlurmPlan& plan) {
  const std::vector<UnfinishedTask> unfinished = UnfinishedTasks(plan);
  if (unfinished.empty()) return;
  std::string msg = fmt::format(
      "{} of {} planned task(s) unfinished (failed, still running or "
      "never run):",
      unfinished.size(), plan.tasks.size());
  std::string ids;
  for (const UnfinishedTask& u : unfinished) {
    msg +=
        fmt::format("\n  task {} ({}): missing {}{}; log {}{}", u.index, u.label, u.missing.front(),
                    u.missing.size() > 1 ? fmt::format(" and {} more", u.missing.size() - 1) : "",
                    u.log, fs::exists(u.log) ? "" : " (none: never started)");
    if (!u.last_log_line.empty()) msg += "\n    last log line: " + u.last_log_line;
    ids += (ids.empty() ? "" : ",") + std::to_string(u.index);
  }
  msg += fmt::format("\nre-submit them alone: sbatch --array={} {}", ids,
                     ShellQuote((fs::path(plan.dir) / "submit.sbatch").string()));
  throw Error(msg, {.file = (fs::path(plan.dir) / "plan.json").string()});
}

std::vector<std::string> PlanArgs(const std::vector<std::string>& argv,
                                  const std::vector<std::string>& drop_valued,
                                  const std::vector<std::string>& drop_flags,
                                  const std::vector<std::string>& path_flags) {
  const auto in = [](const std::vector<std::string>& v, const std::string& s) {
    return std::find(v.begin(), v.end(), s) != v.end();
  };
  const auto absolute = [](const std::string& p) {
    return p.rfind("/vsi", 0) == 0 ? p : fs::absolute(p).lexically_normal().string();
  };
  std::vector<std::string> out;
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    const size_t eq = a.find('=');
    const std::string name = a.rfind("--", 0) == 0 && eq != std::string::npos ? a.substr(0, eq) : a;
    const bool joined = name != a;
    if (in(drop_flags, name)) continue;
    if (in(drop_valued, name)) {
      if (!joined) ++i;
      continue;
    }
    if (in(path_flags, name)) {
      if (joined) {
        out.push_back(name + "=" + absolute(a.substr(eq + 1)));
      } else {
        out.push_back(a);
        if (i + 1 < argv.size()) out.push_back(absolute(argv[++i]));
      }
      continue;
    }
    out.push_back(a);
  }
  return out;
}

std::optional<std::vector<std::string>> PlannedMergeArgs(const std::string& kind,
                                                         const std::vector<std::string>& argv) {
  std::string out_dir, log_level;
  bool reuse = false;
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a == "--reuse") {
      reuse = true;
    } else if ((a == "--out" || a == "--log-level") && i + 1 < argv.size()) {
      (a == "--out" ? out_dir : log_level) = argv[++i];
    } else if (a.rfind("--out=", 0) == 0) {
      out_dir = a.substr(6);
    } else if (a.rfind("--log-level=", 0) == 0) {
      log_level = a.substr(12);
    } else {
      return std::nullopt;  // other flags: the command line as given
    }
  }
  if (!reuse || out_dir.empty()) return std::nullopt;
  const std::optional<SlurmPlan> plan = ReadSlurmPlan(out_dir);
  if (!plan || plan->kind != kind) return std::nullopt;
  std::vector<std::string> args = plan->args;
  args.push_back("--reuse");
  if (!log_level.empty()) args.insert(args.end(), {"--log-level", log_level});
  return args;
}

}  // namespace optinav::app

namespace optinav::app {
namespace {

std::vector<std::string> SweepArgs(const std::vector<std::string>& given_args) {
  return PlanArgs(given_args, {"--plan", "--slurm-args", "--task", "--jobs", "--log-level"},
                  {"--reuse"}, {"--out"});
}

std::vector<std::string> Words(const std::string& s) {
  std::vector<std::string> out;
  for (size_t i = 0, end; i < s.size(); i = end + 1) {
    end = s.find(' ', i);
    if (end == std::string::npos) end = s.size();
    if (end > i) out.push_back(s.substr(i, end - i));
  }
  return out;
}

}  // namespace

SlurmPlan WriteSweepPlan(const std::string& kind, const std::string& out_dir,
                         const std::vector<std::string>& given_args, std::vector<PlannedTask> tasks,
                         const SlurmResources& task_resources, const std::string& slurm_args) {
  SlurmPlan p;
  p.kind = kind;
  p.dir = fs::absolute(out_dir).lexically_normal().string();
  if (p.dir.size() > 1 && p.dir.back() == '/') p.dir.pop_back();
  p.job_name = "optinav-" + Words(kind).back();
  p.args = SweepArgs(given_args);
  std::vector<std::string> base = {SelfExecutable()};
  for (const std::string& w : Words(kind)) base.push_back(w);
  base.insert(base.end(), p.args.begin(), p.args.end());
  p.task_command = base;
  p.task_command.insert(p.task_command.end(), {"--task", "{task}", "--reuse"});
  p.merge_command = base;
  p.merge_command.push_back("--reuse");
  p.tasks = std::move(tasks);
  p.task_resources = task_resources;
  // The merge reads the run files and evaluates them: one CPU, a GB, well under an hour.
  p.merge_resources = {1, 2048, 60, "1 CPU, 2 GB, 60 min: reads and evaluates the run files"};
  p.slurm_args = slurm_args;
  WriteSlurmPlan(p);
  return p;
}

bool IsPlannedMerge(const std::string& kind, const std::string& out_dir,
                    const std::vector<std::string>& given_args) {
  const std::optional<SlurmPlan> plan = ReadSlurmPlan(out_dir);
  if (!plan || plan->kind != kind) return false;
  if (SweepArgs(given_args) != plan->args) {
    throw Error(fmt::format("holds a Slurm plan made with other options ({}); merge it with "
                            "`optinav {} --out {} --reuse` (the plan's options), or use another "
                            "folder",
                            CommandLine(plan->args), kind, ShellQuote(out_dir)),
                {.file = (fs::path(out_dir) / "plan.json").string(), .field = "--out"});
  }
  return true;
}

SlurmResources BenchTaskResources(int cpus, double megapixels, double estimate_s,
                                  std::string derivation) {
  SlurmResources r;
  r.cpus_per_task = cpus;
  r.mem_mb = static_cast<int>(std::ceil((512 + 256 * megapixels) / 64) * 64);
  r.time_min = std::max(10, static_cast<int>(std::ceil(3 * estimate_s / 60)));
  r.derivation = std::move(derivation);
  return r;
}

}  // namespace optinav::app
