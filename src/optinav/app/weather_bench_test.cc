#include "optinav/app/weather_bench.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "optinav/report/html_report.h"
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
  fs::remove_all(dir);
}

}  // namespace
}  // namespace optinav::app
