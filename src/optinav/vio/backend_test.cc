#include "optinav/vio/backend.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "optinav/vio/test_scene.h"

namespace optinav::vio {
namespace {

struct RunResult {
  double position_rmse_m = 0, max_rotation_error_rad = 0, distance_m = 0;
  ImuBias final_bias;
};

// Runs the backend on synthetic frames from the true initial state (biases unknown: zero).
RunResult RunBackend(const SyntheticScene& scene, const std::vector<SyntheticFrame>& frames,
                     BackendOptions options, int keyframe_every,
                     std::vector<std::unique_ptr<TimedFactor>> timed = {}) {
  options.imu_noise = scene.noise;
  SlidingWindowBackend backend(options, scene.rig);
  StateEstimate init;
  init.t_ns = frames[0].t_ns;
  init.world_from_body = scene.trajectory.Pose(0.0);
  init.velocity = options.use_imu ? scene.trajectory.Velocity(0.0) : Eigen::Vector3d::Zero();
  backend.Initialize(init, frames[0].observations);
  for (auto& f : timed) backend.AddTimedFactor(std::move(f));
  std::vector<TimedImuSample> imu(frames[0].imu.begin(), frames[0].imu.end());
  RunResult result;
  double sse = 0;
  Eigen::Vector3d last_position = scene.trajectory.Position(0.0);
  for (size_t i = 1; i < frames.size(); ++i) {
    imu.insert(imu.end(), frames[i].imu.begin(), frames[i].imu.end());
    ImuPreintegration pre(ImuBias{}, scene.noise);
    for (const ImuMeasurement& m : ImuMeasurementsBetween(imu, frames[i - 1].t_ns, frames[i].t_ns))
      pre.Integrate(m.gyro, m.accel, m.dt_s);
    const bool keyframe = i % keyframe_every == 0;
    const StateEstimate e = backend.AddFrame(frames[i].t_ns, pre, frames[i].observations, keyframe);
    const double t = frames[i].t_ns * 1e-9;
    const Rigid3d truth = scene.trajectory.Pose(t);
    sse += (e.world_from_body.translation - truth.translation).squaredNorm();
    result.max_rotation_error_rad =
        std::max(result.max_rotation_error_rad,
                 RotationAngle(e.world_from_body.rotation.conjugate() * truth.rotation));
    result.distance_m += (truth.translation - last_position).norm();
    last_position = truth.translation;
    result.final_bias = e.bias;
  }
  result.position_rmse_m = std::sqrt(sse / (frames.size() - 1));
  return result;
}

TEST(Backend, GroundVehicleSigmasAreChecked) {
  BackendOptions o;
  EXPECT_EQ(o.Check(), "");
  o.ground_vehicle_vertical_sigma_m_s = -0.05;
  EXPECT_NE(o.Check().find("ground_vehicle_vertical_sigma_m_s"), std::string::npos);
  o = BackendOptions();
  o.ground_vehicle_boresight_walk_rad_per_sqrt_s = std::nan("");
  EXPECT_NE(o.Check().find("ground_vehicle_boresight_walk_rad_per_sqrt_s"), std::string::npos);
  o = BackendOptions();
  o.marginalize_tracked_max_depth_m = std::nan("");
  EXPECT_NE(o.Check().find("marginalize_tracked_max_depth_m"), std::string::npos);
  o = BackendOptions();
  o.stereo_only_pnp_gate_pixels = -1;
  EXPECT_NE(o.Check().find("stereo_only_pnp_gate_pixels"), std::string::npos);
  o = BackendOptions();
  o.stereo_only_pnp_gate_median_factor = std::nan("");
  EXPECT_NE(o.Check().find("stereo_only_pnp_gate_median_factor"), std::string::npos);
}

TEST(Backend, StereoInertialOnSyntheticRoom) {
  const SyntheticScene scene;
  const auto frames = scene.Generate(10.0, 20.0, 0.7, true, 3);
  BackendOptions options;
  const RunResult r = RunBackend(scene, frames, options, 4);
  const double bg_err = (r.final_bias.gyro - scene.true_bias.gyro).norm();
  std::printf(
      "stereo-inertial, %.1f m in 10 s: position RMSE %.4f m (< 0.03), max rotation "
      "error %.3f deg (< 1), gyro bias error %.5f rad/s (< 0.001)\n",
      r.distance_m, r.position_rmse_m, r.max_rotation_error_rad * 180 / M_PI, bg_err);
  EXPECT_LT(r.position_rmse_m, 0.03);
  EXPECT_LT(r.max_rotation_error_rad * 180 / M_PI, 1.0);
  EXPECT_LT(bg_err, 1e-3);
}

TEST(Backend, StereoOnlyOnSyntheticRoom) {
  const SyntheticScene scene;
  const auto frames = scene.Generate(10.0, 20.0, 0.7, true, 4);
  BackendOptions options;
  options.use_imu = false;
  const RunResult r = RunBackend(scene, frames, options, 4);
  std::printf(
      "stereo-only, %.1f m in 10 s: position RMSE %.4f m (< 0.06), max rotation error "
      "%.3f deg (< 1.2)\n",
      r.distance_m, r.position_rmse_m, r.max_rotation_error_rad * 180 / M_PI);
  EXPECT_LT(r.position_rmse_m, 0.06);
  EXPECT_LT(r.max_rotation_error_rad * 180 / M_PI, 1.0);
}

// Long tracks through a short window: a landmark the newest frame still tracks loses the oldest
// keyframe's observation of it at every marginalisation, unless it is split into the prior
// (marginalize_tracked_landmarks) or kept against that keyframe's fixed pose
// (anchored_observations_per_landmark: the landmark ties the window to the keyframe that first
// saw it; with the left camera's observation, the default, more of them, or both cameras').
// Kept, that information holds the rotation over the tracks' whole life, not only the window's;
// the drift must fall.
TEST(Backend, KeptTrackedLandmarkObservationsHoldTheRotation) {
  const SyntheticScene scene;
  const auto frames = scene.Generate(20.0, 20.0, 0.7, true, 5);
  BackendOptions options;
  options.use_imu = false;
  options.window_keyframes = 4;
  const RunResult dropped = RunBackend(scene, frames, options, 2);
  BackendOptions split_options = options;
  split_options.marginalize_tracked_landmarks = true;
  const RunResult split = RunBackend(scene, frames, split_options, 2);
  options.anchored_observations_per_landmark = 1;
  const RunResult one = RunBackend(scene, frames, options, 2);
  options.anchored_observations_per_landmark = 3;
  const RunResult three = RunBackend(scene, frames, options, 2);
  options.anchored_observations_per_landmark = 1;
  options.anchored_stereo = true;
  const RunResult stereo = RunBackend(scene, frames, options, 2);
  const double deg = 180 / M_PI;
  std::printf(
      "stereo-only, window 4, %.1f m in 20 s: position RMSE %.4f m dropped, %.4f m split, "
      "anchored %.4f m (one, left camera), %.4f m (three), %.4f m (one, both cameras); max "
      "rotation error %.3f / %.3f / %.3f / %.3f / %.3f deg (kept: < 0.2 m, < 2 deg, below the "
      "dropped ones)\n",
      split.distance_m, dropped.position_rmse_m, split.position_rmse_m, one.position_rmse_m,
      three.position_rmse_m, stereo.position_rmse_m, dropped.max_rotation_error_rad * deg,
      split.max_rotation_error_rad * deg, one.max_rotation_error_rad * deg,
      three.max_rotation_error_rad * deg, stereo.max_rotation_error_rad * deg);
  for (const RunResult* r : {&split, &one, &three, &stereo}) {
    EXPECT_LT(r->position_rmse_m, 0.2);
    EXPECT_LT(r->max_rotation_error_rad * deg, 2.0);
    EXPECT_LT(r->position_rmse_m, dropped.position_rmse_m);
    EXPECT_LT(r->max_rotation_error_rad, dropped.max_rotation_error_rad);
  }
}

// Stereo-only, window 4: a car driving circles in the room (level, heading along its velocity,
// its body x axis `yaw_offset` left of it), free and with the ground-vehicle constraint between
// consecutive states at 0.05 m/s (the boresight estimated with `boresight_sigma_rad` > 0).
struct CarRuns {
  RunResult free, car;
};
CarRuns RunStereoOnlyCar(double yaw_offset, double boresight_sigma_rad,
                         const RunResult* free = nullptr) {
  SyntheticScene scene;
  scene.trajectory = AnalyticTrajectory::Car(yaw_offset);
  const auto frames = scene.Generate(20.0, 20.0, 0.7, true, 5);
  BackendOptions options;
  options.use_imu = false;
  options.window_keyframes = 4;
  CarRuns r;
  r.free = free ? *free : RunBackend(scene, frames, options, 2);
  options.ground_vehicle_lateral_sigma_m_s = 0.05;
  options.ground_vehicle_vertical_sigma_m_s = 0.05;
  options.ground_vehicle_boresight_sigma_rad = boresight_sigma_rad;
  r.car = RunBackend(scene, frames, options, 2);
  return r;
}

// The constraint (the chord along the body x axis at the arc's middle heading) leaves the vision
// no sideways or vertical translation to trade for a rotation; the drift must fall.
TEST(Backend, GroundVehiclePairFactorHoldsAStereoOnlyCar) {
  const CarRuns r = RunStereoOnlyCar(0.0, 0.0);
  const double deg = 180 / M_PI;
  std::printf(
      "stereo-only car, window 4, %.1f m in 20 s: position RMSE %.4f m free, %.4f m with the "
      "ground-vehicle pair factor; max rotation error %.3f / %.3f deg (with it: < 0.7x both)\n",
      r.car.distance_m, r.free.position_rmse_m, r.car.position_rmse_m,
      r.free.max_rotation_error_rad * deg, r.car.max_rotation_error_rad * deg);
  EXPECT_LT(r.car.position_rmse_m, 0.7 * r.free.position_rmse_m);
  EXPECT_LT(r.car.max_rotation_error_rad, 0.7 * r.free.max_rotation_error_rad);
}

// The same car with its body x axis 1 deg left of the direction it drives (a camera-to-vehicle
// boresight error, or a bias of the odometry's translation direction): held to body x, the
// constraint turns that degree into a rotation of every step; with the boresight estimated
// (ground_vehicle_boresight_sigma_rad) it is one constant.
TEST(Backend, GroundVehiclePairFactorEstimatesTheBoresight) {
  const double offset = M_PI / 180;
  const CarRuns held = RunStereoOnlyCar(offset, 0.0);
  const CarRuns estimated = RunStereoOnlyCar(offset, 0.05, &held.free);
  const RunResult& free = held.free;
  const double deg = 180 / M_PI;
  std::printf(
      "stereo-only car, boresight 1 deg off: position RMSE %.4f m free, %.4f m with the pair "
      "factor on body x, %.4f m with the boresight estimated; max rotation error %.3f / %.3f / "
      "%.3f deg (estimated: < 0.7x free on both, rotation < 0.5x held)\n",
      free.position_rmse_m, held.car.position_rmse_m, estimated.car.position_rmse_m,
      free.max_rotation_error_rad * deg, held.car.max_rotation_error_rad * deg,
      estimated.car.max_rotation_error_rad * deg);
  EXPECT_LT(estimated.car.position_rmse_m, 0.7 * free.position_rmse_m);
  EXPECT_LT(estimated.car.max_rotation_error_rad, 0.7 * free.max_rotation_error_rad);
  EXPECT_LT(estimated.car.max_rotation_error_rad, 0.5 * held.car.max_rotation_error_rad);
}

TEST(Backend, AnchoringOptionsAreChecked) {
  BackendOptions o;
  o.anchored_observations_per_landmark = -1;
  EXPECT_NE(o.Check().find("anchored_observations_per_landmark"), std::string::npos);
  o.anchored_observations_per_landmark = 2;
  EXPECT_EQ(o.Check(), "");
  o.anchored_max_age_s = std::nan("");
  EXPECT_NE(o.Check().find("anchored_max_age_s"), std::string::npos);
  o.anchored_max_age_s = 0;
  o.anchored_max_depth_m = -1;
  EXPECT_NE(o.Check().find("anchored_max_depth_m"), std::string::npos);
  o.anchored_max_depth_m = 0;
  o.marginalize_tracked_landmarks = true;
  EXPECT_NE(o.Check().find("exclude each other"), std::string::npos);
}

// Falling snow or leaves: points that drift together through the scene (1.2 m/s, the wind's
// direction), each seen from 1.5-5 m for 0.5 s, about 25 at a time besides the 150 room tracks.
void AddParticles(const SyntheticScene& scene, std::vector<SyntheticFrame>* frames,
                  std::set<uint64_t>* particle_ids) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> normal;
  const Eigen::Vector3d velocity(0.6, 0.3, -1.0);
  struct Particle {
    uint64_t id;
    Eigen::Vector3d p0;
    double t0;
  };
  std::vector<Particle> alive;
  uint64_t next_id = 1'000'000;
  const double lifetime_s = 0.5;
  for (SyntheticFrame& f : *frames) {
    const double t = f.t_ns * 1e-9;
    std::erase_if(alive, [&](const Particle& q) { return t - q.t0 > lifetime_s; });
    const Rigid3d world_from_body = scene.trajectory.Pose(t);
    while (alive.size() < 25) {
      const Eigen::Vector3d in_body(1.5 + 3.5 * u(rng), -1.5 + 3 * u(rng), -1 + 2 * u(rng));
      alive.push_back({next_id++, world_from_body * in_body, t});
    }
    const Rigid3d body_from_world = world_from_body.Inverse();
    const Rigid3d cam0_from_world = scene.rig.cam0_from_body * body_from_world;
    const Rigid3d cam1_from_world = scene.rig.cam1_from_body * body_from_world;
    const double noise_n = 0.3 / scene.fx;
    for (const Particle& q : alive) {
      const Eigen::Vector3d p = q.p0 + velocity * (t - q.t0);
      const auto left = scene.Observe(cam0_from_world, p);
      if (!left) continue;
      StereoObservation obs;
      obs.track_id = q.id;
      obs.left = *left + noise_n * Eigen::Vector2d(normal(rng), normal(rng));
      if (const auto right = scene.Observe(cam1_from_world, p))
        obs.right = *right + noise_n * Eigen::Vector2d(normal(rng), normal(rng));
      f.observations.push_back(obs);
      particle_ids->insert(q.id);
    }
  }
}

// The room's frames (10 s at 30 Hz, 0.3 px noise) without and with the drifting particles.
struct ParticleRun {
  SyntheticScene scene;
  std::vector<SyntheticFrame> clean, with_particles;
  std::set<uint64_t> particle_ids;
  ParticleRun() : clean(scene.Generate(10.0, 30.0, 0.3, true, 6)), with_particles(clean) {
    AddParticles(scene, &with_particles, &particle_ids);
  }
};

TEST(Backend, PredictedGateRejectsDriftingParticles) {
  // The stereo-inertial window among drifting particles, without and with the gate on the
  // IMU-predicted pose (every frame a keyframe, as on the car route).
  const ParticleRun run;
  BackendOptions options;
  const RunResult clean = RunBackend(run.scene, run.clean, options, 1);
  const RunResult ungated = RunBackend(run.scene, run.with_particles, options, 1);
  options.predicted_gate_pixels = 2.0;
  const RunResult gated = RunBackend(run.scene, run.with_particles, options, 1);
  options.predicted_gate_median_factor = 3.0;  // the gate relative to the frame's median error
  const RunResult relative = RunBackend(run.scene, run.with_particles, options, 1);
  const double deg = 180 / M_PI;
  std::printf(
      "%zu particles among the room's tracks: max rotation error without the gate %.3f deg, "
      "with it %.3f deg (< 0.5 x, < 2 x %.3f deg without particles); position RMSE %.4f / "
      "%.4f m (%.4f m without particles)\n",
      run.particle_ids.size(), ungated.max_rotation_error_rad * deg,
      gated.max_rotation_error_rad * deg, clean.max_rotation_error_rad * deg,
      ungated.position_rmse_m, gated.position_rmse_m, clean.position_rmse_m);
  EXPECT_LT(gated.max_rotation_error_rad, 0.5 * ungated.max_rotation_error_rad);
  EXPECT_LT(gated.max_rotation_error_rad, 2.0 * clean.max_rotation_error_rad);
  EXPECT_LT(gated.position_rmse_m, ungated.position_rmse_m);
  // The particles are a minority: the median stays on the scene and the relative gate is the
  // fixed one here.
  std::printf("relative gate (3 x median): max rotation error %.3f deg, position RMSE %.4f m\n",
              relative.max_rotation_error_rad * deg, relative.position_rmse_m);
  EXPECT_LT(relative.max_rotation_error_rad, 0.5 * ungated.max_rotation_error_rad);
  EXPECT_LT(relative.max_rotation_error_rad, 2.0 * clean.max_rotation_error_rad);
  EXPECT_LT(relative.position_rmse_m, ungated.position_rmse_m);
}

TEST(Backend, StereoOnlyPnpGateRejectsDriftingParticles) {
  // Without IMU the gate measures against a RANSAC PnP pose of the new frame: the same drifting
  // particles, stereo-only, every frame a keyframe.
  const ParticleRun run;
  BackendOptions options;
  options.use_imu = false;
  options.stereo_only_outlier_pixels = 2.0;
  const RunResult clean = RunBackend(run.scene, run.clean, options, 1);
  const RunResult ungated = RunBackend(run.scene, run.with_particles, options, 1);
  options.stereo_only_pnp_gate_pixels = 2.0;
  const RunResult gated = RunBackend(run.scene, run.with_particles, options, 1);
  const RunResult gated_clean = RunBackend(run.scene, run.clean, options, 1);
  const double deg = 180 / M_PI;
  std::printf(
      "stereo-only, %zu particles: max rotation error without the PnP gate %.3f deg, with it "
      "%.3f deg (< 0.5 x; %.3f deg without particles); position RMSE %.4f / %.4f m (%.4f m "
      "without particles; gated without particles %.4f m, < 1.5 x)\n",
      run.particle_ids.size(), ungated.max_rotation_error_rad * deg,
      gated.max_rotation_error_rad * deg, clean.max_rotation_error_rad * deg,
      ungated.position_rmse_m, gated.position_rmse_m, clean.position_rmse_m,
      gated_clean.position_rmse_m);
  EXPECT_LT(gated.max_rotation_error_rad, 0.5 * ungated.max_rotation_error_rad);
  EXPECT_LT(gated.position_rmse_m, 0.5 * ungated.position_rmse_m);
  // Without particles the gate keeps the scene.
  EXPECT_LT(gated_clean.position_rmse_m, 1.5 * clean.position_rmse_m);
  EXPECT_LT(gated_clean.max_rotation_error_rad, 1.5 * clean.max_rotation_error_rad);
}

TEST(Backend, RelativePredictedGateKeepsTheSceneWhenThePredictionIsOff) {
  // An unknown gyro bias of 0.15 rad/s (initialised at zero) turns the IMU prediction by 5 mrad
  // per frame, 2.3 px at this focal length: the fixed 2 px gate rejects most of the scene until
  // the bias is estimated; widened to 3 x the frame's median predicted error it keeps it.
  SyntheticScene scene;
  scene.true_bias.gyro = {0.02, -0.03, 0.15};
  const auto frames = scene.Generate(6.0, 30.0, 0.3, true, 7);
  BackendOptions options;
  const RunResult ungated = RunBackend(scene, frames, options, 1);
  options.predicted_gate_pixels = 2.0;
  const RunResult fixed = RunBackend(scene, frames, options, 1);
  options.predicted_gate_median_factor = 3.0;
  const RunResult relative = RunBackend(scene, frames, options, 1);
  const double deg = 180 / M_PI;
  std::printf(
      "gyro bias 0.15 rad/s unknown: max rotation error without the gate %.3f deg, fixed 2 px "
      "%.3f deg, relative %.3f deg; position RMSE %.4f / %.4f / %.4f m\n",
      ungated.max_rotation_error_rad * deg, fixed.max_rotation_error_rad * deg,
      relative.max_rotation_error_rad * deg, ungated.position_rmse_m, fixed.position_rmse_m,
      relative.position_rmse_m);
  EXPECT_LT(relative.position_rmse_m, 1.5 * ungated.position_rmse_m);
  EXPECT_LT(relative.max_rotation_error_rad, 1.5 * ungated.max_rotation_error_rad);
  EXPECT_LT(relative.position_rmse_m, 0.5 * fixed.position_rmse_m);
}

struct PositionFunctor {
  Eigen::Vector3d dp, target, g;
  double dt, sigma;
  template <typename T>
  bool operator()(const T* pose, const T* sb, T* r) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p(pose), v(sb);
    const Eigen::Map<const Eigen::Quaternion<T>> q(pose + 3);
    const Eigen::Matrix<T, 3, 1> at_t =
        p + v * T(dt) + T(0.5 * dt * dt) * g.cast<T>() + q * dp.cast<T>();
    for (int i = 0; i < 3; ++i) r[i] = (at_t[i] - T(target[i])) / T(sigma);
    return true;
  }
};

struct Diff {
  Eigen::Vector3d measured;
  double w;
  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    for (int i = 0; i < 3; ++i) r[i] = T(w) * (b[i] - a[i] - T(measured[i]));
    return true;
  }
};
struct Abs {
  Eigen::Vector3d measured;
  double w;
  template <typename T>
  bool operator()(const T* a, T* r) const {
    for (int i = 0; i < 3; ++i) r[i] = T(w) * (a[i] - T(measured[i]));
    return true;
  }
};

// A position measurement at a time between frames (what the GNSS issue will add).
class TestPositionFactor : public TimedFactor {
 public:
  TestPositionFactor(int64_t t_ns, const Eigen::Vector3d& position, double sigma)
      : t_ns_(t_ns), position_(position), sigma_(sigma) {}
  int64_t t_ns() const override { return t_ns_; }
  ceres::CostFunction* Create(const ImuPreintegration& anchor_to_t, const Eigen::Vector3d& g,
                              bool uses_speed_bias) const override {
    EXPECT_TRUE(uses_speed_bias);
    return new ceres::AutoDiffCostFunction<PositionFunctor, 3, kPoseSize, kSpeedBiasSize>(
        new PositionFunctor{anchor_to_t.delta_p(), position_, g, anchor_to_t.dt_s(), sigma_});
  }

 private:
  int64_t t_ns_;
  Eigen::Vector3d position_;
  double sigma_;
};

TEST(Backend, TimedFactorsPullTheEstimate) {
  // Without vision, the IMU alone drifts; position factors at odd times (between frames) hold
  // the estimate to the truth, also after their anchor states are marginalised.
  SyntheticScene scene;
  scene.landmarks.clear();
  const auto frames = scene.Generate(6.0, 20.0, 0.7, true, 5);
  BackendOptions options;
  const RunResult free_run = RunBackend(scene, frames, options, 2);
  std::vector<std::unique_ptr<TimedFactor>> timed;
  for (double t = 0.33; t < 6.0; t += 0.5)
    timed.push_back(std::make_unique<TestPositionFactor>(static_cast<int64_t>(t * 1e9),
                                                         scene.trajectory.Position(t), 0.02));
  // Added all at once before the run: each enters the window when the frame after it arrives.
  const RunResult held = RunBackend(scene, frames, options, 2, std::move(timed));
  std::printf(
      "IMU only: position RMSE %.3f m; with position factors every 0.5 s (sigma 2 cm) "
      "between frames: %.3f m (< 0.05)\n",
      free_run.position_rmse_m, held.position_rmse_m);
  EXPECT_LT(held.position_rmse_m, 0.05);
  EXPECT_LT(held.position_rmse_m, 0.5 * free_run.position_rmse_m);
}

// An altimeter with an unknown constant offset: z(t) + offset - measured, the offset a global
// block of the window.
struct OffsetAltimeterFunctor {
  TimedStatePredictor predict;
  double measured, sigma;
  template <typename T>
  bool operator()(const T* pose, const T* sb, const T* offset, T* r) const {
    Eigen::Matrix<T, 3, 1> p;
    predict(pose, sb, &p, nullptr, nullptr);
    r[0] = (p[2] + offset[0] - T(measured)) / T(sigma);
    return true;
  }
};

class OffsetAltimeterFactor : public TimedFactor {
 public:
  OffsetAltimeterFactor(int64_t t_ns, double measured, int block)
      : t_ns_(t_ns), measured_(measured), block_(block) {}
  int64_t t_ns() const override { return t_ns_; }
  ceres::CostFunction* Create(const ImuPreintegration& pre, const Eigen::Vector3d& g,
                              bool) const override {
    return new ceres::AutoDiffCostFunction<OffsetAltimeterFunctor, 1, kPoseSize, kSpeedBiasSize, 1>(
        new OffsetAltimeterFunctor{TimedStatePredictor(pre, g), measured_, 0.01});
  }
  std::vector<int> global_blocks() const override { return {block_}; }

 private:
  int64_t t_ns_;
  double measured_;
  int block_;
};

TEST(Backend, GlobalBlockAndNewestCovariance) {
  // No vision: position factors (2 cm) every 0.5 s and an altimeter reading 0.7 m high at 20 Hz.
  // The altimeter's offset, a global block with a 2 m prior, must come out as 0.7 m, carried
  // through marginalisation; the newest state's covariance must be consistent with that.
  SyntheticScene scene;
  scene.landmarks.clear();
  const auto frames = scene.Generate(6.0, 20.0, 0.7, true, 5);
  BackendOptions options;
  options.imu_noise = scene.noise;
  options.window_keyframes = 6;
  SlidingWindowBackend backend(options, scene.rig);
  StateEstimate init;
  init.t_ns = frames[0].t_ns;
  init.world_from_body = scene.trajectory.Pose(0.0);
  init.velocity = scene.trajectory.Velocity(0.0);
  backend.Initialize(init, {});
  const int offset =
      backend.AddGlobalBlock(Eigen::VectorXd::Zero(1), Eigen::VectorXd::Constant(1, 2.0),
                             Eigen::VectorXd::Constant(1, 0.001));
  EXPECT_EQ(backend.GlobalBlock(offset).size(), 1);
  for (double t = 0.33; t < 6.0; t += 0.5)
    backend.AddTimedFactor(std::make_unique<TestPositionFactor>(
        static_cast<int64_t>(t * 1e9), scene.trajectory.Position(t), 0.02));
  for (double t = 0.01; t < 6.0; t += 0.05)
    backend.AddTimedFactor(std::make_unique<OffsetAltimeterFactor>(
        static_cast<int64_t>(t * 1e9), scene.trajectory.Position(t).z() + 0.7, offset));
  std::vector<TimedImuSample> imu(frames[0].imu.begin(), frames[0].imu.end());
  for (size_t i = 1; i < frames.size(); ++i) {
    imu.insert(imu.end(), frames[i].imu.begin(), frames[i].imu.end());
    ImuPreintegration pre(ImuBias{}, scene.noise);
    for (const ImuMeasurement& m : ImuMeasurementsBetween(imu, frames[i - 1].t_ns, frames[i].t_ns))
      pre.Integrate(m.gyro, m.accel, m.dt_s);
    backend.AddFrame(frames[i].t_ns, pre, {}, true);
  }
  const double estimated = backend.GlobalBlock(offset)[0];
  const Eigen::MatrixXd cov = backend.NewestCovariance();
  ASSERT_EQ(cov.rows(), 15);
  const double sigma_z = std::sqrt(cov(2, 2)), sigma_x = std::sqrt(cov(0, 0));
  const double error = (backend.Newest().world_from_body.translation -
                        scene.trajectory.Position(frames.back().t_ns * 1e-9))
                           .norm();
  std::printf(
      "altimeter offset %.4f m (truth 0.7, |err| < 0.02); newest position error %.4f m, "
      "sigma x %.4f m, sigma z %.4f m (in (0.001, 0.2))\n",
      estimated, error, sigma_x, sigma_z);
  EXPECT_NEAR(estimated, 0.7, 0.02);
  EXPECT_GT(sigma_x, 0.001);
  EXPECT_LT(sigma_x, 0.2);
  EXPECT_LT(sigma_z, 0.2);
  EXPECT_TRUE((cov - cov.transpose()).cwiseAbs().maxCoeff() < 1e-6 * cov.cwiseAbs().maxCoeff());
  EXPECT_LT(error, 5 * std::max(sigma_x, sigma_z) + 0.02);
}

TEST(Marginalize, SchurComplementKeepsTheSolution) {
  // A linear Gaussian chain x0 - x1 - x2 (3-vectors): marginalising x0 and solving the rest
  // gives the same x1, x2 as solving everything.
  double x[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  auto make = [&](std::vector<std::unique_ptr<ResidualSpec>>* specs) {
    auto add = [&](ceres::CostFunction* c, std::vector<double*> blocks) {
      auto s = std::make_unique<ResidualSpec>();
      s->cost.reset(c);
      s->blocks = std::move(blocks);
      specs->push_back(std::move(s));
    };
    add(new ceres::AutoDiffCostFunction<Abs, 3, 3>(new Abs{{1, 2, 3}, 2.0}), {x[0]});
    add(new ceres::AutoDiffCostFunction<Diff, 3, 3, 3>(new Diff{{0.5, -1, 2}, 1.0}), {x[0], x[1]});
    add(new ceres::AutoDiffCostFunction<Diff, 3, 3, 3>(new Diff{{1, 1, 1}, 3.0}), {x[0], x[2]});
    add(new ceres::AutoDiffCostFunction<Diff, 3, 3, 3>(new Diff{{0.4, -0.8, 3.1}, 0.5}),
        {x[1], x[2]});
    add(new ceres::AutoDiffCostFunction<Abs, 3, 3>(new Abs{{2, 2, 2}, 0.7}), {x[2]});
  };
  auto solve = [&](const std::vector<ResidualSpec*>& specs) {
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    for (ResidualSpec* s : specs) problem.AddResidualBlock(s->cost.get(), nullptr, s->blocks);
    ceres::Solver::Options so;
    so.logging_type = ceres::SILENT;
    so.function_tolerance = so.gradient_tolerance = so.parameter_tolerance = 1e-15;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
  };
  std::vector<std::unique_ptr<ResidualSpec>> full;
  make(&full);
  std::vector<ResidualSpec*> all;
  for (auto& s : full) all.push_back(s.get());
  solve(all);
  const Eigen::Vector3d x1_full(x[1]), x2_full(x[2]);

  // Linearise at a point away from the optimum (exact for a linear problem).
  for (auto& b : x)
    for (double& v : b) v = 0.3;
  std::vector<const ResidualSpec*> to_marginalize{full[0].get(), full[1].get(), full[2].get()};
  const LinearPrior prior = Marginalize(
      to_marginalize, {x[0]}, [](const double*) -> const ceres::Manifold* { return nullptr; },
      [](const double*) { return 3; });
  ASSERT_EQ(prior.blocks.size(), 2u);
  auto prior_spec = std::make_unique<ResidualSpec>();
  prior_spec->cost.reset(prior.CreateCostFunction());
  for (const auto& b : prior.blocks) prior_spec->blocks.push_back(b.values);
  solve({prior_spec.get(), full[3].get(), full[4].get()});
  const double err =
      std::max((Eigen::Vector3d(x[1]) - x1_full).norm(), (Eigen::Vector3d(x[2]) - x2_full).norm());
  std::printf("Schur marginalisation: |x_marg - x_full| = %.2e (< 1e-6)\n", err);
  EXPECT_LT(err, 1e-6);
}

}  // namespace
}  // namespace optinav::vio
