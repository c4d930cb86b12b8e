#include "optinav/vio/imu_preintegration.h"

#include <algorithm>

#include "optinav/geometry/lie.h"
#include "optinav/util/error.h"

namespace optinav::vio {

ImuPreintegration::ImuPreintegration(const ImuBias& linearization_bias, const ImuNoise& noise)
    : bias_(linearization_bias), noise_(noise) {}

void ImuPreintegration::Reset() {
  dt_s_ = 0;
  gyro_walk_s_ = 0;
  delta_R_.setIdentity();
  delta_v_.setZero();
  delta_p_.setZero();
  covariance_.setZero();
  dR_dbg_.setZero();
  dv_dbg_.setZero();
  dv_dba_.setZero();
  dp_dbg_.setZero();
  dp_dba_.setZero();
}

void ImuPreintegration::Integrate(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel,
                                  double dt_s) {
  OPTINAV_CHECK(dt_s > 0);
  Add({dt_s, gyro, accel});
}

void ImuPreintegration::Append(const ImuPreintegration& next) {
  for (const ImuMeasurement& m : next.measurements_) Add(m);
}

void ImuPreintegration::Reintegrate(const ImuBias& linearization_bias) {
  bias_ = linearization_bias;
  Reset();
  for (const ImuMeasurement& m : measurements_) Propagate(m);
}

ImuPreintegration ImuPreintegration::Prefix(double duration_s) const {
  ImuPreintegration out(bias_, noise_);
  double t = 0;
  for (const ImuMeasurement& m : measurements_) {
    const double dt = std::min(m.dt_s, duration_s - t);
    if (dt <= 1e-12) break;
    ImuMeasurement cut = m;
    cut.dt_s = dt;
    out.Add(cut);
    t += dt;
  }
  return out;
}

void ImuPreintegration::Add(const ImuMeasurement& m) {
  measurements_.push_back(m);
  Propagate(measurements_.back());
}

void ImuPreintegration::ScaleGyroBiasWalk(double scale) {
  OPTINAV_CHECK(scale > 0);
  gyro_walk_s_ = 0;
  for (ImuMeasurement& m : measurements_) {
    m.gyro_walk_scale *= scale;
    gyro_walk_s_ += m.gyro_walk_scale * m.gyro_walk_scale * m.dt_s;
  }
}

void ImuPreintegration::ScaleWhiteNoise(double scale) {
  OPTINAV_CHECK(scale > 0);
  for (ImuMeasurement& m : measurements_) m.white_noise_scale *= scale;
  Reintegrate(bias_);
}

void ImuPreintegration::Propagate(const ImuMeasurement& m) {
  const double dt = m.dt_s, dt2 = dt * dt;
  gyro_walk_s_ += m.gyro_walk_scale * m.gyro_walk_scale * dt;
  const Eigen::Vector3d w = m.gyro - bias_.gyro;
  const Eigen::Vector3d a = m.accel - bias_.accel;
  const Eigen::Matrix3d dR = delta_R_.toRotationMatrix();
  const Eigen::Matrix3d a_hat = Hat(a);
  const Eigen::Vector3d rotation_increment = w * dt;
  const Eigen::Quaterniond dR_inc = ExpSO3(rotation_increment);
  const Eigen::Matrix3d dR_inc_T = dR_inc.toRotationMatrix().transpose();
  const Eigen::Matrix3d jr = RightJacobianSO3(rotation_increment);

  // Covariance of (phi, v, p): A * P * A^T + B * Q * B^T with discrete noise sigma^2 / dt.
  Matrix9d A = Matrix9d::Identity();
  A.block<3, 3>(0, 0) = dR_inc_T;
  A.block<3, 3>(3, 0) = -dR * a_hat * dt;
  A.block<3, 3>(6, 0) = -0.5 * dR * a_hat * dt2;
  A.block<3, 3>(6, 3) = Eigen::Matrix3d::Identity() * dt;
  Eigen::Matrix<double, 9, 6> B = Eigen::Matrix<double, 9, 6>::Zero();
  B.block<3, 3>(0, 0) = jr * dt;
  B.block<3, 3>(3, 3) = dR * dt;
  B.block<3, 3>(6, 3) = 0.5 * dR * dt2;
  Eigen::Matrix<double, 6, 1> q;
  const double sg = noise_.gyro_noise_density * m.white_noise_scale;
  const double sa = noise_.accel_noise_density * m.white_noise_scale;
  q << Eigen::Vector3d::Constant(sg * sg / dt), Eigen::Vector3d::Constant(sa * sa / dt);
  covariance_ = A * covariance_ * A.transpose() + B * q.asDiagonal() * B.transpose();

  // Bias Jacobians: position first (it uses the old velocity and rotation Jacobians).
  dp_dba_ += dv_dba_ * dt - 0.5 * dR * dt2;
  dp_dbg_ += dv_dbg_ * dt - 0.5 * dR * a_hat * dR_dbg_ * dt2;
  dv_dba_ -= dR * dt;
  dv_dbg_ -= dR * a_hat * dR_dbg_ * dt;
  dR_dbg_ = dR_inc_T * dR_dbg_ - jr * dt;

  // The deltas themselves.
  delta_p_ += delta_v_ * dt + 0.5 * dR * a * dt2;
  delta_v_ += dR * a * dt;
  delta_R_ = (delta_R_ * dR_inc).normalized();
  dt_s_ += dt;
}

Matrix15d ImuPreintegration::FullCovariance() const {
  Matrix15d c = Matrix15d::Zero();
  c.topLeftCorner<9, 9>() = covariance_;
  const double wg = noise_.gyro_random_walk, wa = noise_.accel_random_walk;
  c.block<3, 3>(9, 9) = Eigen::Matrix3d::Identity() * wg * wg * gyro_walk_s_;
  c.block<3, 3>(12, 12) = Eigen::Matrix3d::Identity() * wa * wa * dt_s_;
  return c;
}

Eigen::Quaterniond ImuPreintegration::CorrectedDeltaR(const ImuBias& bias) const {
  return (delta_R_ * ExpSO3(dR_dbg_ * (bias.gyro - bias_.gyro))).normalized();
}

Eigen::Vector3d ImuPreintegration::CorrectedDeltaV(const ImuBias& bias) const {
  return delta_v_ + dv_dbg_ * (bias.gyro - bias_.gyro) + dv_dba_ * (bias.accel - bias_.accel);
}

Eigen::Vector3d ImuPreintegration::CorrectedDeltaP(const ImuBias& bias) const {
  return delta_p_ + dp_dbg_ * (bias.gyro - bias_.gyro) + dp_dba_ * (bias.accel - bias_.accel);
}

NavState ImuPreintegration::Predict(const NavState& s, const ImuBias& bias,
                                    const Eigen::Vector3d& gravity) const {
  NavState out;
  const double dt = dt_s_;
  out.world_from_body_rotation = (s.world_from_body_rotation * CorrectedDeltaR(bias)).normalized();
  out.velocity = s.velocity + gravity * dt + s.world_from_body_rotation * CorrectedDeltaV(bias);
  out.position = s.position + s.velocity * dt + 0.5 * gravity * dt * dt +
                 s.world_from_body_rotation * CorrectedDeltaP(bias);
  return out;
}

Eigen::Matrix<double, 9, 1> ImuPreintegration::Residual(const NavState& si, const NavState& sj,
                                                        const ImuBias& bias,
                                                        const Eigen::Vector3d& gravity) const {
  const double dt = dt_s_;
  const Eigen::Quaterniond ri_inv = si.world_from_body_rotation.conjugate();
  Eigen::Matrix<double, 9, 1> r;
  r.head<3>() = LogSO3(CorrectedDeltaR(bias).conjugate() * ri_inv * sj.world_from_body_rotation);
  r.segment<3>(3) = ri_inv * (sj.velocity - si.velocity - gravity * dt) - CorrectedDeltaV(bias);
  r.tail<3>() = ri_inv * (sj.position - si.position - si.velocity * dt - 0.5 * gravity * dt * dt) -
                CorrectedDeltaP(bias);
  return r;
}

std::vector<ImuMeasurement> ImuMeasurementsBetween(const std::vector<TimedImuSample>& samples,
                                                   int64_t t0_ns, int64_t t1_ns) {
  std::vector<ImuMeasurement> out;
  if (samples.empty() || t1_ns <= t0_ns) return out;
  // Linear interpolation of the samples at time t (held constant outside their span).
  auto at = [&](double t_ns, Eigen::Vector3d* gyro, Eigen::Vector3d* accel) {
    auto it = std::lower_bound(samples.begin(), samples.end(), t_ns,
                               [](const TimedImuSample& s, double t) { return s.t_ns < t; });
    if (it == samples.begin()) {
      *gyro = it->gyro, *accel = it->accel;
      return;
    }
    if (it == samples.end()) {
      *gyro = samples.back().gyro, *accel = samples.back().accel;
      return;
    }
    const TimedImuSample& b = *it;
    const TimedImuSample& a = *(it - 1);
    const double alpha = (t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
    *gyro = (1 - alpha) * a.gyro + alpha * b.gyro;
    *accel = (1 - alpha) * a.accel + alpha * b.accel;
  };
  std::vector<int64_t> cuts{t0_ns};
  for (const TimedImuSample& s : samples)
    if (s.t_ns > t0_ns && s.t_ns < t1_ns) cuts.push_back(s.t_ns);
  cuts.push_back(t1_ns);
  for (size_t k = 0; k + 1 < cuts.size(); ++k) {
    ImuMeasurement m;
    m.dt_s = (cuts[k + 1] - cuts[k]) * 1e-9;
    if (m.dt_s <= 0) continue;
    // The midpoint value: second-order accurate for smooth signals.
    at(0.5 * (static_cast<double>(cuts[k]) + static_cast<double>(cuts[k + 1])), &m.gyro, &m.accel);
    out.push_back(m);
  }
  return out;
}

}  // namespace optinav::vio
