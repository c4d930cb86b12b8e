#include "optinav/vio/pipeline.h"

#include <cstdio>

#include <gtest/gtest.h>

#include "optinav/eval/metrics.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/util/testing.h"

namespace optinav::vio {
namespace {

std::string Micro() {
  return (optinav::testing::SharedDataDir() / "euroc" / "V1_01_micro").string();
}

Trajectory GroundTruth() {
  return io::ReadTrajectory((optinav::testing::SharedDataDir() / "euroc" / "V1_01_micro" / "mav0" /
                             "state_groundtruth_estimate0" / "data.csv")
                                .string());
}

TEST(Pipeline, EurocMicroInitialisesStaticallyAndDriftsLessThan2cm) {
  VioRunOptions options;
  const VioRunResult r = RunVioOnEuroc(Micro(), options);
  ASSERT_GT(r.estimates.size(), 80u);
  EXPECT_EQ(r.first_init_kind, "static");
  EXPECT_TRUE(r.lost.empty());
  const Trajectory est = EstimatesToTrajectory(r.estimates);
  const Trajectory gt = GroundTruth();
  // End-to-end drift: the relative motion first -> last frame against the ground truth's.
  const Rigid3d est_rel = est.pose(0).Inverse() * est.pose(est.size() - 1);
  const auto gt0 = gt.InterpolateAt(est.t_ns.front());
  const auto gt1 = gt.InterpolateAt(est.t_ns.back());
  ASSERT_TRUE(gt0 && gt1);
  const Rigid3d gt_rel = gt0->Inverse() * *gt1;
  const double drift = (est_rel.translation - gt_rel.translation).norm();
  // APE after SE(3) alignment over the clip.
  eval::SyncedPair synced = eval::Synchronize(gt, est);
  eval::AlignTrajectory(synced.ref, &synced.est, {.mode = eval::AlignMode::kSe3});
  std::vector<double> errors;
  for (size_t i = 0; i < synced.est.size(); ++i)
    errors.push_back((synced.est.positions[i] - synced.ref.positions[i]).norm());
  const eval::Statistics ape = eval::ComputeStatistics(errors);
  std::printf(
      "V1_01_micro: %zu frames, %s initialisation, ground-truth motion %.3f m, drift "
      "first->last %.4f m (< 0.02), APE RMSE (SE3) %.4f m (< 0.02), lost intervals %zu; "
      "median frame %.1f ms\n",
      r.estimates.size(), r.first_init_kind.c_str(), gt_rel.translation.norm(), drift, ape.rmse,
      r.lost.size(), r.timing.at("total").median_s * 1e3);
  EXPECT_LT(drift, 0.02);
  EXPECT_LT(ape.rmse, 0.02);
}

TEST(Pipeline, SequentialAndThreadedRunsAreIdentical) {
  VioRunOptions options;
  options.max_frames = 40;
  const VioRunResult a = RunVioOnEuroc(Micro(), options);
  const VioRunResult b = RunVioOnEuroc(Micro(), options);
  options.threaded = true;
  const VioRunResult c = RunVioOnEuroc(Micro(), options);
  ASSERT_EQ(a.estimates.size(), b.estimates.size());
  ASSERT_EQ(a.estimates.size(), c.estimates.size());
  for (size_t i = 0; i < a.estimates.size(); ++i) {
    EXPECT_EQ(a.estimates[i].state.world_from_body.translation,
              b.estimates[i].state.world_from_body.translation);
    EXPECT_EQ(a.estimates[i].state.world_from_body.translation,
              c.estimates[i].state.world_from_body.translation);
  }
}

TEST(Pipeline, StereoOnlyModeRuns) {
  VioRunOptions options;
  options.vio.mode = VioMode::kStereo;
  options.max_frames = 40;
  const VioRunResult r = RunVioOnEuroc(Micro(), options);
  ASSERT_GT(r.estimates.size(), 30u);
  const Trajectory est = EstimatesToTrajectory(r.estimates);
  const double moved = (est.pose(0).Inverse() * est.pose(est.size() - 1)).translation.norm();
  std::printf(
      "stereo-only on V1_01_micro (40 frames): end-to-end motion %.4f m (nearly still: "
      "< 0.05)\n",
      moved);
  EXPECT_LT(moved, 0.05);
}

}  // namespace
}  // namespace optinav::vio
