// GNSS fusion on feature-level synthetic stereo-inertial data (no rendering: fast and exact):
// the backend runs on synthetic observations, GNSS samples come from the true antenna path
// mapped into an ENU frame that differs from the VIO world by a yaw and a translation.
#include "optinav/vio/gnss_fusion.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "optinav/vio/gnss_smoother.h"
#include "optinav/vio/test_scene.h"

namespace optinav::vio {
namespace {

// The ENU frame of the tests: 40 deg of yaw and an offset from the VIO world.
WorldAlignment TrueAlignment() {
  WorldAlignment a;
  a.yaw_rad = 40.0 * M_PI / 180.0;
  a.translation = {120.0, -45.0, 3.0};
  return a;
}

// An outdoor flight: a wide wavy circle at 10 m/s over ground texture and poles, seen by a
// forward-looking stereo rig with a 0.5 m baseline.
SyntheticScene OutdoorScene(double radius_m, double speed_m_s) {
  SyntheticScene scene;
  scene.trajectory.radius_m = radius_m;
  scene.trajectory.omega = speed_m_s / radius_m;
  scene.trajectory.height_m = 12.0;
  scene.trajectory.bob_m = 1.0;
  scene.trajectory.yaw_amp = 0.3;
  Eigen::Matrix3d body_from_cam;
  body_from_cam << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  // Pitched down by 15 deg.
  const Eigen::Matrix3d pitch = Eigen::AngleAxisd(0.26, Eigen::Vector3d::UnitY()).matrix();
  const Rigid3d body_from_cam0(Eigen::Quaterniond(pitch * body_from_cam), {0.1, 0.25, 0.0});
  const Rigid3d body_from_cam1(Eigen::Quaterniond(pitch * body_from_cam), {0.1, -0.25, 0.0});
  scene.rig.cam0_from_body = body_from_cam0.Inverse();
  scene.rig.cam1_from_body = body_from_cam1.Inverse();
  scene.landmarks.clear();
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double r0 = radius_m - 60, r1 = radius_m + 60;
  const int n = static_cast<int>(0.25 * M_PI * (r1 * r1 - r0 * r0));
  for (int i = 0; i < n; ++i) {
    const double r = std::sqrt(r0 * r0 + u(rng) * (r1 * r1 - r0 * r0));
    const double phi = 2 * M_PI * u(rng);
    const double z = i % 4 == 0 ? 8.0 * u(rng) : 0.0;  // a quarter on poles and walls
    scene.landmarks.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
  }
  return scene;
}

struct GnssSimOptions {
  double rate_hz = 5.0, sigma_m = 3.0;
  double outlier_fraction = 0.0, outlier_min_m = 20.0, outlier_max_m = 50.0;
  double outage_start_s = -1, outage_duration_s = 0;
  Eigen::Vector3d lever_arm{0.0, 0.0, 0.3};
  unsigned seed = 1;
};

std::vector<GnssSample> SimulateGnss(const SyntheticScene& scene, double duration_s,
                                     const GnssSimOptions& o) {
  std::mt19937 rng(o.seed),
      outlier_rng(o.seed + 100);  // same inlier noise with or without outliers
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Rigid3d enu_from_world = TrueAlignment().EnuFromWorld();
  std::vector<GnssSample> out;
  // Offset from the frame times on purpose (samples fall between frames).
  for (double t = 0.037; t <= duration_s; t += 1.0 / o.rate_hz) {
    if (t >= o.outage_start_s && t < o.outage_start_s + o.outage_duration_s) continue;
    const Rigid3d pose = scene.trajectory.Pose(t);
    GnssSample s;
    s.t_ns = static_cast<int64_t>(t * 1e9);
    s.sigma_m = o.sigma_m;
    s.position_enu_m = enu_from_world * (pose.translation + pose.rotation * o.lever_arm) +
                       o.sigma_m * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    if (u(outlier_rng) < o.outlier_fraction) {
      Eigen::Vector3d dir(normal(outlier_rng), normal(outlier_rng), normal(outlier_rng));
      s.position_enu_m += dir.normalized() *
                          (o.outlier_min_m + (o.outlier_max_m - o.outlier_min_m) * u(outlier_rng));
      s.sigma_m = -s.sigma_m;  // marks the outlier for the test (restored below)
    }
    out.push_back(s);
  }
  return out;
}

// Splits the outlier marks off (negative sigma): returns how many outliers there are.
size_t TakeOutlierMarks(std::vector<GnssSample>* samples, std::vector<int64_t>* outlier_stamps) {
  for (GnssSample& s : *samples)
    if (s.sigma_m < 0) {
      s.sigma_m = -s.sigma_m;
      outlier_stamps->push_back(s.t_ns);
    }
  return outlier_stamps->size();
}

struct FusedRun {
  std::vector<int64_t> t_ns;
  std::vector<Eigen::Vector3d> world, enu, truth_world, truth_enu;
  std::vector<Eigen::Vector3d> enu_smoothed;  // SmoothGnssAlignment of the run
  int tracks_smoothed = 0;
  size_t samples_used = 0, samples_smoothed = 0;
  std::vector<bool> aligned;
  std::vector<WorldAlignment> alignments;
  GnssFusionStats stats;
  WorldAlignment final_alignment;
  std::vector<RejectedGnss> rejected;
  double distance_m = 0;
};

// The backend on the synthetic frames from the true initial state, with GNSS when `gnss` has
// samples; every `keyframe_every`-th frame is a keyframe.
FusedRun RunFusion(const SyntheticScene& scene, const std::vector<SyntheticFrame>& frames,
                   const std::vector<GnssSample>& gnss, const GnssFusionOptions& gnss_options,
                   int keyframe_every = 3) {
  BackendOptions options;
  options.imu_noise = scene.noise;
  options.window_keyframes = 6;
  SlidingWindowBackend backend(options, scene.rig);
  GnssFusion fusion(gnss_options);
  StateEstimate init;
  init.t_ns = frames[0].t_ns;
  init.world_from_body = scene.trajectory.Pose(0.0);
  init.velocity = scene.trajectory.Velocity(0.0);
  backend.Initialize(init, frames[0].observations);
  size_t next_gnss = 0;
  auto feed_gnss = [&](int64_t up_to) {
    while (next_gnss < gnss.size() && gnss[next_gnss].t_ns <= up_to)
      fusion.AddSample(gnss[next_gnss++]);
  };
  feed_gnss(frames[0].t_ns);
  fusion.OnFrame(backend.Newest(), &backend);
  std::vector<TimedImuSample> imu(frames[0].imu.begin(), frames[0].imu.end());
  FusedRun run;
  std::vector<FrameEstimate> estimates;
  const Rigid3d enu_from_world = TrueAlignment().EnuFromWorld();
  Eigen::Vector3d last = scene.trajectory.Position(0.0);
  for (size_t i = 1; i < frames.size(); ++i) {
    imu.insert(imu.end(), frames[i].imu.begin(), frames[i].imu.end());
    if (imu.size() > 400) imu.erase(imu.begin(), imu.end() - 200);
    ImuPreintegration pre(backend.Newest().bias, scene.noise);
    for (const ImuMeasurement& m : ImuMeasurementsBetween(imu, frames[i - 1].t_ns, frames[i].t_ns))
      pre.Integrate(m.gyro, m.accel, m.dt_s);
    const bool keyframe = i % keyframe_every == 0;
    const StateEstimate e = backend.AddFrame(frames[i].t_ns, pre, frames[i].observations, keyframe);
    feed_gnss(frames[i].t_ns);
    fusion.OnFrame(e, &backend);
    const double t = frames[i].t_ns * 1e-9;
    const Eigen::Vector3d truth = scene.trajectory.Position(t);
    run.distance_m += (truth - last).norm();
    last = truth;
    run.t_ns.push_back(frames[i].t_ns);
    run.world.push_back(e.world_from_body.translation);
    run.truth_world.push_back(truth);
    run.truth_enu.push_back(enu_from_world * truth);
    run.aligned.push_back(fusion.alignment().has_value());
    run.alignments.push_back(fusion.alignment().value_or(WorldAlignment{}));
    run.enu.push_back(fusion.alignment() ? Eigen::Vector3d(fusion.alignment()->EnuFromWorld() *
                                                           e.world_from_body.translation)
                                         : Eigen::Vector3d::Constant(NAN));
    estimates.push_back({e, keyframe, fusion.alignment()});
  }
  const GnssSmoothing smoothed =
      SmoothGnssAlignment(estimates, {}, fusion.used(), fusion.inflations(), gnss_options);
  run.tracks_smoothed = smoothed.tracks_smoothed;
  run.samples_used = fusion.used().size();
  run.samples_smoothed = smoothed.samples;
  for (size_t i = 0; i < estimates.size(); ++i)
    run.enu_smoothed.push_back(
        smoothed.enu_from_world[i]
            ? Eigen::Vector3d(smoothed.enu_from_world[i]->EnuFromWorld() * run.world[i])
            : Eigen::Vector3d::Constant(NAN));
  run.stats = fusion.stats();
  if (fusion.alignment()) run.final_alignment = *fusion.alignment();
  run.rejected = fusion.rejected();
  return run;
}

// RMSE of the ENU estimate (live, or smoothed) against the truth (no alignment) over the frames
// in [t0, t1) s.
double GlobalRmse(const FusedRun& r, double t0_s = 0, double t1_s = 1e9, bool smoothed = false) {
  double sse = 0;
  int n = 0;
  for (size_t i = 0; i < r.t_ns.size(); ++i) {
    const double t = r.t_ns[i] * 1e-9;
    if (!r.aligned[i] || t < t0_s || t >= t1_s) continue;
    sse += ((smoothed ? r.enu_smoothed[i] : r.enu[i]) - r.truth_enu[i]).squaredNorm();
    ++n;
  }
  return n ? std::sqrt(sse / n) : INFINITY;
}

double ErrorAt(const FusedRun& r, double t_s, bool smoothed = false) {
  for (size_t i = 0; i < r.t_ns.size(); ++i)
    if (r.t_ns[i] * 1e-9 >= t_s)
      return ((smoothed ? r.enu_smoothed[i] : r.enu[i]) - r.truth_enu[i]).norm();
  return INFINITY;
}

// World-frame drift of a VIO-only run (no GNSS), the initial state being the truth.
double WorldRmse(const FusedRun& r) {
  double sse = 0;
  for (size_t i = 0; i < r.t_ns.size(); ++i) sse += (r.world[i] - r.truth_world[i]).squaredNorm();
  return std::sqrt(sse / r.t_ns.size());
}

// One outdoor scene, its frames and the VIO-alone run, shared by the tests (built once).
struct Outdoor {
  SyntheticScene scene = OutdoorScene(80.0, 10.0);
  double duration = 40.0;
  std::vector<SyntheticFrame> frames = scene.Generate(duration, 10.0, 0.7, true, 7);
  FusedRun alone = RunFusion(scene, frames, {}, GnssFusionOptions());
};
const Outdoor& TheOutdoor() {
  static const Outdoor o;
  return o;
}

GnssFusionOptions OptionsFor(const GnssSimOptions& sim, GnssNorm norm = GnssNorm::kHuber) {
  GnssFusionOptions o;
  o.lever_arm_in_body = sim.lever_arm;
  o.norm = norm;
  return o;
}

TEST(GnssFusion, RecoversTheEnuAlignmentAndBoundsTheError) {
  const Outdoor& d = TheOutdoor();
  GnssSimOptions sim;
  const FusedRun fused =
      RunFusion(d.scene, d.frames, SimulateGnss(d.scene, d.duration, sim), OptionsFor(sim));
  ASSERT_TRUE(fused.stats.aligned_at_ns.has_value());
  const double rmse = GlobalRmse(fused, 10.0);
  std::printf(
      "outdoor %.0f m at 10 m/s, GNSS sigma 3 m at 5 Hz: alignment at %.1f s; global RMSE from "
      "10 s %.3f m (< 1.0 = a third of sigma); VIO alone drifts to %.2f m RMSE in its world; "
      "%zu factors, %zu rejected (< 5)\n",
      d.alone.distance_m, *fused.stats.aligned_at_ns * 1e-9, rmse, WorldRmse(d.alone),
      fused.stats.factors, fused.stats.rejected);
  EXPECT_LT(rmse, 1.0);
  EXPECT_LT(fused.stats.rejected, 5u);  // 99.9 % gate: about 0.1 % of inliers
  // The output smoothed over the run (every accepted sample, earlier and later). This VIO drifts
  // 1.4 m in 400 m, far beyond the smoother's random walk (0.003 m/sqrt(m)): the smoother cannot
  // follow that drift better than the live estimate does, but it must not make it worse.
  const double smoothed = GlobalRmse(fused, 10.0, 1e9, true);
  std::printf("smoothed over the run: global RMSE from 10 s %.3f m (< 1.1 x the live %.3f m)\n",
              smoothed, rmse);
  EXPECT_LT(smoothed, 1.1 * rmse);
  EXPECT_EQ(fused.tracks_smoothed, 1);
  // Every accepted sample is smoothed but the one before the first recorded frame (t = 0.037 s);
  // accepted = the factors and the older samples of the initialisation (its prior).
  EXPECT_EQ(fused.samples_smoothed + 1, fused.samples_used);
  EXPECT_GT(fused.samples_used, fused.stats.factors);
  // The yaw of the alignment is the truth's up to the VIO's own yaw drift (< 1 deg here).
  const double yaw_error =
      std::remainder(fused.final_alignment.yaw_rad - TrueAlignment().yaw_rad, 2 * M_PI);
  EXPECT_LT(std::abs(yaw_error) * 180 / M_PI, 1.0);
}

TEST(GnssFusion, PreciseGnssGivesPreciseTrajectory) {
  // Nothing systematic: with 5 cm GNSS the fused trajectory follows it to centimetres (lever arm,
  // timing between frames and the alignment are right).
  const Outdoor& d = TheOutdoor();
  GnssSimOptions sim;
  sim.sigma_m = 0.05;
  const FusedRun fused =
      RunFusion(d.scene, d.frames, SimulateGnss(d.scene, d.duration, sim), OptionsFor(sim));
  const double rmse = GlobalRmse(fused, 2.0);
  std::printf("GNSS sigma 5 cm: global RMSE %.3f m (< 0.075), aligned at %.2f s\n", rmse,
              fused.stats.aligned_at_ns.value_or(-1) * 1e-9);
  EXPECT_LT(rmse, 0.075);
}

TEST(GnssFusion, OutliersAreGatedAndRobustNormsHold) {
  // 10 % outliers of 20-50 m: the result must be that of the same stream without them.
  const Outdoor& d = TheOutdoor();
  GnssSimOptions sim;
  sim.outlier_fraction = 0.10;
  auto gnss = SimulateGnss(d.scene, d.duration, sim);
  std::vector<int64_t> outliers;
  const size_t num_outliers = TakeOutlierMarks(&gnss, &outliers);
  std::vector<GnssSample> without;
  for (const GnssSample& s : gnss)
    if (!std::count(outliers.begin(), outliers.end(), s.t_ns)) without.push_back(s);
  for (GnssNorm norm : {GnssNorm::kL2, GnssNorm::kHuber, GnssNorm::kTukey}) {
    const double clean_rmse =
        GlobalRmse(RunFusion(d.scene, d.frames, without, OptionsFor(sim, norm)), 10.0);
    const FusedRun fused = RunFusion(d.scene, d.frames, gnss, OptionsFor(sim, norm));
    const double rmse = GlobalRmse(fused, 10.0);
    size_t caught = 0;
    for (const RejectedGnss& r : fused.rejected)
      caught += std::count(outliers.begin(), outliers.end(), r.t_ns) ? 1 : 0;
    std::printf(
        "10 %% outliers of 20-50 m, %s: global RMSE %.3f m vs %.3f m with the outliers removed "
        "(limit x1.2, threshold %.3f m); %zu of %zu outliers rejected (>= 90 %%), %zu inliers "
        "rejected\n",
        GnssNormName(norm).c_str(), rmse, clean_rmse, 1.2 * clean_rmse, caught, num_outliers,
        fused.rejected.size() - caught);
    EXPECT_LT(rmse, 1.2 * clean_rmse) << GnssNormName(norm);
    EXPECT_GE(caught, num_outliers * 9 / 10);
  }
}

TEST(GnssFusion, OutageFallsBackToVioAndReconverges) {
  const Outdoor& d = TheOutdoor();
  GnssSimOptions sim;
  sim.outage_start_s = 15.0;
  sim.outage_duration_s = 15.0;
  // The outage comes at 15 s of this 40 s flight: align on the 1 deg yaw rule (the default 0.3 deg
  // waits until about 25 s with 3 m GNSS; when to align is WaitsForMotionBeforeAligning's subject).
  GnssFusionOptions options = OptionsFor(sim);
  options.init_max_yaw_sigma_rad = 0.0175;
  const FusedRun fused =
      RunFusion(d.scene, d.frames, SimulateGnss(d.scene, d.duration, sim), options);
  const double t0 = sim.outage_start_s, t1 = t0 + sim.outage_duration_s;
  const double growth = ErrorAt(fused, t1) - ErrorAt(fused, t0);
  // VIO alone over the same interval, started from the truth at t0.
  auto world_at = [&](const FusedRun& r, double t, bool truth) {
    for (size_t i = 0; i < r.t_ns.size(); ++i)
      if (r.t_ns[i] * 1e-9 >= t) return truth ? r.truth_world[i] : r.world[i];
    return Eigen::Vector3d(NAN, NAN, NAN);
  };
  // VIO alone (started from the truth, in the true frame): its global error over the interval.
  const double alone0 = (world_at(d.alone, t0, false) - world_at(d.alone, t0, true)).norm();
  const double alone1 = (world_at(d.alone, t1, false) - world_at(d.alone, t1, true)).norm();
  const double after = ErrorAt(fused, t1 + 10.0);
  std::printf(
      "%.0f s outage: fused error %.2f -> %.2f m (growth %.2f m); VIO alone %.2f -> %.2f m "
      "(growth %.2f m); 10 s after GNSS returns %.2f m (< 1.5)\n",
      sim.outage_duration_s, ErrorAt(fused, t0), ErrorAt(fused, t1), growth, alone0, alone1,
      alone1 - alone0, after);
  EXPECT_LT(growth, alone1 - alone0);
  EXPECT_LT(after, 1.5);
  // Smoothed, the outage is bridged from both sides.
  const double smoothed_growth = ErrorAt(fused, t1, true) - ErrorAt(fused, t0, true);
  const double smoothed_max = [&] {
    double m = 0;
    for (size_t i = 0; i < fused.t_ns.size(); ++i)
      if (fused.t_ns[i] * 1e-9 >= t0 && fused.t_ns[i] * 1e-9 < t1)
        m = std::max(m, (fused.enu_smoothed[i] - fused.truth_enu[i]).norm());
    return m;
  }();
  std::printf(
      "smoothed: growth over the outage %.2f m (< VIO alone's %.2f m), max error in it %.2f m (< "
      "the live estimate's %.2f m at the outage's end), at its end %.2f m (< 0.8 x live)\n",
      smoothed_growth, alone1 - alone0, smoothed_max, ErrorAt(fused, t1), ErrorAt(fused, t1, true));
  EXPECT_LT(smoothed_growth, alone1 - alone0);
  EXPECT_LT(smoothed_max, ErrorAt(fused, t1));
  EXPECT_LT(ErrorAt(fused, t1, true), 0.8 * ErrorAt(fused, t1));
}

TEST(GnssFusion, WaitsForMotionBeforeAligning) {
  // A room-sized flight (2 m circle) with 3 m GNSS: the yaw to ENU stays unknown, so the fusion
  // never aligns and the estimate is exactly the VIO's; with 5 cm GNSS it aligns at once.
  const SyntheticScene scene;
  const auto frames = scene.Generate(8.0, 10.0, 0.7, true, 3);
  GnssSimOptions noisy;
  noisy.lever_arm.setZero();
  const FusedRun a = RunFusion(scene, frames, SimulateGnss(scene, 8.0, noisy), OptionsFor(noisy));
  const FusedRun alone = RunFusion(scene, frames, {}, OptionsFor(noisy));
  EXPECT_FALSE(a.stats.aligned_at_ns.has_value());
  EXPECT_EQ(a.stats.factors, 0u);
  double diff = 0;
  for (size_t i = 0; i < a.world.size(); ++i)
    diff = std::max(diff, (a.world[i] - alone.world[i]).norm());
  EXPECT_EQ(diff, 0.0);
  GnssSimOptions precise = noisy;
  precise.sigma_m = 0.05;
  GnssFusionOptions room = OptionsFor(precise);
  room.init_min_distance_m = 2.0;
  const FusedRun b = RunFusion(scene, frames, SimulateGnss(scene, 8.0, precise), room);
  ASSERT_TRUE(b.stats.aligned_at_ns.has_value());
  std::printf(
      "room, 3 m GNSS: not aligned (%zu samples held); 5 cm GNSS: aligned at %.2f s, "
      "global RMSE %.3f m (< 0.05)\n",
      a.stats.received, *b.stats.aligned_at_ns * 1e-9, GlobalRmse(b));
  EXPECT_LT(GlobalRmse(b), 0.075);
}

TEST(GnssFusion, BadSamplesAreRejectedWithAReason) {
  GnssFusion fusion(GnssFusionOptions{});
  fusion.AddSample({100, {1, 2, 3}, 1.0});
  fusion.AddSample({100, {1, 2, 3}, 1.0});    // repeated stamp
  fusion.AddSample({50, {1, 2, 3}, 1.0});     // earlier
  fusion.AddSample({200, {NAN, 2, 3}, 1.0});  // non-finite
  fusion.AddSample({300, {1, 2, 3}, 0.0});    // sigma 0
  ASSERT_EQ(fusion.rejected().size(), 4u);
  EXPECT_NE(fusion.rejected()[0].reason.find("timestamp"), std::string::npos);
  EXPECT_NE(fusion.rejected()[2].reason.find("non-finite"), std::string::npos);
  // A sample before the first frame: no pose to tie it to.
  BackendOptions bo;
  SyntheticScene scene;
  bo.imu_noise = scene.noise;
  SlidingWindowBackend backend(bo, scene.rig);
  StateEstimate s;
  s.t_ns = 1000;
  backend.Initialize(s, {});
  fusion.OnFrame(s, &backend);
  ASSERT_EQ(fusion.rejected().size(), 5u);
  EXPECT_NE(fusion.rejected()[4].reason.find("before the first frame"), std::string::npos);
  GnssFusionOptions bad;
  bad.init_min_samples = 1;
  EXPECT_FALSE(bad.Check().empty());
  for (double scale : {0.0, -1.0, double(NAN), double(INFINITY)}) {
    GnssFusionOptions o;
    o.factor_sigma_scale = scale;
    EXPECT_NE(o.Check().find("factor_sigma_scale"), std::string::npos) << scale;
  }
  EXPECT_EQ(GnssFusionOptions().Check(), "");
}

}  // namespace
}  // namespace optinav::vio
