// The GNSS smoother on a synthetic run: a 1 km circle flown at 10 m/s whose VIO world drifts away
// from ENU (0.6 m and 0.3 deg over the run), 3 m GNSS at 5 Hz, and a live alignment that wanders
// the way a causal estimate does (correlated 0.4 m error).
#include "optinav/vio/gnss_smoother.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace optinav::vio {
namespace {

constexpr int64_t kFrameNs = 50'000'000;  // 20 Hz
constexpr int kFrames = 2000;             // 100 s

// The true enu_from_world at time s: a fixed tie plus the VIO drift.
WorldAlignment TrueAlignmentAt(double s) {
  WorldAlignment a;
  a.yaw_rad = 0.7 + 0.3 * M_PI / 180.0 * s / 100.0;
  a.translation = Eigen::Vector3d(50.0, -20.0, 2.0) + Eigen::Vector3d(0.4, -0.4, 0.2) * s / 100.0;
  return a;
}

Eigen::Vector3d TruePosition(double s) {
  const double r = 160.0, w = 10.0 / r;
  return {r * std::cos(w * s), r * std::sin(w * s), 20.0 + 2.0 * std::sin(0.3 * s)};
}

struct SyntheticRun {
  std::vector<FrameEstimate> estimates;
  std::vector<GnssSample> samples;
  std::vector<Eigen::Vector3d> truth;  // ENU, per frame
};

// lever: the antenna in the body frame (the body's axes are ENU's here); jump_m: the VIO world
// jumps by this (along ENU x) from frame 1000 on, as after a drift the fusion's test caught.
SyntheticRun MakeRun(int seed, double outlier_fraction = 0.0,
                     const Eigen::Vector3d& lever = Eigen::Vector3d::Zero(), double jump_m = 0) {
  SyntheticRun run;
  std::mt19937 rng(seed), outlier_rng(100 + seed);  // the outliers leave the noise draw alone
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Eigen::Vector3d live_error = Eigen::Vector3d::Zero();
  const double rho = std::exp(-0.05 / 5.0);  // 5 s correlation time
  for (int i = 0; i < kFrames; ++i) {
    const double s = i * 0.05;
    const Eigen::Vector3d p_enu = TruePosition(s);
    WorldAlignment truth = TrueAlignmentAt(s);
    if (i >= 1000) truth.translation.x() += jump_m;
    const Rigid3d world_from_enu = truth.EnuFromWorld().Inverse();
    FrameEstimate e;
    e.state.t_ns = 1'000'000'000 + i * kFrameNs;
    e.state.world_from_body = Rigid3d(world_from_enu.rotation, world_from_enu * p_enu);
    for (int k = 0; k < 3; ++k)
      live_error[k] = rho * live_error[k] + std::sqrt(1 - rho * rho) * 0.4 * n01(rng);
    WorldAlignment live = truth;
    live.translation += live_error;
    e.enu_from_world = live;
    run.estimates.push_back(e);
    run.truth.push_back(p_enu);
    if (i % 4 == 1) {  // 5 Hz, between frames
      GnssSample g;
      g.t_ns = e.state.t_ns + kFrameNs / 2;
      g.position_enu_m =
          TruePosition(s + 0.025) + lever + 3.0 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
      if (u(outlier_rng) < outlier_fraction)
        g.position_enu_m +=
            30.0 * Eigen::Vector3d(n01(outlier_rng), n01(outlier_rng), 0.0).normalized();
      g.sigma_m = 3.0;
      run.samples.push_back(g);
    }
  }
  return run;
}

double GlobalRmse(const SyntheticRun& run,
                  const std::vector<std::optional<WorldAlignment>>& alignments) {
  const Trajectory t = EstimatesToEnuTrajectory(run.estimates, alignments);
  EXPECT_EQ(t.size(), run.truth.size());
  double sse = 0;
  for (size_t i = 0; i < t.size(); ++i) sse += (t.positions[i] - run.truth[i]).squaredNorm();
  return std::sqrt(sse / t.size());
}

std::vector<std::optional<WorldAlignment>> Live(const SyntheticRun& run) {
  std::vector<std::optional<WorldAlignment>> live;
  for (const FrameEstimate& e : run.estimates) live.push_back(e.enu_from_world);
  return live;
}

TEST(GnssSmoother, BeatsTheLiveAlignmentOnEverySeed) {
  for (int seed = 1; seed <= 3; ++seed) {
    const SyntheticRun run = MakeRun(seed);
    GnssFusionOptions o;
    const GnssSmoothing s = SmoothGnssAlignment(run.estimates, {}, run.samples, {}, o);
    EXPECT_EQ(s.tracks_smoothed, 1);
    EXPECT_EQ(s.samples, run.samples.size());
    const double live = GlobalRmse(run, Live(run)), smoothed = GlobalRmse(run, s.enu_from_world);
    std::printf(
        "seed %d: global RMSE live %.3f m, smoothed %.3f m (threshold 0.45 m and 0.8 x live)\n",
        seed, live, smoothed);
    EXPECT_LT(smoothed, 0.45);
    EXPECT_LT(smoothed, 0.8 * live);
  }
}

TEST(GnssSmoother, RobustNormsHoldAgainstOutliers) {
  const SyntheticRun clean_run = MakeRun(4);
  const SyntheticRun run = MakeRun(4, 0.1);
  GnssFusionOptions o;
  const double clean = GlobalRmse(
      clean_run,
      SmoothGnssAlignment(clean_run.estimates, {}, clean_run.samples, {}, o).enu_from_world);
  o.norm = GnssNorm::kL2;
  const double l2 =
      GlobalRmse(run, SmoothGnssAlignment(run.estimates, {}, run.samples, {}, o).enu_from_world);
  o.norm = GnssNorm::kTukey;
  const double tukey =
      GlobalRmse(run, SmoothGnssAlignment(run.estimates, {}, run.samples, {}, o).enu_from_world);
  o.norm = GnssNorm::kHuber;
  const double huber =
      GlobalRmse(run, SmoothGnssAlignment(run.estimates, {}, run.samples, {}, o).enu_from_world);
  std::printf(
      "10 %% outliers of 30 m: global RMSE L2 %.3f, Huber %.3f, Tukey %.3f m; without outliers "
      "(Huber) %.3f m (Tukey within 10 %%, Huber within 50 %%)\n",
      l2, huber, tukey, clean);
  EXPECT_LT(tukey, 1.1 * clean);
  EXPECT_LT(huber, 1.5 * clean);
  EXPECT_LT(tukey, l2);
  EXPECT_LT(huber, l2);
}

TEST(GnssSmoother, TracksAreSmoothedApartAndShortOnesKeepTheLiveAlignment) {
  SyntheticRun run = MakeRun(5);
  // A new VIO track from frame 1000 on; the second track gets 2 samples only.
  const int64_t split_ns = run.estimates[1000].state.t_ns;
  std::vector<GnssSample> used;
  for (const GnssSample& g : run.samples)
    if (g.t_ns < split_ns) used.push_back(g);
  used.push_back(run.samples[300]), used.back().t_ns = run.estimates[1500].state.t_ns;
  used.push_back(run.samples[301]), used.back().t_ns = run.estimates[1504].state.t_ns;
  const GnssSmoothing s = SmoothGnssAlignment(run.estimates, {1000}, used, {}, GnssFusionOptions());
  EXPECT_EQ(s.tracks_smoothed, 1);
  EXPECT_NE(s.enu_from_world[999]->translation, run.estimates[999].enu_from_world->translation);
  for (size_t i = 1000; i < run.estimates.size(); ++i) {
    ASSERT_TRUE(s.enu_from_world[i]);
    EXPECT_EQ(s.enu_from_world[i]->translation, run.estimates[i].enu_from_world->translation);
  }
  EXPECT_NE(s.enu_from_world[500]->translation, run.estimates[500].enu_from_world->translation);

  GnssFusionOptions off;
  off.smooth = false;
  const GnssSmoothing live = SmoothGnssAlignment(run.estimates, {}, run.samples, {}, off);
  EXPECT_EQ(live.tracks_smoothed, 0);
  EXPECT_DOUBLE_EQ(GlobalRmse(run, live.enu_from_world), GlobalRmse(run, Live(run)));
}

TEST(GnssSmoother, LeverArmAndInflationsAreUsed) {
  const Eigen::Vector3d lever(1.0, 0.5, 0.8);
  const SyntheticRun run = MakeRun(7, 0.0, lever, 2.0);
  GnssFusionOptions o;
  // What the fusion's drift test would report at the jump (first sample after frame 1000).
  const AlignmentInflation at_jump{run.estimates[1001].state.t_ns, Eigen::Vector4d(2, 2, 2, 0.01)};
  const double without_lever = GlobalRmse(
      run, SmoothGnssAlignment(run.estimates, {}, run.samples, {at_jump}, o).enu_from_world);
  o.lever_arm_in_body = lever;
  const double without_inflation =
      GlobalRmse(run, SmoothGnssAlignment(run.estimates, {}, run.samples, {}, o).enu_from_world);
  const double both = GlobalRmse(
      run, SmoothGnssAlignment(run.estimates, {}, run.samples, {at_jump}, o).enu_from_world);
  const SyntheticRun steady = MakeRun(7, 0.0, lever, 0.0);
  const double no_jump = GlobalRmse(
      steady, SmoothGnssAlignment(steady.estimates, {}, steady.samples, {}, o).enu_from_world);
  std::printf(
      "2 m jump of the VIO at 50 s, lever arm (1, 0.5, 0.8) m: global RMSE %.3f m with both, %.3f "
      "without the inflation (limit 0.8 x), %.3f without the lever arm (limit 0.6 x); %.3f m for "
      "the "
      "same run without the jump (limit + 0.1 m)\n",
      both, without_inflation, without_lever, no_jump);
  EXPECT_LT(both, no_jump + 0.1);  // the inflation lets the smoother take the jump
  EXPECT_LT(both, 0.8 * without_inflation);
  EXPECT_LT(both, 0.6 * without_lever);
}

TEST(GnssSmoother, FramesBeforeTheFirstAlignmentUseTheFirstOne) {
  SyntheticRun run = MakeRun(6);
  for (int i = 0; i < 100; ++i) run.estimates[i].enu_from_world.reset();
  // Smoothed, they are re-estimated from the samples (the first alignment is frame 100's).
  const GnssSmoothing on =
      SmoothGnssAlignment(run.estimates, {}, run.samples, {}, GnssFusionOptions());
  ASSERT_TRUE(on.enu_from_world[0]);
  EXPECT_NE(on.enu_from_world[0]->translation, run.estimates[100].enu_from_world->translation);
  EXPECT_LT(
      (on.enu_from_world[0]->EnuFromWorld() * run.estimates[0].state.world_from_body.translation -
       run.truth[0])
          .norm(),
      1.0);
  GnssFusionOptions off;
  off.smooth = false;
  const GnssSmoothing s = SmoothGnssAlignment(run.estimates, {}, run.samples, {}, off);
  ASSERT_TRUE(s.enu_from_world[0]);
  EXPECT_EQ(s.enu_from_world[0]->translation, run.estimates[100].enu_from_world->translation);
  for (FrameEstimate& e : run.estimates) e.enu_from_world.reset();
  EXPECT_FALSE(SmoothGnssAlignment(run.estimates, {}, run.samples, {}, off).enu_from_world[0]);
}

}  // namespace
}  // namespace optinav::vio
