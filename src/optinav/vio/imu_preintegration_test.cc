#include "optinav/vio/imu_preintegration.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "optinav/geometry/lie.h"
#include "optinav/vio/test_trajectory.h"

namespace optinav::vio {
namespace {

// Integrates the analytic trajectory's ideal IMU from t0 to t1 at `rate_hz` (midpoint samples).
ImuPreintegration IntegrateAnalytic(const AnalyticTrajectory& traj, double t0, double t1,
                                    double rate_hz, const ImuBias& true_bias,
                                    const ImuBias& lin_bias) {
  ImuPreintegration pre(lin_bias, ImuNoise{});
  const int n = static_cast<int>(std::round((t1 - t0) * rate_hz));
  const double dt = (t1 - t0) / n;
  for (int k = 0; k < n; ++k) {
    const double t = t0 + (k + 0.5) * dt;
    pre.Integrate(traj.GyroAt(t) + true_bias.gyro, traj.AccelAt(t) + true_bias.accel, dt);
  }
  return pre;
}

TEST(ImuPreintegration, PredictsAnalyticTrajectory) {
  const AnalyticTrajectory traj;
  ImuBias bias;
  bias.gyro = {0.01, -0.02, 0.015};
  bias.accel = {0.1, 0.05, -0.08};
  const double t0 = 0.3, t1 = 2.3;
  const NavState truth = traj.StateAt(t1);
  // Forster's discretisation (sample held over dt, rotation at the interval start) is first
  // order: the error must shrink about 4x when the rate grows 4x.
  double pos_err[2], vel_err[2], rot_err[2];
  const double rates[2] = {1000, 4000};
  for (int k = 0; k < 2; ++k) {
    const ImuPreintegration pre = IntegrateAnalytic(traj, t0, t1, rates[k], bias, bias);
    const NavState predicted = pre.Predict(traj.StateAt(t0), bias);
    pos_err[k] = (predicted.position - truth.position).norm();
    vel_err[k] = (predicted.velocity - truth.velocity).norm();
    rot_err[k] = RotationAngle(predicted.world_from_body_rotation.conjugate() *
                               truth.world_from_body_rotation);
    std::printf("2 s at %.0f Hz: position error %.2e m, velocity %.2e m/s, rotation %.2e rad\n",
                rates[k], pos_err[k], vel_err[k], rot_err[k]);
  }
  std::printf(
      "thresholds at 1 kHz: position < 2e-3 m, velocity < 1e-3 m/s, rotation < 1e-5 rad; "
      "4 kHz error < 1/3 of 1 kHz error\n");
  EXPECT_LT(pos_err[0], 2e-3);
  EXPECT_LT(vel_err[0], 1e-3);
  EXPECT_LT(rot_err[0], 1e-5);
  EXPECT_LT(pos_err[1], pos_err[0] / 3);
  EXPECT_LT(vel_err[1], vel_err[0] / 3);
  const ImuPreintegration pre = IntegrateAnalytic(traj, t0, t1, 4000, bias, bias);
  EXPECT_LT(pre.Residual(traj.StateAt(t0), truth, bias).norm(), 1e-3);
  // A wrong state gives a residual of the right size.
  NavState moved = truth;
  moved.position.x() += 0.5;
  EXPECT_NEAR(pre.Residual(traj.StateAt(t0), moved, bias).tail<3>().norm(), 0.5, 1e-3);
}

TEST(ImuPreintegration, BiasJacobiansMatchNumericDifferences) {
  const AnalyticTrajectory traj;
  const ImuBias lin;
  const ImuPreintegration base = IntegrateAnalytic(traj, 0.0, 1.0, 400, {}, lin);
  const double h = 1e-6;
  Eigen::Matrix<double, 9, 6> numeric, analytic;
  for (int c = 0; c < 6; ++c) {
    ImuBias b = lin;
    if (c < 3)
      b.gyro[c] += h;
    else
      b.accel[c - 3] += h;
    ImuPreintegration moved = base;
    moved.Reintegrate(b);
    // The preintegrated quantities at the moved bias, as a function of the bias.
    numeric.block<3, 1>(0, c) = LogSO3(base.delta_R().conjugate() * moved.delta_R()) / h;
    numeric.block<3, 1>(3, c) = (moved.delta_v() - base.delta_v()) / h;
    numeric.block<3, 1>(6, c) = (moved.delta_p() - base.delta_p()) / h;
  }
  analytic.setZero();
  analytic.block<3, 3>(0, 0) = base.dR_dbg();
  analytic.block<3, 3>(3, 0) = base.dv_dbg();
  analytic.block<3, 3>(3, 3) = base.dv_dba();
  analytic.block<3, 3>(6, 0) = base.dp_dbg();
  analytic.block<3, 3>(6, 3) = base.dp_dba();
  const double err = (numeric - analytic).cwiseAbs().maxCoeff();
  std::printf("bias Jacobians: max |numeric - analytic| = %.2e (< 1e-4), max |J| = %.2f\n", err,
              analytic.cwiseAbs().maxCoeff());
  EXPECT_LT(err, 1e-4);
  EXPECT_GT(analytic.cwiseAbs().maxCoeff(), 0.1);

  // First-order bias correction is close to a full re-integration for a small bias change.
  ImuBias changed;
  changed.gyro = {0.002, -0.001, 0.003};
  changed.accel = {0.02, 0.03, -0.01};
  ImuPreintegration redone = base;
  redone.Reintegrate(changed);
  EXPECT_LT((base.CorrectedDeltaP(changed) - redone.delta_p()).norm(), 1e-4);
  EXPECT_LT((base.CorrectedDeltaV(changed) - redone.delta_v()).norm(), 1e-4);
  EXPECT_LT(RotationAngle(base.CorrectedDeltaR(changed).conjugate() * redone.delta_R()), 1e-6);
}

TEST(ImuPreintegration, CovarianceMatchesMonteCarlo) {
  const AnalyticTrajectory traj;
  ImuNoise noise;
  noise.gyro_noise_density = 2e-3;
  noise.accel_noise_density = 2e-2;
  const double rate = 200, t0 = 0.0, t1 = 1.0;
  const int n = static_cast<int>((t1 - t0) * rate);
  const double dt = 1.0 / rate;
  ImuPreintegration clean(ImuBias{}, noise);
  std::vector<Eigen::Vector3d> gyro(n), accel(n);
  for (int k = 0; k < n; ++k) {
    gyro[k] = traj.GyroAt(t0 + (k + 0.5) * dt);
    accel[k] = traj.AccelAt(t0 + (k + 0.5) * dt);
    clean.Integrate(gyro[k], accel[k], dt);
  }
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  const double sg = noise.gyro_noise_density / std::sqrt(dt);
  const double sa = noise.accel_noise_density / std::sqrt(dt);
  const int runs = 2000;
  Matrix9d sample_cov = Matrix9d::Zero();
  for (int r = 0; r < runs; ++r) {
    ImuPreintegration noisy(ImuBias{}, noise);
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3d ng(normal(rng), normal(rng), normal(rng));
      const Eigen::Vector3d na(normal(rng), normal(rng), normal(rng));
      noisy.Integrate(gyro[k] + sg * ng, accel[k] + sa * na, dt);
    }
    Eigen::Matrix<double, 9, 1> e;
    e << LogSO3(clean.delta_R().conjugate() * noisy.delta_R()), noisy.delta_v() - clean.delta_v(),
        noisy.delta_p() - clean.delta_p();
    sample_cov += e * e.transpose() / runs;
  }
  const Matrix9d& cov = clean.covariance();
  // Compare standard deviations per component (2000 samples: about 3 % sampling error).
  double worst = 0;
  for (int i = 0; i < 9; ++i) {
    const double ratio = std::sqrt(sample_cov(i, i) / cov(i, i));
    worst = std::max(worst, std::abs(ratio - 1.0));
  }
  std::printf("covariance: worst relative std deviation error vs Monte Carlo %.3f (< 0.10)\n",
              worst);
  EXPECT_LT(worst, 0.10);
  // Cross terms (rotation -> velocity coupling) are predicted too.
  const double corr_pred = cov(3, 1) / std::sqrt(cov(3, 3) * cov(1, 1));
  const double corr_mc = sample_cov(3, 1) / std::sqrt(sample_cov(3, 3) * sample_cov(1, 1));
  EXPECT_NEAR(corr_pred, corr_mc, 0.1);
  // Bias random walk grows linearly in the 15x15 covariance.
  const Matrix15d full = clean.FullCovariance();
  EXPECT_NEAR(full(9, 9), noise.gyro_random_walk * noise.gyro_random_walk * 1.0, 1e-15);
}

TEST(ImuPreintegration, AppendEqualsOneIntegration) {
  const AnalyticTrajectory traj;
  ImuBias bias;
  bias.gyro = {0.01, 0, 0};
  const ImuPreintegration whole = IntegrateAnalytic(traj, 0.0, 1.0, 200, {}, bias);
  ImuPreintegration first = IntegrateAnalytic(traj, 0.0, 0.4, 200, {}, bias);
  const ImuPreintegration second = IntegrateAnalytic(traj, 0.4, 1.0, 200, {}, bias);
  first.Append(second);
  EXPECT_NEAR(first.dt_s(), 1.0, 1e-12);
  EXPECT_LT((first.delta_p() - whole.delta_p()).norm(), 1e-12);
  EXPECT_LT((first.covariance() - whole.covariance()).norm(), 1e-15);
  EXPECT_LT((first.dp_dbg() - whole.dp_dbg()).norm(), 1e-12);
}

// A held gyro bias (ScaleGyroBiasWalk, backend.lowcontrast_gyro_walk_scale): only the gyro bias
// block of the 15x15 covariance shrinks, by the scale squared; it survives a merge with an
// unscaled interval (time-weighted), a re-integration and a prefix.
TEST(ImuPreintegration, ScaledGyroBiasWalk) {
  const AnalyticTrajectory traj;
  const ImuNoise noise;
  ImuPreintegration held = IntegrateAnalytic(traj, 0.0, 0.4, 200, {}, {});
  const ImuPreintegration plain = held;
  held.ScaleGyroBiasWalk(0.1);
  const double wg2 = noise.gyro_random_walk * noise.gyro_random_walk;
  const Matrix15d a = plain.FullCovariance(), b = held.FullCovariance();
  EXPECT_NEAR(b(9, 9), 0.01 * a(9, 9), 1e-20);
  EXPECT_NEAR(b(11, 11), 0.01 * wg2 * 0.4, 1e-20);
  EXPECT_EQ(b(12, 12), a(12, 12));
  EXPECT_EQ((b.topLeftCorner<9, 9>() - a.topLeftCorner<9, 9>()).norm(), 0.0);
  ImuPreintegration merged = held;
  merged.Append(IntegrateAnalytic(traj, 0.4, 1.0, 200, {}, {}));
  EXPECT_NEAR(merged.FullCovariance()(9, 9), wg2 * (0.01 * 0.4 + 0.6), 1e-18);
  ImuBias other;
  other.gyro = {0.002, 0, 0};
  merged.Reintegrate(other);
  EXPECT_NEAR(merged.FullCovariance()(9, 9), wg2 * (0.01 * 0.4 + 0.6), 1e-18);
  EXPECT_NEAR(merged.Prefix(0.2).FullCovariance()(9, 9), wg2 * 0.01 * 0.2, 1e-18);
}

// An interval's white noise inflated (ScaleWhiteNoise, the backend's IMU fault check): the
// preintegrated covariance grows by the scale squared, the deltas and the bias walk stay; the
// scale survives a merge (per sample), a re-integration and a prefix.
TEST(ImuPreintegration, ScaledWhiteNoise) {
  const AnalyticTrajectory traj;
  ImuPreintegration noisy = IntegrateAnalytic(traj, 0.0, 0.4, 200, {}, {});
  const ImuPreintegration plain = noisy;
  noisy.ScaleWhiteNoise(10.0);
  const Matrix15d a = plain.FullCovariance(), b = noisy.FullCovariance();
  const Matrix9d expected = 100.0 * a.topLeftCorner<9, 9>();
  EXPECT_LT((b.topLeftCorner<9, 9>() - expected).norm(), 1e-9 * expected.norm());
  EXPECT_EQ((b.bottomRightCorner<6, 6>() - a.bottomRightCorner<6, 6>()).norm(), 0.0);
  EXPECT_EQ((noisy.delta_p() - plain.delta_p()).norm(), 0.0);
  EXPECT_EQ(noisy.delta_R().angularDistance(plain.delta_R()), 0.0);
  ImuPreintegration merged = noisy;
  merged.Append(IntegrateAnalytic(traj, 0.4, 1.0, 200, {}, {}));
  ImuPreintegration merged_plain = plain;
  merged_plain.Append(IntegrateAnalytic(traj, 0.4, 1.0, 200, {}, {}));
  EXPECT_GT(merged.covariance()(0, 0), 10.0 * merged_plain.covariance()(0, 0));
  const double before = merged.covariance()(0, 0);
  merged.Reintegrate(merged.linearization_bias());
  EXPECT_NEAR(merged.covariance()(0, 0), before, 1e-12 * before);
  EXPECT_NEAR(noisy.Prefix(0.2).covariance()(0, 0), 100.0 * plain.Prefix(0.2).covariance()(0, 0),
              1e-9 * noisy.Prefix(0.2).covariance()(0, 0));
}

TEST(ImuPreintegration, MeasurementsBetweenCoverTheInterval) {
  std::vector<TimedImuSample> samples;
  for (int k = 0; k < 10; ++k) {
    TimedImuSample s;
    s.t_ns = k * 5'000'000;  // 200 Hz
    s.gyro = Eigen::Vector3d::Constant(k);
    s.accel = Eigen::Vector3d::Constant(2.0 * k);
    samples.push_back(s);
  }
  const auto m = ImuMeasurementsBetween(samples, 7'000'000, 21'000'000);
  double total = 0;
  for (const ImuMeasurement& x : m) total += x.dt_s;
  EXPECT_NEAR(total, 0.014, 1e-12);
  ASSERT_EQ(m.size(), 4u);                      // cuts at 7, 10, 15, 20, 21 ms
  EXPECT_NEAR(m[0].gyro.x(), 8.5 / 5.0, 1e-9);  // value at 8.5 ms
  EXPECT_NEAR(m[3].accel.x(), 2.0 * 20.5 / 5.0, 1e-9);
  EXPECT_TRUE(ImuMeasurementsBetween(samples, 5, 5).empty());
}

}  // namespace
}  // namespace optinav::vio
