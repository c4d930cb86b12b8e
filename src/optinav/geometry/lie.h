// Rotations and rigid transforms on Eigen.
//
// Conventions (docs/ARCHITECTURE.md): a transform `target_from_source` maps points expressed in
// `source` into `target`: p_in_target = target_from_source * p_in_source. Rotations are unit
// Eigen::Quaterniond internally; files use the order their format defines, converted here.
// Tangent vectors are ordered (rho, phi): translation part first, rotation part second.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace optinav {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// Skew-symmetric matrix [v]x with [v]x w = v x w.
Eigen::Matrix3d Hat(const Eigen::Vector3d& v);

// SO(3) exponential of a rotation vector (axis * angle), exact also near zero.
Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& rotation_vector);
// SO(3) logarithm: rotation vector with angle in [0, pi].
Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q);
// Rotation angle in [0, pi] of a (not necessarily normalised) quaternion.
double RotationAngle(const Eigen::Quaterniond& q);
// Angle in [0, pi] between two directions (not necessarily unit), accurate near 0 and pi.
double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b);
// Right Jacobian of SO(3) (Forster et al. 2017, eq. 8).
Eigen::Matrix3d RightJacobianSO3(const Eigen::Vector3d& rotation_vector);

// Quaternion construction from and to the two storage orders used by file formats.
// Normalises; the caller validates that the norm is not (close to) zero.
Eigen::Quaterniond QuaternionFromWxyz(double w, double x, double y, double z);
Eigen::Quaterniond QuaternionFromXyzw(double x, double y, double z, double w);
Eigen::Vector4d QuaternionToWxyz(const Eigen::Quaterniond& q);
Eigen::Vector4d QuaternionToXyzw(const Eigen::Quaterniond& q);
// Nearest rotation (by SVD) to a 3x3 matrix that is only approximately orthonormal.
Eigen::Quaterniond QuaternionFromMatrix(const Eigen::Matrix3d& m);

// A rigid transform target_from_source: p_target = rotation * p_source + translation.
struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : rotation(q), translation(t) {}

  static Rigid3d Identity() { return {}; }
  // From a 4x4 or the top 3x4 of a homogeneous matrix; the rotation block is re-orthonormalised.
  static Rigid3d FromMatrix(const Eigen::Matrix<double, 3, 4>& m);
  Eigen::Matrix4d ToMatrix() const;
  Eigen::Matrix<double, 3, 4> ToMatrix3x4() const;

  Rigid3d Inverse() const;
  Rigid3d operator*(const Rigid3d& other) const;
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return rotation * p + translation; }
};

// SE(3) exponential and logarithm with tangent (rho, phi).
Rigid3d ExpSE3(const Vector6d& xi);
Vector6d LogSE3(const Rigid3d& pose);

// A similarity target_from_source: p_target = scale * rotation * p_source + translation.
struct Sim3d {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const {
    return scale * (rotation * p) + translation;
  }
  // Applies to a pose world_from_body: scales its position, rotates and translates it.
  Rigid3d operator*(const Rigid3d& pose) const {
    return {(rotation * pose.rotation).normalized(), (*this) * pose.translation};
  }
  Eigen::Matrix4d ToMatrix() const;
};

// Interpolates between two poses: slerp on rotation, linear on translation; alpha in [0, 1].
Rigid3d InterpolatePose(const Rigid3d& a, const Rigid3d& b, double alpha);

}  // namespace optinav
