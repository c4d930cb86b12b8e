#include "optinav/geometry/lie.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace optinav {
namespace {

TEST(SO3, AngleBetweenDirections) {
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX();
  EXPECT_NEAR(AngleBetween(x, 2 * Eigen::Vector3d::UnitY()), M_PI / 2, 1e-15);
  EXPECT_NEAR(AngleBetween(x, -3 * x), M_PI, 1e-15);
  EXPECT_NEAR(AngleBetween(x, Eigen::Vector3d(1, 1e-9, 0)), 1e-9, 1e-18);  // acos would give 0
  EXPECT_NEAR(AngleBetween(Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(0, 1, 1)), M_PI / 3, 1e-15);
}

TEST(SO3, ExpLogRoundTripIncludingSmallAndNearPi) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 1);
  for (double scale : {1e-12, 1e-6, 0.3, 2.0, M_PI - 1e-7}) {
    for (int k = 0; k < 20; ++k) {
      const Eigen::Vector3d w = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized() * scale;
      const Eigen::Vector3d back = LogSO3(ExpSO3(w));
      EXPECT_LT((back - w).norm(), 1e-9 * std::max(1.0, scale)) << "scale " << scale;
      EXPECT_NEAR(RotationAngle(ExpSO3(w)), scale, 1e-9);
    }
  }
}

TEST(SO3, ExpMatchesAngleAxis) {
  const Eigen::Vector3d w(0.1, -0.7, 0.4);
  const Eigen::Matrix3d expected = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  EXPECT_TRUE(ExpSO3(w).toRotationMatrix().isApprox(expected, 1e-12));
}

TEST(SO3, RightJacobianMatchesFiniteDifference) {
  // Exp(w + dw) ~ Exp(w) Exp(Jr(w) dw)
  const Eigen::Vector3d w(0.3, -0.2, 0.9);
  const Eigen::Matrix3d jr = RightJacobianSO3(w);
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d dw = Eigen::Vector3d::Zero();
    dw[i] = 1e-6;
    const Eigen::Vector3d numeric = LogSO3(ExpSO3(w).conjugate() * ExpSO3(w + dw)) / 1e-6;
    EXPECT_LT((numeric - jr.col(i)).norm(), 1e-5);
  }
}

TEST(Quaternion, BothStorageOrders) {
  // 90 degrees about z.
  const double c = std::sqrt(0.5);
  const Eigen::Quaterniond a = QuaternionFromWxyz(c, 0, 0, c);
  const Eigen::Quaterniond b = QuaternionFromXyzw(0, 0, c, c);
  EXPECT_TRUE(a.isApprox(b));
  EXPECT_TRUE((a * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_TRUE(QuaternionToWxyz(a).isApprox(Eigen::Vector4d(c, 0, 0, c)));
  EXPECT_TRUE(QuaternionToXyzw(a).isApprox(Eigen::Vector4d(0, 0, c, c)));
  // Unnormalised input is normalised.
  EXPECT_NEAR(QuaternionFromWxyz(2, 0, 0, 0).norm(), 1.0, 1e-15);
}

TEST(Quaternion, FromNearlyOrthonormalMatrix) {
  Eigen::Matrix3d m = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()).toRotationMatrix();
  m(0, 0) *= 1.0 + 1e-7;  // like KITTI files written with 7 digits
  const Eigen::Quaterniond q = QuaternionFromMatrix(m);
  EXPECT_NEAR(RotationAngle(q), 0.5, 1e-6);
}

TEST(SE3, CompositionInverseAndMatrix) {
  const Rigid3d a(ExpSO3(Eigen::Vector3d(0.1, 0.2, 0.3)), Eigen::Vector3d(1, 2, 3));
  const Rigid3d b(ExpSO3(Eigen::Vector3d(-0.4, 0.0, 0.2)), Eigen::Vector3d(-1, 0.5, 2));
  EXPECT_TRUE((a * b).ToMatrix().isApprox(a.ToMatrix() * b.ToMatrix(), 1e-12));
  EXPECT_TRUE((a * a.Inverse()).ToMatrix().isApprox(Eigen::Matrix4d::Identity(), 1e-12));
  const Eigen::Vector3d p(0.3, -2, 5);
  EXPECT_TRUE((a * p).isApprox((a.ToMatrix() * p.homogeneous()).head<3>(), 1e-12));
  EXPECT_TRUE(Rigid3d::FromMatrix(a.ToMatrix3x4()).ToMatrix().isApprox(a.ToMatrix(), 1e-12));
}

TEST(SE3, ExpLogRoundTrip) {
  Vector6d xi;
  xi << 0.5, -1.0, 2.0, 0.3, -0.1, 0.8;
  EXPECT_LT((LogSE3(ExpSE3(xi)) - xi).norm(), 1e-10);
  // Pure translation.
  Vector6d t = Vector6d::Zero();
  t.head<3>() << 1, 2, 3;
  EXPECT_TRUE(ExpSE3(t).translation.isApprox(Eigen::Vector3d(1, 2, 3)));
  // exp of a rotation-plus-translation twist follows a screw: check against matrix exponential
  // computed by a series.
  Eigen::Matrix4d X = Eigen::Matrix4d::Zero();
  X.topLeftCorner<3, 3>() = Hat(xi.tail<3>());
  X.topRightCorner<3, 1>() = xi.head<3>();
  Eigen::Matrix4d series = Eigen::Matrix4d::Identity(), term = Eigen::Matrix4d::Identity();
  for (int k = 1; k < 30; ++k) {
    term = term * X / k;
    series += term;
  }
  EXPECT_TRUE(ExpSE3(xi).ToMatrix().isApprox(series, 1e-10));
}

TEST(SE3, InterpolateMidpoint) {
  const Rigid3d a(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0));
  const Rigid3d b(ExpSO3(Eigen::Vector3d(0, 0, 1.0)), Eigen::Vector3d(2, 4, 6));
  const Rigid3d m = InterpolatePose(a, b, 0.5);
  EXPECT_TRUE(m.translation.isApprox(Eigen::Vector3d(1, 2, 3)));
  EXPECT_NEAR(LogSO3(m.rotation).z(), 0.5, 1e-12);
}

TEST(Sim3, AppliesScaleToPositionOnly) {
  Sim3d s;
  s.scale = 2.0;
  s.rotation = ExpSO3(Eigen::Vector3d(0, 0, M_PI / 2));
  s.translation = Eigen::Vector3d(1, 0, 0);
  const Rigid3d p(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0));
  const Rigid3d q = s * p;
  EXPECT_TRUE(q.translation.isApprox(Eigen::Vector3d(1, 2, 0)));
  EXPECT_NEAR(RotationAngle(q.rotation), M_PI / 2, 1e-12);
}

}  // namespace
}  // namespace optinav
