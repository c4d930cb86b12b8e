#include "optinav/app/mission_experiment.h"

#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "optinav/maploc/map_db.h"
#include "optinav/report/html_report.h"
#include "optinav/sim/synthetic_ortho.h"
#include "optinav/util/error.h"
#include "optinav/util/testing.h"

namespace optinav::app {
namespace {

namespace fs = std::filesystem;

// A generated 2.6 x 2.6 km farmland orthophoto at 4 m/px and its map for a 500 m altitude (256 px
// frames, 90 deg: 1 km footprint), shared by the tests (the build is the slow part).
class MissionExperimentTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(testing::MakeTempDir("mission_experiment"));
    const std::string ortho = (*dir_ / "ortho.tif").string();
    sim::WriteSyntheticFarmland(ortho, 640, 4.0, 7);
    maploc::MapBuildOptions bo;
    bo.frame_width = bo.frame_height = 256;
    bo.hfov_deg = 90;
    bo.altitude_m = 500;
    maploc::BuildMapDatabase(ortho, bo, (*dir_ / "map.db").string());
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }

  // Two seeded random legs of >= 1.2 km at 40 m/s, a frame every 2 s, in light fog.
  static MissionExperimentOptions Options(const std::string& out) {
    MissionExperimentOptions o;
    o.map_path = (*dir_ / "map.db").string();
    o.out_dir = (*dir_ / out).string();
    o.runs = 2;
    o.min_distance_m = 1200;
    o.margin_m = 250;
    o.weather = "fog:25";
    o.pictures = "summary";
    o.mission.seed = 42;
    o.mission.speed_m_s = 40;
    o.mission.step_s = 2;
    return o;
  }

  static fs::path* dir_;
};
fs::path* MissionExperimentTest::dir_ = nullptr;

TEST_F(MissionExperimentTest, SeededRunsReachTheTargetAndWriteTheSummary) {
  std::vector<int> reported;
  const MissionExperimentOptions opt = Options("out");
  const MissionExperimentResult r =
      RunMissionExperiment(opt, [&](const MissionRunOutcome& run) { reported.push_back(run.run); });
  EXPECT_EQ(reported, (std::vector<int>{1, 2}));
  ASSERT_EQ(r.runs.size(), 2u);
  EXPECT_EQ(r.reached, 2);
  EXPECT_TRUE(r.all_reached());
  // The seeded figures (2 x 26 steps, every frame localized). Frames are perspective views with
  // the flight's attitude and locate is given that attitude with a 0.5 deg error: at 500 m that
  // alone is ~4 m on the ground, so fixes are ~1.4 map px (4 m/px), no longer sub-pixel.
  EXPECT_EQ(r.steps, 52);
  EXPECT_EQ(r.fixes_found, 52);
  EXPECT_EQ(r.fixes_accepted, 52);
  ASSERT_TRUE(r.fix_error_m.has_value());
  EXPECT_NEAR(r.fix_error_m->median, 4.569, 0.01);
  EXPECT_NEAR(r.fix_error_m->p95, 7.682, 0.01);
  EXPECT_NEAR(r.estimate_error_m.median, 4.621, 0.01);
  EXPECT_NEAR(r.final_distance_m.max, 5.216, 0.01);
  // An even count: the median is the mean of the two middle values.
  EXPECT_DOUBLE_EQ(r.final_distance_m.median, r.final_distance_m.mean);
  for (const MissionRunOutcome& run : r.runs) {
    EXPECT_GE(run.mission.straight_distance_m, 1200);
    EXPECT_EQ(run.mission.end_reason, "arrived");
  }

  // summary.json: the figures of the result, under the keys it always had.
  const nlohmann::json s =
      nlohmann::json::parse(testing::ReadFile(fs::path(opt.out_dir) / "summary.json"));
  EXPECT_EQ(s, r.summary);
  EXPECT_EQ(s["runs"], 2);
  EXPECT_EQ(s["reached"], 2);
  EXPECT_DOUBLE_EQ(s["success_rate"].get<double>(), 1.0);
  EXPECT_EQ(s["steps"], r.steps);
  EXPECT_DOUBLE_EQ(s["median_fix_error_m"].get<double>(), r.fix_error_m->median);
  EXPECT_DOUBLE_EQ(s["median_fix_error_map_px"].get<double>(), r.fix_error_m->median / 4.0);
  EXPECT_EQ(s["fix_error_m"]["n"], r.fixes_found);
  for (const char* key : {"fix_rate", "accepted_fix_rate", "estimate_error_m", "final_distance_m",
                          "navigation_steps_per_second", "settings", "per_run"}) {
    EXPECT_TRUE(s.contains(key)) << key;
  }
  for (const char* key : {"feature_extraction", "matching", "position_estimation", "localization",
                          "odometry", "navigation_step", "frame_synthesis"}) {
    EXPECT_TRUE(s["timing_ms"][key].contains("std")) << key;
  }
  EXPECT_EQ(s["settings"]["weather"], "fog:25");
  EXPECT_EQ(s["settings"]["seed"], 42);
  ASSERT_EQ(s["per_run"].size(), 2u);
  EXPECT_EQ(s["per_run"][1]["run"], 2);
  EXPECT_EQ(s["per_run"][1]["reached"], true);

  // Files: the summary picture and GIS files, per-run steps and GIS (no per-run picture with
  // --pictures summary).
  for (const char* f : {"summary.png", "summary.svg", "paths.geojson", "paths.kml",
                        "run_001/steps.csv", "run_002/paths.geojson", "run_002/paths.kml"}) {
    EXPECT_GT(fs::file_size(fs::path(opt.out_dir) / f), 100u) << f;
  }
  EXPECT_FALSE(fs::exists(fs::path(opt.out_dir) / "run_001" / "path.png"));

  // The HTML report's document: what the page draws, from the same runs.
  const report::ReportDocument doc = report::ReadReportDocument(ReportDocumentPath(opt.out_dir));
  EXPECT_EQ(doc.kind, "mission");
  ASSERT_EQ(doc.views.size(), 1u);
  const report::ReportView& v = doc.views[0];
  EXPECT_EQ(v.frame, "wgs84");
  ASSERT_TRUE(v.image);
  EXPECT_GT(fs::file_size(fs::path(opt.out_dir) / v.image->file), 1000u);
  ASSERT_EQ(v.paths.size(), 4u);  // true and estimated, per run
  EXPECT_EQ(v.paths[0].layer, "true paths");
  EXPECT_EQ(v.paths[3].layer, "estimated paths");
  EXPECT_EQ(v.paths[0].points.size(), r.runs[0].mission.steps.size());
  ASSERT_EQ(v.fixes.size(), static_cast<size_t>(r.fixes_found));
  const nav::StepLog& step = r.runs[0].mission.steps[3];
  EXPECT_NEAR(v.fixes[3].point.x(), step.fix.lat_deg, 1e-7);
  EXPECT_NEAR(v.fixes[3].point.y(), step.fix.lon_deg, 1e-7);
  EXPECT_NEAR(v.fixes[3].error_m, step.fix_error_m, 1e-3);
  EXPECT_NEAR(v.fixes[3].t_s, step.t_s, 1e-3);
  EXPECT_EQ(v.fixes[3].method, step.fix_method);
  EXPECT_EQ(v.fixes[3].inliers, step.inliers);
  ASSERT_EQ(v.markers.size(), 4u);  // start and target per run; no run missed
  EXPECT_EQ(v.markers[1].kind, "target");
  EXPECT_NEAR(v.markers[1].point.x(), r.runs[0].target.lat_deg, 1e-7);
  // The map image covers every path.
  for (const report::ReportPath& p : v.paths)
    for (const Eigen::Vector2d& ll : p.points) {
      EXPECT_GT(ll.x(), v.image->min.x());
      EXPECT_LT(ll.x(), v.image->max.x());
      EXPECT_GT(ll.y(), v.image->min.y());
      EXPECT_LT(ll.y(), v.image->max.y());
    }
  ASSERT_TRUE(v.chart);
  EXPECT_EQ(v.chart->series.size(), 3u);  // the fixes' errors, the estimate error per run
  EXPECT_EQ(doc.settings, s["settings"]);

  // The printed table says the same.
  EXPECT_NE(FormatMissionSummary(r).find("reached 2/2 (within 50 m)"), std::string::npos);
  EXPECT_EQ(FormatMissionRunHeader().substr(0, 14), " run    dist_m");
  EXPECT_EQ(FormatMissionRunRow(r.runs[0]),
            "   1      1961     26      yes        1.8     1.00       4.87\n");
  EXPECT_NE(FormatMissionSummary(r).find("fix error median 4.57 m (1.14 map px), p95 7.68 m"),
            std::string::npos)
      << FormatMissionSummary(r);

  // Same seed, same flights.
  const MissionExperimentResult again = RunMissionExperiment(Options("again"));
  EXPECT_EQ(again.summary["per_run"], s["per_run"]);
  EXPECT_EQ(again.summary["fix_error_m"], s["fix_error_m"]);
}

TEST_F(MissionExperimentTest, StartOutsideTheMapIsRefusedBeforeAnythingIsWritten) {
  MissionExperimentOptions opt = Options("refused");
  opt.start = geo::LatLon{10, 10};
  opt.target = geo::LatLon{10.01, 10};
  try {
    RunMissionExperiment(opt);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_NE(e.message().find("is outside the map"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(opt.out_dir));
}

TEST(MissionExperimentOptions, CheckNamesTheFlagAtFault) {
  MissionExperimentOptions o;
  o.map_path = "map.db";
  o.out_dir = "out";
  EXPECT_EQ(o.Check(), "");
  o.runs = 0;
  EXPECT_EQ(o.Check(), "--runs must be in [1, 10000], got 0");
  o.runs = 3;
  o.pictures = "some";
  EXPECT_EQ(o.Check(), "--pictures expected all|summary|none, got 'some'");
  o.pictures = "none";
  o.start = geo::LatLon{47, -99};
  EXPECT_EQ(o.Check().rfind("--start", 0), 0u) << o.Check();
  o.start.reset();
  o.out_dir.clear();
  EXPECT_EQ(o.Check().rfind("--out", 0), 0u) << o.Check();
  // The driver refuses the same options with the same message.
  try {
    RunMissionExperiment(o);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), o.Check());
  }
}

}  // namespace
}  // namespace optinav::app
