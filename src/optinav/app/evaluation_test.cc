// The evaluation driver on evo's own test data (../shared/data/trajectories). The figures are
// those eval/evo_reference reproduces with a naive re-implementation of evo's code path (printed
// by `optinav eval` to 6 decimals), so a change in reading, association, alignment or the
// statistics shows up here as well as in the JSON written.
#include "optinav/app/evaluation.h"

#include <algorithm>
#include <filesystem>

#include <gtest/gtest.h>

#include "optinav/util/error.h"
#include "optinav/util/testing.h"

namespace optinav::app {
namespace {

std::string Data(const std::string& name) {
  return (testing::SharedDataDir() / "trajectories" / name).string();
}

TEST(Evaluation, ApeSe3OnKittiWritesJsonPlotAndAlignedEstimate) {
  const std::filesystem::path dir = testing::MakeTempDir("app_evaluation");
  EvaluationSettings st;
  st.ref_path = Data("KITTI_00_gt.txt");
  st.est_path = Data("KITTI_00_ORB.txt");
  st.alignment.mode = eval::AlignMode::kSe3;
  st.json_path = (dir / "ape.json").string();
  st.plot_path = (dir / "ape.svg").string();
  st.plot_plane = "xz";
  st.aligned_out_path = (dir / "aligned.txt").string();
  const EvaluationOutcome o = RunEvaluation(st);
  EXPECT_EQ(o.ref_poses, 4541u);
  EXPECT_EQ(o.est_poses, 4541u);
  EXPECT_TRUE(o.synced.by_index);
  EXPECT_EQ(o.title, "APE w.r.t. translation part (m)");
  const eval::Statistics& s = o.series.stats;
  EXPECT_EQ(s.n, 4541u);
  EXPECT_NEAR(s.rmse, 1.303450, 1e-6);
  EXPECT_NEAR(s.mean, 1.156997, 1e-6);
  EXPECT_NEAR(s.max, 3.587949, 1e-6);

  const nlohmann::json j = nlohmann::json::parse(testing::ReadFile(st.json_path));
  for (const char* key : {"metric", "pose_relation", "unit", "n", "rmse", "mean", "median", "std",
                          "min", "max", "sse", "alignment", "association", "ref", "est"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_FALSE(j.contains("delta"));  // RPE only
  EXPECT_EQ(j["metric"], "ape");
  EXPECT_EQ(j["alignment"]["mode"], "se3");
  EXPECT_EQ(j["association"]["by_index"], true);
  EXPECT_DOUBLE_EQ(j["rmse"].get<double>(), s.rmse);
  EXPECT_EQ(j, o.json);
  const std::string svg = testing::ReadFile(st.plot_path);
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("APE w.r.t. translation part (m)"), std::string::npos);
  // Without stamps the aligned estimate is written as KITTI: one 12-number line per pose.
  const std::string aligned = testing::ReadFile(st.aligned_out_path);
  EXPECT_EQ(std::count(aligned.begin(), aligned.end(), '\n'), 4541);

  const std::string table = FormatEvaluationTable(st, o);
  EXPECT_NE(table.find("matched   : 4541 of 4541 possible pairs (by index: no timestamps)"),
            std::string::npos)
      << table;
  EXPECT_NE(table.find("alignment : SE(3) Umeyama on all pairs\n"), std::string::npos) << table;
}

TEST(Evaluation, RpeTenMetresOnKitti) {
  EvaluationSettings st;
  st.metric = EvaluationSettings::Metric::kRpe;
  st.ref_path = Data("KITTI_00_gt.txt");
  st.est_path = Data("KITTI_00_ORB.txt");
  st.alignment.mode = eval::AlignMode::kSe3;
  st.rpe.delta = 10;
  st.rpe.unit = eval::DeltaUnit::kMeters;
  const EvaluationOutcome o = RunEvaluation(st);
  EXPECT_EQ(o.title, "RPE w.r.t. translation part (m) for delta = 10 (m), consecutive pairs");
  EXPECT_EQ(o.series.stats.n, 353u);
  EXPECT_NEAR(o.series.stats.rmse, 0.226261, 1e-6);
  EXPECT_NEAR(o.series.stats.median, 0.138484, 1e-6);
  EXPECT_EQ(o.json["delta"], 10.0);
  EXPECT_EQ(o.json["delta_unit"], "m");
  EXPECT_EQ(o.json["all_pairs"], false);
}

TEST(Evaluation, ApeAssociatesTumStamps) {
  // fr1_xyz: the rgbdslam estimate against the ground truth at another rate (the figures of the
  // example in docs/FORMATS.md).
  EvaluationSettings st;
  st.ref_path = Data("freiburg1_xyz-groundtruth.txt");
  st.est_path = Data("freiburg1_xyz-rgbdslam.txt");
  st.alignment.mode = eval::AlignMode::kSe3;
  const EvaluationOutcome o = RunEvaluation(st);
  EXPECT_FALSE(o.synced.by_index);
  EXPECT_EQ(o.synced.ref.size(), 785u);
  EXPECT_EQ(o.synced.max_pairs, 788u);
  EXPECT_NEAR(o.series.stats.rmse, 0.013470, 1e-6);
}

TEST(Evaluation, InMemoryTrajectoriesGiveTheFileFigures) {
  // The Python module's path: trajectories already read; the paths only label the JSON.
  EvaluationSettings st;
  st.ref_path = Data("freiburg1_xyz-groundtruth.txt");
  st.est_path = Data("freiburg1_xyz-rgbdslam.txt");
  st.alignment.mode = eval::AlignMode::kSe3;
  const EvaluationOutcome from_files = RunEvaluation(st);
  EvaluationSettings unlabeled = st;
  unlabeled.ref_path.clear();
  unlabeled.est_path.clear();
  const EvaluationOutcome in_memory =
      RunEvaluation(unlabeled, io::ReadTrajectory(st.ref_path), io::ReadTrajectory(st.est_path));
  EXPECT_TRUE(in_memory.json["ref"].is_null());
  EXPECT_TRUE(in_memory.json["est"].is_null());
  nlohmann::json j = in_memory.json;
  j["ref"] = st.ref_path;
  j["est"] = st.est_path;
  EXPECT_EQ(j, from_files.json);
}

TEST(Evaluation, CheckNamesTheFlag) {
  EvaluationSettings st;
  st.ref_path = st.est_path = Data("KITTI_00_gt.txt");
  EXPECT_EQ(st.Check(), "");
  st.association.max_diff_s = -1;
  EXPECT_EQ(st.Check(), "--max-diff must be >= 0");
  st.association.max_diff_s = 0.01;
  st.plot_plane = "ab";
  EXPECT_EQ(st.Check().rfind("--plot-plane must be", 0), 0u) << st.Check();
  st.plot_plane = "xy";
  st.metric = EvaluationSettings::Metric::kRpe;
  st.rpe.delta = 0;
  EXPECT_EQ(st.Check().rfind("--delta", 0), 0u) << st.Check();
  EXPECT_ERROR(RunEvaluation(st), {}, "--delta must be a positive number, got 0");
}

TEST(Evaluation, MalformedLineNamesFileAndLineAndKeepsOutputs) {
  const std::filesystem::path dir = testing::MakeTempDir("app_evaluation_bad");
  const std::string bad = testing::WriteFile(dir / "short.txt",
                                             "1.0 0 0 0 0 0 0 1\n"
                                             "2.0 0 0\n");
  EvaluationSettings st;
  st.ref_path = Data("freiburg1_xyz-groundtruth.txt");
  st.est_path = bad;
  st.json_path = testing::WriteFile(dir / "keep.json", "keep me\n");
  try {
    RunEvaluation(st);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.context().file, bad);
    EXPECT_EQ(e.context().line, 2);
  }
  EXPECT_EQ(testing::ReadFile(st.json_path), "keep me\n");  // a failed run writes nothing
}

}  // namespace
}  // namespace optinav::app
