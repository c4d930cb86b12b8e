// GNSS fusion on feature-level synthetic stereo-inertial data (no rendering: fast and exact):
// the backend runs on synthetic observations, GNSS samples come from the true antenna path
// mapped into an ENU frame that differs from the VIO world by a yaw and a translation.
#include "optinav/vio/gnss_fusion.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <cstdlib>

#include <gtest/gtest.h>

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
  std::mt19937 rng(o.seed);
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
    if (u(rng) < o.outlier_fraction) {
      Eigen::Vector3d dir(normal(rng), normal(rng), normal(rng));
      s.position_enu_m +=
          dir.normalized() * (o.outlier_min_m + (o.outlier_max_m - o.outlier_min_m) * u(rng));
    }
    out.push_back(s);
  }
  return out;
}

struct FusedRun {
  std::vector<int64_t> t_ns;
  std::vector<Eigen::Vector3d> world, enu, truth_world, truth_enu;
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
    run.enu.push_back(fusion.alignment()
                          ? Eigen::Vector3d(fusion.alignment()->EnuFromWorld() *
                                            e.world_from_body.translation)
                          : Eigen::Vector3d::Constant(NAN));
  }
  run.stats = fusion.stats();
  if (fusion.alignment()) run.final_alignment = *fusion.alignment();
  run.rejected = fusion.rejected();
  return run;
}

// RMSE of the ENU estimate against the truth (no alignment) over the frames in [t0, t1) s.
double GlobalRmse(const FusedRun& r, double t0_s = 0, double t1_s = 1e9) {
  double sse = 0;
  int n = 0;
  for (size_t i = 0; i < r.t_ns.size(); ++i) {
    const double t = r.t_ns[i] * 1e-9;
    if (!r.aligned[i] || t < t0_s || t >= t1_s) continue;
    sse += (r.enu[i] - r.truth_enu[i]).squaredNorm();
    ++n;
  }
  return n ? std::sqrt(sse / n) : INFINITY;
}

double ErrorAt(const FusedRun& r, double t_s) {
  for (size_t i = 0; i < r.t_ns.size(); ++i)
    if (r.t_ns[i] * 1e-9 >= t_s) return (r.enu[i] - r.truth_enu[i]).norm();
  return INFINITY;
}

// World-frame drift of a VIO-only run (no GNSS), the initial state being the truth.
double WorldRmse(const FusedRun& r) {
  double sse = 0;
  for (size_t i = 0; i < r.t_ns.size(); ++i) sse += (r.world[i] - r.truth_world[i]).squaredNorm();
  return std::sqrt(sse / r.t_ns.size());
}

TEST(GnssFusion, RecoversTheEnuAlignmentAndBoundsTheError) {
  const SyntheticScene scene = OutdoorScene(80.0, 10.0);
  const double duration = 40.0;
  const auto frames = scene.Generate(duration, 10.0, 0.7, true, 7);
  GnssSimOptions sim;
  if (const char* e = std::getenv("GNSS_SIGMA")) sim.sigma_m = std::atof(e);
  const auto gnss = SimulateGnss(scene, duration, sim);
  GnssFusionOptions options;
  options.lever_arm_in_body = sim.lever_arm;
  if (const char* e = std::getenv("WALK_T")) options.alignment_walk_m_per_sqrt_m = std::atof(e);
  if (const char* e = std::getenv("WALK_Y")) options.alignment_walk_rad_per_sqrt_m = std::atof(e);
  const FusedRun fused = RunFusion(scene, frames, gnss, options);
  const FusedRun alone = RunFusion(scene, frames, {}, options);
  ASSERT_TRUE(fused.stats.aligned_at_ns.has_value());
  const WorldAlignment truth = TrueAlignment();
  const WorldAlignment fused_alignment = fused.final_alignment;
  const double rmse = GlobalRmse(fused, 10.0);
  std::printf(
      "outdoor %.0f m, GNSS sigma 3 m at 5 Hz: aligned at %.1f s; global RMSE after 10 s %.3f m "
      "(< 1.0); VIO alone world-frame RMSE %.3f m; %zu factors, %zu rejected\n",
      fused.distance_m, *fused.stats.aligned_at_ns * 1e-9, rmse, WorldRmse(alone),
      fused.stats.factors, fused.stats.rejected);
  for (double t = 2; t < duration; t += 4)
  {
    size_t i = 0;
    while (i + 1 < fused.t_ns.size() && fused.t_ns[i] * 1e-9 < t) ++i;
    const WorldAlignment& a = fused.alignments[i];
    std::printf("  t %.0f s: fused error %.2f m, world error fused %.2f alone %.2f, align yaw err %.3f deg t err %.2f\n", t, ErrorAt(fused, t),
                (fused.world[i] - fused.truth_world[i]).norm(), (alone.world[i] - alone.truth_world[i]).norm(),
                (a.yaw_rad - truth.yaw_rad) * 180 / M_PI, (a.translation - truth.translation).norm());
  }
  std::printf("final alignment: yaw error %.3f deg, translation error %.2f m\n",
              (fused_alignment.yaw_rad - truth.yaw_rad) * 180 / M_PI,
              (fused_alignment.translation - truth.translation).norm());
  EXPECT_LT(rmse, 1.0);
}

}  // namespace
}  // namespace optinav::vio
