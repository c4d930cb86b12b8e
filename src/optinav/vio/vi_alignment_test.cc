#include "optinav/vio/internal/vi_alignment.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "optinav/vio/test_trajectory.h"

namespace optinav::vio {
namespace {

constexpr double kDeg = M_PI / 180;

struct Case {
  std::vector<int64_t> t_ns;
  std::vector<Rigid3d> vo_from_body;
  std::vector<ImuPreintegration> pre;
  std::vector<Eigen::Vector3d> velocity_vo;  // truth
  Eigen::Quaterniond vo_from_world;
};

// Poses at 20 Hz for `duration_s`, expressed in an odometry frame tilted and turned away from
// the world; the IMU at 1 kHz with biases `true_bias`, preintegrated at zero bias.
// `position_noise_m` / `rotation_noise_rad` perturb the odometry poses (fixed seed).
Case MakeCase(double duration_s, const ImuBias& true_bias, double position_noise_m = 0,
              double rotation_noise_rad = 0, double scale_error = 1.0) {
  const AnalyticTrajectory traj;
  Case c;
  c.vo_from_world =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 0.5).normalized()));
  const Eigen::Vector3d vo_origin(4, -1, 2);
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0, 1);
  const double t0 = 1.0;
  const int frames = static_cast<int>(std::round(duration_s * 20)) + 1;
  for (int i = 0; i < frames; ++i) {
    const double t = t0 + i * 0.05;
    c.t_ns.push_back(static_cast<int64_t>(std::llround(t * 1e9)));
    Rigid3d pose(c.vo_from_world * traj.Rotation(t),
                 scale_error * (c.vo_from_world * traj.Position(t)) + vo_origin);
    pose.translation += position_noise_m * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    pose.rotation = (pose.rotation * ExpSO3(rotation_noise_rad *
                                            Eigen::Vector3d(normal(rng), normal(rng), normal(rng))))
                        .normalized();
    c.vo_from_body.push_back(pose);
    c.velocity_vo.push_back(c.vo_from_world * traj.Velocity(t));
    if (i > 0) {
      ImuPreintegration pre(ImuBias{}, ImuNoise{});
      const int n = 50;
      const double dt = 0.05 / n, ts = t - 0.05;
      for (int k = 0; k < n; ++k) {
        const double tk = ts + (k + 0.5) * dt;
        pre.Integrate(traj.GyroAt(tk) + true_bias.gyro, traj.AccelAt(tk) + true_bias.accel, dt);
      }
      c.pre.push_back(pre);
    }
  }
  return c;
}

double TiltErrorRad(const ViAlignmentResult& r, const Case& c) {
  // The estimated world_from_vo must map the true world's up direction onto +z.
  const Eigen::Vector3d up = r.world_from_vo * (c.vo_from_world * Eigen::Vector3d::UnitZ());
  return std::acos(std::min(1.0, up.z()));
}

double MaxVelocityError(const ViAlignmentResult& r, const Case& c) {
  double worst = 0;
  for (size_t k = 0; k < c.velocity_vo.size(); ++k)
    worst = std::max(worst, (r.velocities_vo[k] - c.velocity_vo[k]).norm());
  return worst;
}

TEST(ViAlignment, RecoversGravityVelocityAndGyroBiasFromExactData) {
  ImuBias bias;
  bias.gyro = {0.01, -0.02, 0.015};
  const Case c = MakeCase(1.5, bias);
  const ViAlignmentResult r = SolveViAlignment(c.t_ns, c.vo_from_body, c.pre);
  ASSERT_TRUE(r.ok) << r.failure;
  const double tilt = TiltErrorRad(r, c), vel = MaxVelocityError(r, c);
  const double bg = (r.gyro_bias - bias.gyro).norm();
  std::printf(
      "exact data, 1.5 s: tilt error %.4f deg (< 0.05), velocity %.4f m/s (< 0.01), "
      "gyro bias %.2e rad/s (< 2e-4), free |g| %.3f\n",
      tilt / kDeg, vel, bg, r.unconstrained_gravity_norm);
  EXPECT_LT(tilt, 0.05 * kDeg);
  EXPECT_LT(vel, 0.01);
  EXPECT_LT(bg, 2e-4);
  EXPECT_NEAR(r.gravity_vo.norm(), kGravityMagnitude, 1e-9);
}

TEST(ViAlignment, NoisyOdometryAndUnknownAccelBias) {
  ImuBias bias;
  bias.gyro = {0.01, -0.02, 0.015};
  bias.accel = {0.03, -0.02, 0.04};  // unknown to the solver (prior zero)
  const Case c = MakeCase(1.5, bias, 0.005, 0.002);
  const ViAlignmentResult r = SolveViAlignment(c.t_ns, c.vo_from_body, c.pre);
  ASSERT_TRUE(r.ok) << r.failure;
  const double tilt = TiltErrorRad(r, c), vel = MaxVelocityError(r, c);
  const double bg = (r.gyro_bias - bias.gyro).norm();
  std::printf(
      "5 mm / 2 mrad odometry noise, 0.05 m/s^2 accel bias: tilt error %.3f deg "
      "(< 0.5, reported sigma %.3f deg), velocity %.3f m/s (< 0.1), gyro bias %.2e "
      "(< 3e-3), whitened RMS %.2f max %.2f\n",
      tilt / kDeg, r.tilt_sigma_rad / kDeg, vel, bg, r.whitened_rms, r.max_whitened_residual);
  EXPECT_LT(tilt, 0.5 * kDeg);
  EXPECT_LT(vel, 0.1);
  EXPECT_LT(bg, 3e-3);
  EXPECT_GT(r.tilt_sigma_rad, 0);
}

TEST(ViAlignment, RejectsOdometryThatDisagreesWithTheImu) {
  // A tracking failure: the odometry jumps 0.3 m in the middle of the window.
  Case c = MakeCase(1.5, ImuBias{});
  for (size_t k = c.vo_from_body.size() / 2; k < c.vo_from_body.size(); ++k)
    c.vo_from_body[k].translation += Eigen::Vector3d(0.3, 0, 0);
  const ViAlignmentResult r = SolveViAlignment(c.t_ns, c.vo_from_body, c.pre);
  std::printf("0.3 m jump: ok=%d (%s) rms %.2f max %.2f\n", r.ok, r.failure.c_str(), r.whitened_rms,
              r.max_whitened_residual);
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.failure.empty());
}

TEST(ViAlignment, RejectsTooFewPosesAndUnorderedTimes) {
  Case c = MakeCase(0.05, ImuBias{});
  EXPECT_FALSE(SolveViAlignment(c.t_ns, c.vo_from_body, c.pre).ok);
  c = MakeCase(0.5, ImuBias{});
  std::swap(c.t_ns[2], c.t_ns[3]);
  const ViAlignmentResult r = SolveViAlignment(c.t_ns, c.vo_from_body, c.pre);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.failure.find("increase"), std::string::npos);
}

}  // namespace
}  // namespace optinav::vio
