#include "optinav/app/gnss_bench.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "optinav/report/html_report.h"
#include "optinav/util/testing.h"

namespace fs = std::filesystem;

namespace optinav::app {
namespace {

// A 90 s flight at 100 Hz: a 20 m circle every 30 s, climbing, yawing along the path.
Trajectory CircleFlight() {
  Trajectory t;
  const int64_t t0 = 1'000'000'000'000;
  for (int64_t i = 0; i <= 9000; ++i) {
    const double s = i * 0.01, a = 2 * M_PI * s / 30;
    const Eigen::Quaterniond q(Eigen::AngleAxisd(a + M_PI / 2, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()));
    t.Add(t0 + i * 10'000'000,
          Rigid3d(q, Eigen::Vector3d(20 * std::cos(a), 20 * std::sin(a), 5 + 0.1 * s)));
  }
  return t;
}

const Eigen::Vector3d kLever(0.1, -0.05, 0.2);

Eigen::Vector3d Antenna(const Trajectory& truth, int64_t t_ns) {
  return *truth.InterpolateAt(t_ns) * kLever;
}

TEST(GnssBenchConditions, KeysNamesAndParameters) {
  EXPECT_EQ(AllGnssConditions().size(), 6u);
  for (GnssCondition c : AllGnssConditions())
    EXPECT_EQ(ParseGnssCondition(ConditionSpec(c).key), c);
  EXPECT_FALSE(ParseGnssCondition("rain"));
  EXPECT_FALSE(ParseGnssCondition("sigma 3 m"));  // the name is not a key
  EXPECT_EQ(ConditionLabel(GnssCondition::kOutage), "3 m + 60 s outage");
  EXPECT_EQ(ConditionLabel(std::nullopt), "no GNSS");
  EXPECT_EQ(NormLabel(std::nullopt), "-");
  EXPECT_EQ(NormLabel(vio::GnssNorm::kTukey), "tukey");
  const GnssConditionSpec& outliers = ConditionSpec(GnssCondition::kOutliers);
  EXPECT_EQ(outliers.sigma_m, 3.0);
  EXPECT_EQ(outliers.outlier_fraction, 0.10);
  EXPECT_EQ(ConditionSpec(GnssCondition::kOutage).outage_s, 60.0);
  EXPECT_EQ(ConditionSpec(GnssCondition::kIdeal).factor_sigma_m, 0.05);
  EXPECT_EQ(ParseGnssBenchSequence("outdoor"), GnssBenchSequence::kOutdoor);
  EXPECT_FALSE(ParseGnssBenchSequence("moon"));
}

TEST(GnssBenchOptions, Check) {
  GnssBenchOptions o;
  EXPECT_EQ(o.Check(), "--out must not be empty");
  o.out_dir = testing::MakeTempDir("gnss_bench_check").string() + "/out";
  EXPECT_EQ(o.Check(), "");
  o.seeds = 0;
  EXPECT_EQ(o.Check(), "--seeds must be >= 1");
  EXPECT_ERROR(RunGnssBench(o), {.field = "--seeds"}, "must be >= 1");
  EXPECT_FALSE(fs::exists(o.out_dir));  // nothing written on bad options
  o.seeds = 1;
  o.jobs = 0;
  EXPECT_EQ(o.Check(), "--jobs must be >= 1");
  o.jobs = 1;
  o.scale = 0;
  EXPECT_EQ(o.Check(), "--scale must be > 0, got 0");
  o.scale = 1;
  o.fusion.factor_sigma_scale = 0;
  EXPECT_EQ(o.Check().rfind("--gnss factor_sigma_scale", 0), 0u) << o.Check();
}

// The draws of the benchmark's original generator (before it moved into sim::SimulateGnss,
// checked sample by sample against it when it moved): the figures in bench/RESULTS.md depend on
// them.
TEST(GnssBenchGnss, SameDrawsAsBefore) {
  const std::vector<vio::GnssSample> g =
      MakeConditionGnss(CircleFlight(), kLever, 20.0, GnssCondition::kSigma3, 1);
  ASSERT_GT(g.size(), 8u);
  EXPECT_NEAR(g[0].position_enu_m.x(), 19.077183951888781, 1e-12);
  EXPECT_NEAR(g[0].position_enu_m.y(), -5.8665647193079051, 1e-12);
  EXPECT_NEAR(g[0].position_enu_m.z(), 7.9299827107504237, 1e-12);
  EXPECT_NEAR(g[7].position_enu_m.x(), 16.853190058892942, 1e-12);
  EXPECT_NEAR(g[7].position_enu_m.y(), 6.7315236578906159, 1e-12);
  EXPECT_NEAR(g[7].position_enu_m.z(), 11.121770501823839, 1e-12);
}

TEST(GnssBenchGnss, DeterministicWithCommonRandomNumbers) {
  const Trajectory truth = CircleFlight();
  const int64_t t0 = truth.t_ns.front();
  const auto make = [&](GnssCondition c, int seed) {
    return MakeConditionGnss(truth, kLever, 20.0, c, seed);
  };
  const std::vector<vio::GnssSample> sigma3 = make(GnssCondition::kSigma3, 1);
  // 5 Hz from 0.1 s after the start to the end (89.9 s).
  ASSERT_EQ(sigma3.size(), 450u);
  for (size_t i = 0; i < sigma3.size(); ++i) {
    ASSERT_EQ(sigma3[i].t_ns, t0 + 100'000'000 + static_cast<int64_t>(i) * 200'000'000);
    ASSERT_EQ(sigma3[i].sigma_m, 3.0);
  }
  const std::vector<vio::GnssSample> again = make(GnssCondition::kSigma3, 1);
  const std::vector<vio::GnssSample> seed2 = make(GnssCondition::kSigma3, 2);
  double rms = 0;
  for (size_t i = 0; i < sigma3.size(); ++i) {
    EXPECT_EQ(again[i].position_enu_m, sigma3[i].position_enu_m);
    EXPECT_NE(seed2[i].position_enu_m, sigma3[i].position_enu_m);
    rms += (sigma3[i].position_enu_m - Antenna(truth, sigma3[i].t_ns)).squaredNorm();
  }
  EXPECT_NEAR(std::sqrt(rms / sigma3.size() / 3), 3.0, 0.3);

  // Ideal: the antenna itself. 0.5 m: the 3 m draw scaled.
  const std::vector<vio::GnssSample> ideal = make(GnssCondition::kIdeal, 1);
  const std::vector<vio::GnssSample> half = make(GnssCondition::kSigma0_5, 1);
  ASSERT_EQ(ideal.size(), sigma3.size());
  ASSERT_EQ(half.size(), sigma3.size());
  for (size_t i = 0; i < sigma3.size(); ++i) {
    const Eigen::Vector3d antenna = Antenna(truth, sigma3[i].t_ns);
    EXPECT_LT((ideal[i].position_enu_m - antenna).norm(), 1e-12);
    EXPECT_LT(
        ((half[i].position_enu_m - antenna) * 6 - (sigma3[i].position_enu_m - antenna)).norm(),
        1e-9);
  }
  EXPECT_EQ(ideal[0].sigma_m, 0.05);

  // Outliers: the 3 m samples, about 10 % of them moved by 20-50 m.
  const std::vector<vio::GnssSample> outliers = make(GnssCondition::kOutliers, 1);
  ASSERT_EQ(outliers.size(), sigma3.size());
  int moved = 0;
  for (size_t i = 0; i < sigma3.size(); ++i) {
    ASSERT_EQ(outliers[i].t_ns, sigma3[i].t_ns);
    const double d = (outliers[i].position_enu_m - sigma3[i].position_enu_m).norm();
    if (d == 0) continue;
    ++moved;
    EXPECT_GE(d, 20.0 - 1e-9);
    EXPECT_LE(d, 50.0 + 1e-9);
  }
  EXPECT_GT(moved, 25);
  EXPECT_LT(moved, 65);

  // Outage: the 3 m samples without those in [20 s, 80 s).
  const std::vector<vio::GnssSample> outage = make(GnssCondition::kOutage, 1);
  ASSERT_EQ(outage.size(), 150u);
  size_t j = 0;
  for (const vio::GnssSample& s : sigma3) {
    const double t = (s.t_ns - t0) * 1e-9;
    if (t >= 20 && t < 80) continue;
    ASSERT_LT(j, outage.size());
    EXPECT_EQ(outage[j].t_ns, s.t_ns);
    EXPECT_EQ(outage[j].position_enu_m, s.position_enu_m);
    ++j;
  }
  EXPECT_EQ(j, outage.size());
}

// The room flight, 20 s at 0.3 x the image size: the VIO alone and one fused run (ideal GNSS,
// Huber); then --reuse takes both back, and a run made with other fusion settings is made again.
TEST(GnssBenchRun, SmallRoomRunAndReuse) {
  GnssBenchOptions o;
  const fs::path root = testing::MakeTempDir("gnss_bench");
  o.out_dir = (root / "out").string();
  o.sequences = {GnssBenchSequence::kRoom};
  o.conditions = {GnssCondition::kIdeal};
  o.norms = {vio::GnssNorm::kHuber};
  o.seeds = 1;
  o.jobs = 1;
  o.scale = 0.3;
  o.duration_s = 20;
  std::vector<std::string> lines;
  const auto progress = [&](const std::string& line) { lines.push_back(line); };
  const GnssBenchResult first = RunGnssBench(o, progress);
  std::printf("%s", first.tables.c_str());
  ASSERT_EQ(first.sequences.size(), 1u);
  EXPECT_EQ(first.sequences[0].name, "room");
  EXPECT_GT(first.sequences[0].length_m, 20.0);
  ASSERT_EQ(first.runs.size(), 2u);
  const GnssRunResult& alone = first.runs[0];
  const GnssRunResult& fused = first.runs[1];
  ASSERT_TRUE(alone.ok) << alone.error;
  ASSERT_TRUE(fused.ok) << fused.error;
  EXPECT_FALSE(alone.condition);
  EXPECT_EQ(fused.condition, GnssCondition::kIdeal);
  EXPECT_LT(alone.ate_se3, 0.2);  // 0.108 when written
  EXPECT_TRUE(fused.aligned);
  EXPECT_GT(fused.factors, 50u);
  EXPECT_LT(fused.ate_se3, 0.1);  // 0.072
  EXPECT_LT(fused.ate_se3, alone.ate_se3);
  EXPECT_LT(fused.global_rmse, 0.15);  // 0.091; the VIO alone's 0.271
  EXPECT_LT(fused.global_rmse, alone.global_rmse);
  EXPECT_TRUE(std::isfinite(fused.ate_se3_live));
  EXPECT_TRUE(first.never_worse);
  EXPECT_NE(first.tables.find("| ideal                  | huber |"), std::string::npos);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0].rfind("bench gnss: rendering the room sequence -> ", 0), 0u);
  EXPECT_EQ(lines[2].rfind("bench gnss: [1/1] room, ideal, huber, seed 1: ATE ", 0), 0u);

  const fs::path out = o.out_dir;
  for (const char* f : {"results.csv", "results.json", "tables.md", "error_room.svg",
                        "runs/room_no_GNSS___seed0.tum", "runs/room_no_GNSS___seed0.json",
                        "runs/room_ideal_huber_seed1.tum", "runs/room_ideal_huber_seed1.live.tum",
                        "runs/room_ideal_huber_seed1.json"})
    EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
  EXPECT_EQ(testing::ReadFile(out / "tables.md"), first.tables);
  const std::string csv = testing::ReadFile(out / "results.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 3);
  EXPECT_NE(csv.find("\nroom,ideal,huber,1,1,1,"), std::string::npos);
  // The HTML report's document: truth, the VIO alone and the fused run in ENU, the fused run's
  // GNSS samples as fixes.
  const report::ReportDocument doc = report::ReadReportDocument((out / "report.json").string());
  EXPECT_EQ(doc.kind, "bench gnss");
  ASSERT_EQ(doc.views.size(), 1u);
  const report::ReportView& v = doc.views[0];
  EXPECT_EQ(v.frame, "local");
  ASSERT_EQ(v.paths.size(), 3u);
  EXPECT_EQ(v.paths[0].layer, "ground truth");
  EXPECT_EQ(v.paths[1].layer, "VIO alone (first 5 s aligned)");
  EXPECT_EQ(v.paths[2].layer, "ideal, huber");
  const std::vector<vio::GnssSample> samples =
      MakeConditionGnss(first.sequences[0].truth, first.sequences[0].lever_arm_in_body,
                        first.sequences[0].outage_start_s, GnssCondition::kIdeal, 1);
  ASSERT_EQ(v.fixes.size(), samples.size());
  EXPECT_LT(v.fixes[10].error_m, 1e-3);  // ideal: the antenna itself
  EXPECT_NEAR(v.fixes[10].point.x(), samples[10].position_enu_m.y(), 1e-3);  // [north, east]
  ASSERT_EQ(doc.tables.size(), 1u);
  EXPECT_EQ(doc.tables[0].rows.size(), 2u);

  // --reuse: no rendering, no VIO run, the same figures.
  o.reuse = true;
  lines.clear();
  const GnssBenchResult reused = RunGnssBench(o, progress);
  ASSERT_EQ(reused.runs.size(), 2u);
  EXPECT_TRUE(reused.runs[0].reused);
  EXPECT_TRUE(reused.runs[1].reused);
  // Recomputed from the run's TUM file (its digits): the same to well under the printed ones.
  EXPECT_NEAR(reused.runs[1].ate_se3, fused.ate_se3, 1e-6);
  EXPECT_NEAR(reused.runs[1].global_rmse, fused.global_rmse, 1e-6);
  EXPECT_EQ(reused.tables, first.tables);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_NE(lines[1].find("(reused) ATE"), std::string::npos);

  // Other fusion settings: the fused run is made again, the VIO alone is not.
  o.fusion.factor_sigma_scale = 2;
  const GnssBenchResult rerun = RunGnssBench(o);
  ASSERT_EQ(rerun.runs.size(), 2u);
  EXPECT_TRUE(rerun.runs[0].reused);
  EXPECT_FALSE(rerun.runs[1].reused);
  EXPECT_TRUE(rerun.runs[1].ok) << rerun.runs[1].error;
  EXPECT_NE(testing::ReadFile(out / "runs/room_ideal_huber_seed1.json")
                .find("\"factor_sigma_scale\": 2.0"),
            std::string::npos);

  // Another --duration: the sequence is not of these options, so it is rendered again (the
  // reason printed) and both runs made again on it.
  o.duration_s = 15;
  lines.clear();
  const GnssBenchResult shorter = RunGnssBench(o, progress);
  ASSERT_FALSE(lines.empty());
  EXPECT_NE(lines[0].find("(not reused: requested_duration_s: 20.0 (wanted 15.0))"),
            std::string::npos)
      << lines[0];
  ASSERT_EQ(shorter.runs.size(), 2u);
  EXPECT_FALSE(shorter.runs[0].reused);
  EXPECT_FALSE(shorter.runs[1].reused);
  fs::remove_all(root);
}

}  // namespace
}  // namespace optinav::app
