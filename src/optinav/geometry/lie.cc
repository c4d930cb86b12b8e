#include "optinav/geometry/lie.h"

#include <cmath>

#include <Eigen/SVD>

namespace optinav {

Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& w) {
  const double theta2 = w.squaredNorm();
  const double theta = std::sqrt(theta2);
  double real, imag_factor;
  if (theta < 1e-8) {
    // Taylor expansion: sin(theta/2)/theta ~ 1/2 - theta^2/48.
    real = 1.0 - theta2 / 8.0;
    imag_factor = 0.5 - theta2 / 48.0;
  } else {
    real = std::cos(0.5 * theta);
    imag_factor = std::sin(0.5 * theta) / theta;
  }
  Eigen::Quaterniond q(real, imag_factor * w.x(), imag_factor * w.y(), imag_factor * w.z());
  return q.normalized();
}

Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  // Use the representative with w >= 0 so the angle is in [0, pi].
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d v = q.vec();
  const double n = v.norm();
  if (n < 1e-10) {
    // atan2(n, w) / n -> 1 / w for small n.
    return (2.0 / q.w()) * v;
  }
  const double angle = 2.0 * std::atan2(n, q.w());
  return (angle / n) * v;
}

double RotationAngle(const Eigen::Quaterniond& q) {
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
}

double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

Eigen::Matrix3d RightJacobianSO3(const Eigen::Vector3d& w) {
  const double theta2 = w.squaredNorm();
  const Eigen::Matrix3d W = Hat(w);
  if (theta2 < 1e-10) return Eigen::Matrix3d::Identity() - 0.5 * W + W * W / 6.0;
  const double theta = std::sqrt(theta2);
  return Eigen::Matrix3d::Identity() - (1.0 - std::cos(theta)) / theta2 * W +
         (theta - std::sin(theta)) / (theta2 * theta) * W * W;
}

Eigen::Quaterniond QuaternionFromWxyz(double w, double x, double y, double z) {
  return Eigen::Quaterniond(w, x, y, z).normalized();
}
Eigen::Quaterniond QuaternionFromXyzw(double x, double y, double z, double w) {
  return Eigen::Quaterniond(w, x, y, z).normalized();
}
Eigen::Vector4d QuaternionToWxyz(const Eigen::Quaterniond& q) {
  return {q.w(), q.x(), q.y(), q.z()};
}
Eigen::Vector4d QuaternionToXyzw(const Eigen::Quaterniond& q) {
  return {q.x(), q.y(), q.z(), q.w()};
}

Eigen::Quaterniond QuaternionFromMatrix(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) d(2, 2) = -1;
  const Eigen::Matrix3d r = svd.matrixU() * d * svd.matrixV().transpose();
  return Eigen::Quaterniond(r).normalized();
}

Rigid3d Rigid3d::FromMatrix(const Eigen::Matrix<double, 3, 4>& m) {
  return {QuaternionFromMatrix(m.leftCols<3>()), m.col(3)};
}

Eigen::Matrix4d Rigid3d::ToMatrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = rotation.toRotationMatrix();
  m.topRightCorner<3, 1>() = translation;
  return m;
}

Eigen::Matrix<double, 3, 4> Rigid3d::ToMatrix3x4() const { return ToMatrix().topRows<3>(); }

Rigid3d Rigid3d::Inverse() const {
  const Eigen::Quaterniond inv = rotation.conjugate();
  return {inv, -(inv * translation)};
}

Rigid3d Rigid3d::operator*(const Rigid3d& o) const {
  return {(rotation * o.rotation).normalized(), rotation * o.translation + translation};
}

Rigid3d ExpSE3(const Vector6d& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  // Left Jacobian J(phi) = R_r(-phi).
  const Eigen::Matrix3d jl = RightJacobianSO3(-phi);
  return {ExpSO3(phi), jl * rho};
}

Vector6d LogSE3(const Rigid3d& pose) {
  const Eigen::Vector3d phi = LogSO3(pose.rotation);
  const Eigen::Matrix3d jl = RightJacobianSO3(-phi);
  Vector6d xi;
  xi.head<3>() = jl.inverse() * pose.translation;
  xi.tail<3>() = phi;
  return xi;
}

Eigen::Matrix4d Sim3d::ToMatrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = scale * rotation.toRotationMatrix();
  m.topRightCorner<3, 1>() = translation;
  return m;
}

Rigid3d InterpolatePose(const Rigid3d& a, const Rigid3d& b, double alpha) {
  return {a.rotation.slerp(alpha, b.rotation).normalized(),
          (1.0 - alpha) * a.translation + alpha * b.translation};
}

}  // namespace optinav
