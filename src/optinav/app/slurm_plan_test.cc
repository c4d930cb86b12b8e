#include "optinav/app/slurm_plan.h"

#include <filesystem>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "optinav/util/testing.h"

namespace fs = std::filesystem;

namespace optinav::app {
namespace {

TEST(SlurmPlan, SlurmArgsAreSbatchOptions) {
  EXPECT_EQ(SplitSlurmArgs("  --mem=8G --partition gpu -t 30 --exclusive"),
            (std::vector<std::string>{"--mem=8G", "--partition gpu", "-t 30", "--exclusive"}));
  EXPECT_TRUE(SplitSlurmArgs("").empty());
  EXPECT_ERROR(SplitSlurmArgs("gpu"), {.field = "--slurm-args"}, "'gpu' is not an sbatch option");
  EXPECT_ERROR(SplitSlurmArgs("--mem=8G 4"), {.field = "--slurm-args"}, "'4' is not an sbatch");
  EXPECT_ERROR(SplitSlurmArgs("--comment=$(rm)"), {.field = "--slurm-args"}, "shell characters");
}

TEST(SlurmPlan, PlanArgsDropPlanningFlagsAndFixPaths) {
  const std::string cwd = fs::current_path().string();
  EXPECT_EQ(PlanArgs({"--out", "d", "--plan", "slurm", "--scale=0.1", "--reuse", "--jobs=2",
                      "--slurm-args", "--mem=1G", "--out=/vsis3/b", "--seeds", "3"},
                     {"--plan", "--slurm-args", "--jobs"}, {"--reuse"}, {"--out"}),
            (std::vector<std::string>{"--out", cwd + "/d", "--scale=0.1", "--out=/vsis3/b",
                                      "--seeds", "3"}));
  EXPECT_EQ(ShellQuote("a/b_c-1.5,x"), "a/b_c-1.5,x");
  EXPECT_EQ(ShellQuote("it's here"), "'it'\\''s here'");
  EXPECT_EQ(ShellQuote(""), "''");
}

SlurmPlan SmallPlan(const fs::path& dir) {
  SlurmPlan p;
  p.kind = "bench weather";
  p.dir = dir.string();
  p.job_name = "optinav-weather";
  p.args = {"--out", dir.string(), "--scale", "0.1"};
  p.task_command = {"/bin/optinav", "bench", "weather", "--out",  dir.string(),
                    "--scale",      "0.1",   "--task",  "{task}", "--reuse"};
  p.merge_command = {"/bin/optinav", "bench",   "weather", "--out",
                     dir.string(),   "--scale", "0.1",     "--reuse"};
  for (int i = 0; i < 3; ++i)
    p.tasks.push_back(
        {"run " + std::to_string(i), {(dir / ("r" + std::to_string(i) + ".json")).string()}});
  p.task_resources = {2, 1500, 25, "why"};
  p.merge_resources = {1, 2048, 60, "merge"};
  p.slurm_args = "--partition short --time=90";
  return p;
}

TEST(SlurmPlan, WritesThePlanAndTheScripts) {
  const fs::path dir = testing::MakeTempDir("slurm_plan");
  const SlurmPlan p = SmallPlan(dir);
  WriteSlurmPlan(p);
  const nlohmann::json j = nlohmann::json::parse(testing::ReadFile(dir / "plan.json"));
  ASSERT_EQ(j.at("tasks").size(), 3u);
  EXPECT_EQ(j.at("tasks")[2].at("command"),
            nlohmann::json({"/bin/optinav", "bench", "weather", "--out", dir.string(), "--scale",
                            "0.1", "--task", "2", "--reuse"}));
  EXPECT_EQ(j.at("tasks")[2].at("log"), (dir / "logs" / "task_2.log").string());
  EXPECT_EQ(j.at("task_resources").at("mem_mb"), 1500);
  const std::string s = testing::ReadFile(dir / "submit.sbatch");
  for (const std::string& line : std::vector<std::string>{
           "#SBATCH --array=0-2\n", "#SBATCH --cpus-per-task=2\n", "#SBATCH --mem=1500M\n",
           "#SBATCH --time=25\n#SBATCH --output=" + (dir / "logs" / "task_%a.log").string() + "\n",
           // --slurm-args after the derived lines: sbatch takes the last of a repeated option.
           "#SBATCH --open-mode=append\n#SBATCH --partition short\n#SBATCH --time=90\n",
           "--dependency=afterok:${SLURM_ARRAY_JOB_ID} --kill-on-invalid-dep=yes " +
               (dir / "merge.sbatch").string() + "\n",
           "exec /bin/optinav bench weather --out " + dir.string() +
               " --scale 0.1 --task \"${SLURM_ARRAY_TASK_ID}\" --reuse\n"})
    EXPECT_NE(s.find(line), std::string::npos) << line << "\nin\n" << s;
  const std::string m = testing::ReadFile(dir / "merge.sbatch");
  EXPECT_NE(
      m.find("exec /bin/optinav bench weather --out " + dir.string() + " --scale 0.1 --reuse\n"),
      std::string::npos)
      << m;
  EXPECT_TRUE(fs::is_directory(dir / "logs"));

  // Read back.
  const std::optional<SlurmPlan> back = ReadSlurmPlan(dir.string());
  ASSERT_TRUE(back);
  EXPECT_EQ(back->task_command, p.task_command);
  EXPECT_EQ(back->tasks.size(), 3u);
  EXPECT_EQ(TaskCommand(*back, 1)[8], "1");
  EXPECT_FALSE(ReadSlurmPlan((dir / "logs").string()));

  // Unfinished tasks: listed with their logs, the last log line and how to re-submit them.
  testing::WriteFile(dir / "r1.json", "{}");
  testing::WriteFile(dir / "logs" / "task_2.log", "started\nerror: out of memory\n\n");
  EXPECT_EQ(UnfinishedTasks(*back).size(), 2u);
  EXPECT_ERROR(ThrowIfUnfinished(*back), {.file = "plan.json"},
               "2 of 3 planned task(s) unfinished (failed, still running or never run):\n"
               "  task 0 (run 0): missing " +
                   (dir / "r0.json").string() + "; log " + (dir / "logs" / "task_0.log").string() +
                   " (none: never started)\n"
                   "  task 2 (run 2): missing " +
                   (dir / "r2.json").string() + "; log " + (dir / "logs" / "task_2.log").string() +
                   "\n    last log line: error: out of memory\n"
                   "re-submit them alone: sbatch --array=0,2 " +
                   (dir / "submit.sbatch").string());
  testing::WriteFile(dir / "r0.json", "{}");
  testing::WriteFile(dir / "r2.json", "{}");
  ThrowIfUnfinished(*back);

  // The merge: `--out DIR --reuse` alone takes the plan's options; other flags must match them.
  EXPECT_EQ(*PlannedMergeArgs("bench weather", {"--out", dir.string(), "--reuse"}),
            (std::vector<std::string>{"--out", dir.string(), "--scale", "0.1", "--reuse"}));
  EXPECT_FALSE(PlannedMergeArgs("bench gnss", {"--out", dir.string(), "--reuse"}));
  EXPECT_FALSE(PlannedMergeArgs("bench weather", {"--out", dir.string()}));
  EXPECT_FALSE(
      PlannedMergeArgs("bench weather", {"--out", dir.string(), "--reuse", "--seeds", "2"}));
  EXPECT_TRUE(IsPlannedMerge("bench weather", dir.string(),
                             {"--out", dir.string(), "--scale", "0.1", "--reuse", "--jobs", "2"}));
  EXPECT_FALSE(IsPlannedMerge("bench gnss", dir.string(), {"--out", dir.string()}));
  EXPECT_ERROR(IsPlannedMerge("bench weather", dir.string(),
                              {"--out", dir.string(), "--scale", "0.2", "--reuse"}),
               {.file = "plan.json", .field = "--out"},
               "holds a Slurm plan made with other options");

  SlurmPlan bad = p;
  bad.slurm_args = "oops";
  EXPECT_ERROR(WriteSlurmPlan(bad), {.field = "--slurm-args"}, "not an sbatch option");
  testing::WriteFile(dir / "plan.json", "{\"format\": 1}");
  EXPECT_ERROR(ReadSlurmPlan(dir.string()), {.file = "plan.json"}, "cannot read the Slurm plan");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace optinav::app
