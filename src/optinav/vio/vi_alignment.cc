#include "optinav/vio/internal/vi_alignment.h"

#include <cmath>

#include <Eigen/Dense>
#include <fmt/format.h>

namespace optinav::vio {
namespace {

// VO attitude noise: enters through R_k applied to the preintegrated deltas.
constexpr double kRotationSigmaRad = 0.005;

Eigen::Matrix<double, 3, 2> TangentBasis(const Eigen::Vector3d& g) {
  const Eigen::Vector3d n = g.normalized();
  const Eigen::Vector3d a =
      std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  Eigen::Matrix<double, 3, 2> b;
  b.col(0) = (a - n * n.dot(a)).normalized();
  b.col(1) = n.cross(b.col(0));
  return b;
}

}  // namespace

ViAlignmentResult SolveViAlignment(const std::vector<int64_t>& t_ns,
                                   const std::vector<Rigid3d>& vo_from_body,
                                   std::vector<ImuPreintegration> pre,
                                   const ViAlignmentOptions& options) {
  ViAlignmentResult out;
  const int n = static_cast<int>(vo_from_body.size());
  if (n < 3 || t_ns.size() != vo_from_body.size() || pre.size() + 1 != vo_from_body.size()) {
    out.failure = "needs at least 3 poses and one preintegration between consecutive poses";
    return out;
  }
  for (int k = 0; k + 1 < n; ++k) {
    if (t_ns[k + 1] <= t_ns[k]) {
      out.failure = "pose times must increase";
      return out;
    }
  }
  const ImuBias prior_bias = pre.front().linearization_bias();

  // 1. Gyroscope bias from the odometry's relative rotations over half the window: the bias
  // error grows with the interval while the odometry's attitude noise does not, so long
  // intervals (the preintegrations chained) observe it best.
  ImuBias bias = prior_bias;
  for (int iteration = 0; iteration < 2; ++iteration) {
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    // Pairs (k, k + span) over the chained preintegrations: long intervals, distinct ends.
    const int span = std::max(1, (n - 1) / 2);
    for (int k = 0; k + span < n; ++k) {
      ImuPreintegration chained = pre[k];
      for (int m = k + 1; m < k + span; ++m) chained.Append(pre[m]);
      const Eigen::Quaterniond rel =
          vo_from_body[k].rotation.conjugate() * vo_from_body[k + span].rotation;
      const Eigen::Vector3d r = LogSO3(chained.delta_R().conjugate() * rel);
      const Eigen::Matrix3d& j = chained.dR_dbg();
      h += j.transpose() * j;
      g += j.transpose() * r;
    }
    const Eigen::Vector3d delta = h.ldlt().solve(g);
    if (!delta.allFinite()) {
      out.failure = "gyroscope bias not observable (no rotation data)";
      return out;
    }
    bias.gyro += delta;
    for (ImuPreintegration& p : pre) p.Reintegrate(bias);
  }
  out.gyro_bias = bias.gyro;

  // 2. Velocities and gravity. Unknowns: v_0 .. v_n-1, then gravity (3) or its tangent (2).
  const int nv = 3 * n;
  const int rows = 6 * (n - 1);
  Eigen::MatrixXd a_v = Eigen::MatrixXd::Zero(rows, nv);  // velocity columns
  Eigen::MatrixXd a_g = Eigen::MatrixXd::Zero(rows, 3);   // gravity columns
  Eigen::VectorXd b = Eigen::VectorXd::Zero(rows);
  Eigen::VectorXd w = Eigen::VectorXd::Zero(rows);  // 1 / sigma per row
  for (int k = 0; k + 1 < n; ++k) {
    const double dt = (t_ns[k + 1] - t_ns[k]) * 1e-9;
    const Eigen::Matrix3d rk = vo_from_body[k].rotation.toRotationMatrix();
    const Eigen::Vector3d dp = rk * pre[k].delta_p(), dv = rk * pre[k].delta_v();
    const Matrix9d& cov = pre[k].covariance();
    const double ba = options.accel_bias_sigma;
    const double var_p = 2 * options.position_sigma_m * options.position_sigma_m +
                         cov.block<3, 3>(6, 6).trace() / 3 + std::pow(0.5 * dt * dt * ba, 2) +
                         std::pow(kRotationSigmaRad * dp.norm(), 2);
    const double var_v = cov.block<3, 3>(3, 3).trace() / 3 + std::pow(dt * ba, 2) +
                         std::pow(kRotationSigmaRad * dv.norm(), 2);
    const int rp = 6 * k, rv = 6 * k + 3;
    // Position rows: v_k dt + 1/2 dt^2 g = p_k+1 - p_k - R_k dp.
    a_v.block<3, 3>(rp, 3 * k) = dt * Eigen::Matrix3d::Identity();
    a_g.block<3, 3>(rp, 0) = 0.5 * dt * dt * Eigen::Matrix3d::Identity();
    b.segment<3>(rp) = vo_from_body[k + 1].translation - vo_from_body[k].translation - dp;
    w.segment<3>(rp).setConstant(1 / std::sqrt(var_p));
    // Velocity rows: v_k+1 - v_k - dt g = R_k dv.
    a_v.block<3, 3>(rv, 3 * k) = -Eigen::Matrix3d::Identity();
    a_v.block<3, 3>(rv, 3 * (k + 1)) = Eigen::Matrix3d::Identity();
    a_g.block<3, 3>(rv, 0) = -dt * Eigen::Matrix3d::Identity();
    b.segment<3>(rv) = dv;
    w.segment<3>(rv).setConstant(1 / std::sqrt(var_v));
  }
  a_v = w.asDiagonal() * a_v;
  a_g = w.asDiagonal() * a_g;
  b = w.asDiagonal() * b;

  // Free solve.
  Eigen::MatrixXd a(rows, nv + 3);
  a << a_v, a_g;
  Eigen::VectorXd x = a.colPivHouseholderQr().solve(b);
  Eigen::Vector3d gravity = x.tail<3>();
  out.unconstrained_gravity_norm = gravity.norm();
  if (!x.allFinite() || std::abs(gravity.norm() - kGravityMagnitude) >
                            options.max_gravity_norm_error * kGravityMagnitude) {
    out.failure =
        fmt::format("gravity norm {:.2f} m/s^2 is not {:.2f} within {:.0f} %", gravity.norm(),
                    kGravityMagnitude, 100 * options.max_gravity_norm_error);
    return out;
  }

  // |g| fixed: gravity = g0 + B * dg, re-normalised, three times.
  Eigen::MatrixXd ac(rows, nv + 2);
  Eigen::VectorXd xc;
  for (int iteration = 0; iteration < 3; ++iteration) {
    const Eigen::Vector3d g0 = gravity.normalized() * kGravityMagnitude;
    const Eigen::Matrix<double, 3, 2> basis = TangentBasis(g0);
    ac << a_v, a_g * basis;
    xc = ac.colPivHouseholderQr().solve(b - a_g * g0);
    gravity = (g0 + basis * xc.tail<2>()).normalized() * kGravityMagnitude;
    if (iteration == 2) {
      const Eigen::VectorXd residual = ac * xc - (b - a_g * g0);
      out.whitened_rms = std::sqrt(residual.squaredNorm() / rows);
      out.max_whitened_residual = residual.cwiseAbs().maxCoeff();
      double sq = 0;
      for (int k = 0; k + 1 < n; ++k) sq += (residual.segment<3>(6 * k) / w(6 * k)).squaredNorm();
      out.position_rms_m = std::sqrt(sq / (3 * (n - 1)));
      // Covariance of the tangent, scaled by the residual when the noise model is optimistic.
      const Eigen::MatrixXd info = ac.transpose() * ac;
      const Eigen::MatrixXd cov = info.ldlt().solve(Eigen::MatrixXd::Identity(nv + 2, nv + 2));
      const double inflate = std::max(1.0, out.whitened_rms);
      out.tilt_sigma_rad =
          std::sqrt(cov.bottomRightCorner<2, 2>().trace() / 2) * inflate / kGravityMagnitude;
      out.first_velocity_sigma_m_s = std::sqrt(cov.topLeftCorner<3, 3>().trace() / 3) * inflate;
    }
  }
  if (!xc.allFinite()) {
    out.failure = "velocity/gravity solve is not finite";
    return out;
  }
  if (out.whitened_rms > options.max_whitened_rms ||
      out.max_whitened_residual > options.max_whitened_residual) {
    out.failure = fmt::format(
        "odometry and IMU disagree (whitened residual RMS {:.2f}, max {:.2f}; limits {:.2f}, "
        "{:.2f}; position RMS {:.3f} m)",
        out.whitened_rms, out.max_whitened_residual, options.max_whitened_rms,
        options.max_whitened_residual, out.position_rms_m);
    return out;
  }
  out.gravity_vo = gravity;
  out.velocities_vo.resize(n);
  for (int k = 0; k < n; ++k) out.velocities_vo[k] = xc.segment<3>(3 * k);
  out.world_from_vo = Eigen::Quaterniond::FromTwoVectors(gravity, GravityInWorld()).normalized();
  out.ok = true;
  return out;
}

}  // namespace optinav::vio
