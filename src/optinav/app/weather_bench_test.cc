#include "optinav/app/weather_bench.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "optinav/app/internal/weather_bench_report.h"
#include "optinav/io/text_parse.h"
#include "optinav/report/html_report.h"
#include "optinav/sim/camera_noise.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/testing.h"

namespace fs = std::filesystem;

namespace optinav::app {
namespace {

TEST(WeatherBench, SuiteConditionsAndTheDocumentsFigures) {
  // The document's 36 sequences: 24 urban (road effects only there), 12 terrain.
  EXPECT_EQ(SuiteConditions(sim::WorldKind::kUrban).size(), 24u);
  ASSERT_EQ(SuiteConditions(sim::WorldKind::kTerrain).size(), 12u);
  EXPECT_EQ(SuiteConditions(sim::WorldKind::kTerrain)[0].ToString(), "none");
  EXPECT_EQ(SuiteConditions(sim::WorldKind::kTerrain)[11].ToString(), "dust:100");
  const auto doc = [](sim::WorldKind w, const char* c) {
    return DocumentMeanError(w, sim::ParseWeather(c));
  };
  EXPECT_DOUBLE_EQ(doc(sim::WorldKind::kUrban, "none")->mean_error_m, 1.71);
  EXPECT_DOUBLE_EQ(doc(sim::WorldKind::kUrban, "fog:100")->mean_error_m, 3.76);
  EXPECT_DOUBLE_EQ(doc(sim::WorldKind::kUrban, "snow:50")->mean_error_m, 2.38);
  EXPECT_DOUBLE_EQ(doc(sim::WorldKind::kTerrain, "fog:75")->mean_error_m, 106.38);
  EXPECT_TRUE(doc(sim::WorldKind::kTerrain, "dust:100")->lost);
  EXPECT_FALSE(doc(sim::WorldKind::kTerrain, "dust:50")->lost);
  EXPECT_FALSE(doc(sim::WorldKind::kUrban, "road-snow:50"));  // no figure in the document
  EXPECT_FALSE(doc(sim::WorldKind::kUrban, "snow:75"));
}

TEST(WeatherBench, InvalidOptionsNameTheFlag) {
  WeatherBenchOptions o;
  o.out_dir = (fs::temp_directory_path() / "never_written").string();
  o.seeds = 0;
  EXPECT_ERROR(RunWeatherBench(o), {.field = "--seeds"}, "must be >= 1, got 0");
  o.seeds = 1;
  o.worlds = {sim::WorldKind::kTerrain};
  o.conditions = {sim::ParseWeather("road-snow:50")};
  EXPECT_ERROR(RunWeatherBench(o), {.field = "--conditions"}, "urban world only");
  o.worlds = {sim::WorldKind::kUrban};
  o.scale = 0;
  EXPECT_ERROR(RunWeatherBench(o), {.field = "--scale"}, "must be in [0.05, 4], got 0");
  o.scale = 0.5;
  o.vio_config = (fs::temp_directory_path() / "no_such_vio.yaml").string();
  EXPECT_ERROR(RunWeatherBench(o), {.field = "--config"}, "no such file");
  const fs::path bad = fs::temp_directory_path() / "optinav_bad_vio_config.yaml";
  io::WriteFileAtomically(bad.string(), "frontend: [unclosed\n");
  o.vio_config = bad.string();
  EXPECT_ERROR(RunWeatherBench(o), {.file = bad.string(), .line = 2}, "YAML syntax error");
  fs::remove(bad);
  EXPECT_FALSE(fs::exists(o.out_dir));
}

TEST(WeatherBench, ListFlags) {
  WeatherBenchOptions o;
  ParseWeatherBenchLists("terrain", "none,,dust:100", "stereo,stereo-imu", &o);
  ASSERT_EQ(o.worlds.size(), 1u);
  EXPECT_EQ(o.worlds[0], sim::WorldKind::kTerrain);
  ASSERT_EQ(o.conditions.size(), 2u);
  EXPECT_EQ(o.conditions[1].ToString(), "dust:100");
  ASSERT_EQ(o.modes.size(), 2u);
  EXPECT_EQ(o.modes[1], vio::VioMode::kStereoImu);
  ParseWeatherBenchLists("urban", "", "stereo", &o);
  EXPECT_TRUE(o.conditions.empty());  // the suite's
  EXPECT_ERROR(ParseWeatherBenchLists("urban,moon", "", "stereo", &o), {.field = "--worlds"},
               "unknown world 'moon' (urban, terrain)");
  EXPECT_ERROR(ParseWeatherBenchLists("urban", "none,fog:150", "stereo", &o),
               {.field = "--conditions"}, "weather intensity 150 % is outside 0-100");
  EXPECT_ERROR(ParseWeatherBenchLists("urban", "", "mono", &o), {.field = "--modes"},
               "unknown mode 'mono'");
}

bool Said(const std::vector<std::string>& lines, const std::string& what) {
  for (const std::string& l : lines)
    if (l.find(what) != std::string::npos) return true;
  return false;
}

// The table's title names a camera noise other than the default, custom values included.
TEST(WeatherBench, TableTitleNamesTheCameraNoise) {
  WeatherBenchOptions o;
  const auto title = [&](const std::string& noise) {
    o.camera_noise = sim::ParseCameraNoise(noise, "--camera-noise");
    const std::string t = internal::WeatherBenchTable(o, {}, {});
    return t.substr(0, t.find('\n'));
  };
  EXPECT_EQ(title("on").find("camera-noise"), std::string::npos);
  EXPECT_EQ(title("0.8:0.02").find("camera-noise"), std::string::npos);
  EXPECT_NE(title("off").find(", --camera-noise off;"), std::string::npos) << title("off");
  EXPECT_NE(title("1.5:0.04").find(", --camera-noise 1.5:0.04;"), std::string::npos)
      << title("1.5:0.04");
}

// A loop is checked against the truth's translation between its two keyframes: one measured as
// the truth has it passes, one a road-texture period (8 m) off does not; a loop without its
// relative pose (stats written before it) is not checked.
TEST(WeatherBench, LoopsOffTheTruth) {
  Trajectory truth;
  for (int i = 0; i <= 100; ++i) {  // 10 m/s along x, turning slowly
    const double t = 0.1 * i;
    truth.Add(static_cast<int64_t>(t * 1e9),
              Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.05 * t, Eigen::Vector3d::UnitZ())),
                      Eigen::Vector3d(10 * t, 0.5 * t * t, 0)));
  }
  const Rigid3d old_body_from_new_body = truth.pose(20).Inverse() * truth.pose(90);
  auto loop = [&](const Eigen::Vector3d& translation_offset) {
    const Eigen::Vector3d t = old_body_from_new_body.translation + translation_offset;
    const Eigen::Quaterniond q = old_body_from_new_body.rotation;
    return nlohmann::json{
        {"old_keyframe_s", 2.0},
        {"new_keyframe_s", 9.0},
        {"old_body_from_new_body", {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}}};
  };
  nlohmann::json loops = nlohmann::json::array();
  loops.push_back(loop({0.3, -0.2, 0.1}));  // 0.37 m off: within 1 m
  loops.push_back(loop({8.0, 0, 0}));       // one period off
  loops.push_back({{"old_keyframe_s", 2.0}, {"new_keyframe_s", 9.0}});
  const auto [checked, off] = LoopsOffTruth(truth, loops);
  EXPECT_EQ(checked, 2u);
  EXPECT_EQ(off, 1u);
  EXPECT_EQ(LoopsOffTruth(truth, loops, 0.2).second, 2u);
}

// Six seconds of the urban car route at 400x300, clear and in 100 % dust, two jobs: the real
// pipeline end to end (rendering, threaded VIO, the metrics, the files), then --reuse.
TEST(WeatherBench, ShortUrbanRouteClearAndDustThenReuse) {
  const fs::path dir = testing::MakeTempDir("weather_bench");
  WeatherBenchOptions o;
  o.out_dir = dir.string();
  o.worlds = {sim::WorldKind::kUrban};
  o.conditions = {sim::ParseWeather("none"), sim::ParseWeather("dust:100")};
  o.duration_s = 6;
  o.jobs = 2;
  std::vector<std::string> lines;
  const auto say = [&](const std::string& l) { lines.push_back(l); };
  const WeatherBenchResult r = RunWeatherBench(o, say);
  std::printf("%s", r.table.c_str());
  ASSERT_EQ(r.runs.size(), 2u);
  ASSERT_EQ(r.cells.size(), 2u);
  EXPECT_TRUE(Said(lines, "rendering urban_default (seed 1)"));
  EXPECT_TRUE(Said(lines, "rendering urban_dust_100 (seed 1)"));
  EXPECT_TRUE(Said(lines, "] urban_dust_100, stereo, seed 1: mean error "));
  for (const WeatherRunResult& run : r.runs) {
    SCOPED_TRACE(run.sequence);
    ASSERT_TRUE(run.ok) << run.error;
    EXPECT_FALSE(run.reused);
    EXPECT_EQ(run.frames, 201u);  // 6 s at 30 ms, both ends
    EXPECT_GT(run.path_length_m, 5.0);
    // A few metres of route: the odometry's error after the start pose stays well under 1 m.
    EXPECT_LT(run.mean_error_m, 1.0);
    EXPECT_GT(run.mean_error_m, 0.0);
    // A straight stretch: the SE(3) fit is undetermined (roll about the line), no APE.
    EXPECT_TRUE(std::isnan(run.ape_rmse_se3_m));
    EXPECT_GT(run.coverage, 0.9);
    EXPECT_GT(run.fps, 1.0);
    EXPECT_FALSE(run.Lost());
  }
  const WeatherCell& clear = r.cells[0];
  const WeatherCell& dust = r.cells[1];
  EXPECT_EQ(clear.condition.ToString(), "none");
  EXPECT_DOUBLE_EQ(clear.ratio_to_clear, 1.0);
  EXPECT_DOUBLE_EQ(dust.ratio_to_clear, r.runs[1].mean_error_m / r.runs[0].mean_error_m);
  EXPECT_NEAR(dust.document_ratio_to_clear, 2.68 / 1.71, 1e-12);
  // The files.
  for (const char* f :
       {"results.json", "table.md", "table.csv", "weather_error.svg", "weather_error.png",
        "runs/urban_dust_100_stereo_seed1.tum", "runs/urban_dust_100_stereo_seed1.json",
        "sequences/seed1_6s/urban_dust_100/sim_complete.json"})
    EXPECT_TRUE(fs::is_regular_file(dir / f)) << f;
  const nlohmann::json j = nlohmann::json::parse(testing::ReadFile(dir / "results.json"));
  EXPECT_EQ(j.at("cells").size(), 2u);
  EXPECT_DOUBLE_EQ(j.at("cells")[1].at("orbslam3").at("mean_error_m").get<double>(), 2.68);
  EXPECT_DOUBLE_EQ(j.at("runs")[1].at("mean_error_m").get<double>(), r.runs[1].mean_error_m);
  // The HTML report's document: the truth and both runs (first pose on the truth's).
  const report::ReportDocument doc = report::ReadReportDocument((dir / "report.json").string());
  EXPECT_EQ(doc.kind, "bench weather");
  ASSERT_EQ(doc.views.size(), 1u);
  ASSERT_EQ(doc.views[0].paths.size(), 3u);
  EXPECT_EQ(doc.views[0].paths[2].layer, "dust:100, stereo");
  EXPECT_NEAR((doc.views[0].paths[2].points[0] - doc.views[0].paths[0].points[0]).norm(), 0,
              1e-3);  // the first pose is put on the truth's
  ASSERT_TRUE(doc.views[0].chart);
  EXPECT_EQ(doc.views[0].chart->series.size(), 2u);
  EXPECT_NE(r.table.find("| urban | dust:100 | stereo | "), std::string::npos) << r.table;
  EXPECT_EQ(testing::ReadFile(dir / "table.md"), r.table);
  const std::string csv = testing::ReadFile(dir / "table.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 3);

  // --reuse: nothing rendered or run again, the same figures from the same files.
  o.reuse = true;
  lines.clear();
  const WeatherBenchResult again = RunWeatherBench(o, say);
  EXPECT_FALSE(Said(lines, "rendering"));
  ASSERT_EQ(again.runs.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_TRUE(again.runs[i].reused);
    EXPECT_DOUBLE_EQ(again.runs[i].mean_error_m, r.runs[i].mean_error_m);
    EXPECT_DOUBLE_EQ(again.runs[i].fps, r.runs[i].fps);
  }
  EXPECT_TRUE(Said(lines, "(reused) mean error"));

  // An interrupted rendering (no completion marker) is rendered and run again; the other kept.
  fs::remove(dir / "sequences/seed1_6s/urban_dust_100/sim_complete.json");
  lines.clear();
  const WeatherBenchResult resumed = RunWeatherBench(o, say);
  EXPECT_TRUE(Said(lines, "rendering urban_dust_100"));
  EXPECT_FALSE(Said(lines, "rendering urban_default"));
  EXPECT_TRUE(resumed.runs[0].reused);
  EXPECT_FALSE(resumed.runs[1].reused);
  EXPECT_TRUE(resumed.runs[1].ok);

  // A record made by a binary with other defaults (its effective options differ) is run again.
  std::vector<fs::path> records;
  for (const auto& e : fs::directory_iterator(dir / "runs"))
    if (e.path().extension() == ".json" && e.path().string().find(".stats.") == std::string::npos)
      records.push_back(e.path());
  ASSERT_EQ(records.size(), 2u);
  nlohmann::json record = nlohmann::json::parse(testing::ReadFile(records[0]));
  const std::string yaml = record.at("vio_options_yaml").get<std::string>();
  EXPECT_EQ(yaml.rfind("mode: stereo\n", 0), 0u) << yaml;
  record["vio_options_yaml"] = yaml + "# another binary\n";
  io::WriteFileAtomically(records[0].string(), record.dump(2));
  const WeatherBenchResult stale = RunWeatherBench(o, say);
  EXPECT_EQ(std::count_if(stale.runs.begin(), stale.runs.end(),
                          [](const WeatherRunResult& run) { return run.reused; }),
            1);

  // --config: the runs made with other VIO options are run again; the renderings are kept.
  o.vio_config = (dir / "vio.yaml").string();
  io::WriteFileAtomically(o.vio_config, "frontend:\n  detect_min_eigen: 0\n");
  lines.clear();
  const WeatherBenchResult configured = RunWeatherBench(o, say);
  EXPECT_FALSE(Said(lines, "rendering"));
  ASSERT_EQ(configured.runs.size(), 2u);
  for (const WeatherRunResult& run : configured.runs) {
    EXPECT_FALSE(run.reused);
    EXPECT_TRUE(run.ok);
  }
  lines.clear();
  EXPECT_TRUE(RunWeatherBench(o, say).runs[0].reused);  // the same text: kept

  // A sequence from an older renderer (its marker without "renderer", as before version 2) is
  // rendered and run again; the other is kept.
  const fs::path clear_marker = dir / "sequences/seed1_6s/urban_default/sim_complete.json";
  nlohmann::json marker = nlohmann::json::parse(testing::ReadFile(clear_marker));
  EXPECT_EQ(marker.at("renderer"), sim::kRendererVersion);
  marker.erase("renderer");
  io::WriteFileAtomically(clear_marker.string(), marker.dump(2));
  // Runs the bench again, expecting the sequence `redone` (0 clear, 1 dust) rendered and run
  // again and the other kept.
  const char* const names[] = {"urban_default", "urban_dust_100"};
  auto expect_only_redone = [&](size_t redone) {
    SCOPED_TRACE(names[redone]);
    lines.clear();
    const WeatherBenchResult result = RunWeatherBench(o, say);
    EXPECT_TRUE(Said(lines, std::string("rendering ") + names[redone]));
    EXPECT_FALSE(Said(lines, std::string("rendering ") + names[1 - redone]));
    ASSERT_EQ(result.runs.size(), 2u);
    EXPECT_FALSE(result.runs[redone].reused);
    EXPECT_TRUE(result.runs[redone].ok);
    EXPECT_TRUE(result.runs[1 - redone].reused);
  };
  expect_only_redone(0);

  // A rendering with frozen particles (`sim --particles-still`, diagnostics) is not the
  // condition: rendered again.
  const fs::path dust_marker = dir / "sequences/seed1_6s/urban_dust_100/sim_complete.json";
  marker = nlohmann::json::parse(testing::ReadFile(dust_marker));
  marker["particles_still"] = true;
  io::WriteFileAtomically(dust_marker.string(), marker.dump(2));
  expect_only_redone(1);
  EXPECT_FALSE(nlohmann::json::parse(testing::ReadFile(dust_marker)).contains("particles_still"));

  // The default asphalt is varied, and the marker says so.
  EXPECT_EQ(nlohmann::json::parse(testing::ReadFile(dust_marker)).at("asphalt"), "varied");
  // --asphalt tiled: both urban sequences rendered and run again, recorded in their markers and
  // run records; back to varied, the same again. A marker without the key (rendered before the
  // key existed) is tiled.
  o.varied_asphalt = false;
  lines.clear();
  const WeatherBenchResult tiled = RunWeatherBench(o, say);
  EXPECT_TRUE(Said(lines, "rendering urban_default"));
  EXPECT_TRUE(Said(lines, "rendering urban_dust_100"));
  ASSERT_EQ(tiled.runs.size(), 2u);
  for (const WeatherRunResult& run : tiled.runs) {
    EXPECT_FALSE(run.reused);
    EXPECT_TRUE(run.ok);
  }
  EXPECT_EQ(nlohmann::json::parse(testing::ReadFile(dust_marker)).at("asphalt"), "tiled");
  EXPECT_EQ(nlohmann::json::parse(testing::ReadFile(dir / "runs/urban_dust_100_stereo_seed1.json"))
                .at("asphalt"),
            "tiled");
  EXPECT_NE(tiled.table.find("--asphalt tiled"), std::string::npos);
  marker = nlohmann::json::parse(testing::ReadFile(dust_marker));
  marker.erase("asphalt");
  io::WriteFileAtomically(dust_marker.string(), marker.dump(2));
  o.reuse = true;
  lines.clear();
  EXPECT_TRUE(RunWeatherBench(o, say).runs[1].reused);
  o.varied_asphalt = true;
  lines.clear();
  const WeatherBenchResult varied = RunWeatherBench(o, say);
  EXPECT_TRUE(Said(lines, "rendering urban_default"));
  EXPECT_FALSE(varied.runs[0].reused);
  EXPECT_EQ(varied.table.find("--asphalt"), std::string::npos);
  EXPECT_EQ(nlohmann::json::parse(testing::ReadFile(dust_marker)).at("asphalt"), "varied");
  fs::remove_all(dir);
}

// A planned sweep run task by task (as Slurm's array tasks would), then merged: the merge lists
// unfinished tasks until all are done, then writes the tables a single-machine run writes from
// the same run files, byte for byte; with the timing of an independent single-machine run put in
// the records, byte for byte that run's tables.
TEST(WeatherBench, PlannedTasksMergeIntoTheSingleMachineTables) {
  const fs::path dir = testing::MakeTempDir("weather_tasks");
  WeatherBenchOptions o;
  o.worlds = {sim::WorldKind::kUrban};
  o.conditions = {sim::ParseWeather("none"), sim::ParseWeather("fog:50")};
  o.scale = 0.2;
  o.duration_s = 3;
  o.out_dir = (dir / "single").string();
  const WeatherBenchResult single = RunWeatherBench(o);
  ASSERT_TRUE(single.runs[0].ok && single.runs[1].ok);

  o.out_dir = (dir / "sweep").string();
  const std::vector<PlannedTask> tasks = WeatherBenchTasks(o);
  ASSERT_EQ(tasks.size(), 2u);
  EXPECT_EQ(tasks[1].label, "urban_fog_50 stereo seed 1");
  EXPECT_EQ(tasks[1].outputs.back(), o.out_dir + "/runs/urban_fog_50_stereo_seed1.json");
  const SlurmPlan plan = WriteSweepPlan("bench weather", o.out_dir,
                                        {"--out", o.out_dir, "--worlds", "urban", "--conditions",
                                         "none,fog:50", "--scale", "0.2", "--duration", "3"},
                                        tasks, WeatherBenchTaskResources(o), "");
  EXPECT_EQ(plan.task_command.back(), "--reuse");
  WeatherBenchOptions merge = o;
  merge.reuse = merge.merge = true;
  EXPECT_ERROR(RunWeatherBench(merge), {.file = "plan.json"},
               "re-submit them alone: sbatch --array=0,1 ");
  WeatherBenchOptions task = o;
  task.reuse = true;
  task.task = 1;
  const WeatherBenchResult one = RunWeatherBench(task);
  ASSERT_EQ(one.runs.size(), 1u);
  EXPECT_EQ(one.runs[0].sequence, "urban_fog_50");
  EXPECT_FALSE(fs::exists(dir / "sweep" / "table.md"));  // a task writes its run files only
  EXPECT_FALSE(fs::exists(dir / "sweep" / "sequences" / "seed1_3s" / "urban_default"));
  EXPECT_ERROR(RunWeatherBench(merge), {.file = "plan.json"}, "1 of 2 planned task(s) unfinished");
  task.task = 0;
  RunWeatherBench(task);
  task.task = 2;
  EXPECT_ERROR(RunWeatherBench(task), {.field = "--task"}, "task 2 does not exist");
  const WeatherBenchResult merged = RunWeatherBench(merge);
  EXPECT_TRUE(merged.runs[0].reused && merged.runs[1].reused);
  // The same run files read by a single-machine --reuse run: the same bytes.
  WeatherBenchOptions again = o;
  again.reuse = true;
  again.out_dir = (dir / "again").string();
  fs::copy(dir / "sweep", dir / "again", fs::copy_options::recursive);
  RunWeatherBench(again);
  for (const char* f : {"table.md", "table.csv"})
    EXPECT_EQ(testing::ReadFile(dir / "again" / f), testing::ReadFile(dir / "sweep" / f)) << f;
  // The independent single-machine run: every figure but the timing is the same.
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(merged.runs[i].mean_error_m, single.runs[i].mean_error_m);
    EXPECT_EQ(merged.runs[i].ape_rmse_se3_m == merged.runs[i].ape_rmse_se3_m,
              single.runs[i].ape_rmse_se3_m == single.runs[i].ape_rmse_se3_m);
    EXPECT_EQ(merged.runs[i].frames, single.runs[i].frames);
    // Its timing into the sweep's records: then the tables are the single run's, to the byte.
    const std::string stem =
        "runs/" + std::string(i == 0 ? "urban_default" : "urban_fog_50") + "_stereo_seed1.json";
    nlohmann::json rec = nlohmann::json::parse(testing::ReadFile(dir / "sweep" / stem));
    const nlohmann::json ref = nlohmann::json::parse(testing::ReadFile(dir / "single" / stem));
    for (const char* k : {"wall_s", "fps", "frame_median_ms", "frame_p95_ms"}) rec[k] = ref[k];
    testing::WriteFile(dir / "sweep" / stem, rec.dump(2) + "\n");
  }
  RunWeatherBench(merge);
  for (const char* f : {"table.md", "table.csv"})
    EXPECT_EQ(testing::ReadFile(dir / "sweep" / f), testing::ReadFile(dir / "single" / f)) << f;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace optinav::app
