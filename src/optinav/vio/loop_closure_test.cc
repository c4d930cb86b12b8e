// Loop closure: option checks, corrections without loops, and a simulated flight around a
// square that returns to its start (stereo-only VIO): the loops found must agree with the ground
// truth and the corrected trajectory must beat the odometry.
#include "optinav/vio/internal/loop_closure.h"

#include <cstdio>

#include <gtest/gtest.h>

#include "optinav/eval/metrics.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/error.h"
#include "optinav/util/testing.h"
#include "optinav/vio/pipeline.h"

namespace optinav::vio {
namespace {

TEST(LoopClosure, ChecksOptions) {
  EXPECT_EQ(LoopClosureOptions().Check(), "");
  LoopClosureOptions o;
  o.min_inliers = 3;
  EXPECT_NE(o.Check().find("min_inliers"), std::string::npos);
  o = {};
  o.loop_sigma_m = 0;
  EXPECT_NE(o.Check().find("sigmas"), std::string::npos);
  o = {};
  o.loop_consistency_m = 0;
  EXPECT_NE(o.Check().find("loop_consistency_m"), std::string::npos);
  o = {};
  o.max_view_angle_deg = 200;
  EXPECT_ERROR(LoopCloser(camera::StereoRig{}, Rigid3d::Identity(), o), {.field = "loop_closure"},
               "loop_closure.max_view_angle_deg must be in (0, 180]");
}

TEST(LoopClosure, NoLoopNoCorrection) {
  camera::StereoRig rig;
  rig.left = rig.right = camera::PinholeCamera::FromHorizontalFov(160, 120, M_PI / 2);
  rig.right_from_left.translation = {-0.2, 0, 0};
  LoopCloser closer(rig, Rigid3d::Identity(), {});
  const cv::Mat black = cv::Mat::zeros(120, 160, CV_8U);  // no features: nothing to match
  for (int k = 0; k < 5; ++k) {
    StateEstimate s;
    s.t_ns = k * 1'000'000'000LL;
    s.world_from_body.translation = {0, 10.0 * k, 0};
    EXPECT_FALSE(closer.AddKeyframe(s, black, black));
  }
  closer.NewTrack(10'000'000'000LL);
  EXPECT_EQ(closer.keyframes(), 5u);
  EXPECT_TRUE(closer.loops().empty());
  EXPECT_TRUE(closer.CorrectionAt(3'500'000'000LL).translation.isZero());
  EXPECT_TRUE(closer.CorrectionAt(12'000'000'000LL).translation.isZero());
}

Rigid3d At(const Trajectory& t, int64_t t_ns) {
  const auto p = t.InterpolateAt(t_ns);
  if (!p) throw Error("no ground truth at the loop's time");
  return *p;
}

double MeanError(const Trajectory& gt, const Trajectory& est) {
  eval::SyncedPair synced = eval::Synchronize(gt, est);
  eval::AlignTrajectory(synced.ref, &synced.est,
                        {.mode = eval::AlignMode::kNone, .align_origin = true});
  return eval::ComputeStatistics(
             eval::ComputeApe(synced.ref, synced.est, eval::PoseRelation::kTranslation).errors)
      .mean;
}

TEST(LoopClosure, SquareFlightClosesItsLoop) {
  // 25 m square at 4 m altitude, 5 m/s, back over the start and on along the first side.
  const auto dir = testing::MakeTempDir("loop_square");
  testing::WriteFile(dir / "wp.txt", "0, 0, 4\n25, 0, 4\n25, 25, 4\n0, 25, 4\n0, 0, 4\n20, 0, 4\n");
  sim::SimulationOptions o;
  o.route = "drone:" + (dir / "wp.txt").string();
  o.speed_m_s = 5.0;
  o.seed = 4;
  o.scale = 0.5;
  o.out_dir = (dir / "seq").string();
  sim::RunSimulation(o);
  VioRunOptions options;
  options.vio.mode = VioMode::kStereo;
  const VioRunResult r = RunVioOnEuroc(o.out_dir, options);
  ASSERT_TRUE(r.loop_closure_ran);
  const Trajectory gt =
      io::ReadTrajectory(o.out_dir + "/mav0/state_groundtruth_estimate0/data.csv");
  const double before =
      MeanError(gt, EstimatesToTrajectory(r.odometry.empty() ? r.estimates : r.odometry));
  const double after = MeanError(gt, EstimatesToTrajectory(r.estimates));
  double worst_m = 0, worst_deg = 0;
  for (const LoopEdge& l : r.loops) {
    const Rigid3d truth = At(gt, l.t_old_ns).Inverse() * At(gt, l.t_new_ns);
    const Rigid3d diff = truth.Inverse() * l.old_body_from_new_body;
    worst_m = std::max(worst_m, diff.translation.norm());
    worst_deg = std::max(worst_deg, Eigen::AngleAxisd(diff.rotation).angle() * 180 / M_PI);
  }
  std::printf(
      "square flight, stereo-only, %zu poses: %zu loop(s); worst loop against the ground truth "
      "%.3f m (< 0.3), %.2f deg (< 2); mean error (first poses aligned) %.3f m odometry -> %.3f m "
      "corrected (< half); loop closure median %.1f ms per keyframe\n",
      r.estimates.size(), r.loops.size(), worst_m, worst_deg, before, after,
      r.timing.count("loop_closure") ? r.timing.at("loop_closure").median_s * 1e3 : 0.0);
  ASSERT_GE(r.loops.size(), 1u);
  EXPECT_LT(worst_m, 0.3);
  EXPECT_LT(worst_deg, 2.0);
  EXPECT_LT(after, 0.5 * before);
  ASSERT_EQ(r.odometry.size(), r.estimates.size());
}

}  // namespace
}  // namespace optinav::vio
