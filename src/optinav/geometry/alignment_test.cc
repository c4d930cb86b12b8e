#include "optinav/geometry/alignment.h"

#include <random>

#include <gtest/gtest.h>

#include "optinav/util/error.h"
#include "optinav/util/testing.h"

namespace optinav {
namespace {

std::vector<Eigen::Vector3d> RandomPoints(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-10, 10);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < n; ++i) pts.emplace_back(u(rng), u(rng), u(rng));
  return pts;
}

TEST(Umeyama, RecoversKnownSim3AndSe3) {
  const auto src = RandomPoints(50, 1);
  Sim3d truth;
  truth.scale = 1.7;
  truth.rotation = ExpSO3(Eigen::Vector3d(0.4, -1.1, 2.0));
  truth.translation = Eigen::Vector3d(100, -20, 3);
  std::vector<Eigen::Vector3d> dst;
  for (const auto& p : src) dst.push_back(truth * p);
  const Sim3d est = UmeyamaAlignment(src, dst, /*with_scale=*/true);
  EXPECT_NEAR(est.scale, 1.7, 1e-10);
  EXPECT_TRUE(est.rotation.toRotationMatrix().isApprox(truth.rotation.toRotationMatrix(), 1e-10));
  EXPECT_TRUE(est.translation.isApprox(truth.translation, 1e-10));

  truth.scale = 1.0;
  dst.clear();
  for (const auto& p : src) dst.push_back(truth * p);
  const Sim3d se3 = UmeyamaAlignment(src, dst, false);
  EXPECT_EQ(se3.scale, 1.0);
  EXPECT_TRUE(se3.translation.isApprox(truth.translation, 1e-10));
}

TEST(Umeyama, NoReflectionForMirroredData) {
  auto src = RandomPoints(20, 2);
  std::vector<Eigen::Vector3d> dst;
  for (const auto& p : src) dst.emplace_back(p.x(), p.y(), -p.z());  // a mirror image
  const Sim3d est = UmeyamaAlignment(src, dst, false);
  EXPECT_NEAR(est.rotation.toRotationMatrix().determinant(), 1.0, 1e-12);
}

TEST(Umeyama, FirstNPairsOnly) {
  const auto src = RandomPoints(10, 3);
  auto dst = src;
  for (size_t i = 5; i < dst.size(); ++i) dst[i] += Eigen::Vector3d(50, 0, 0);  // corrupt tail
  const Sim3d est = UmeyamaAlignment(src, dst, false, /*max_pairs=*/5);
  EXPECT_LT(est.translation.norm(), 1e-10);
}

TEST(Umeyama, RejectsTooFewAndDegenerate) {
  const auto src = RandomPoints(2, 4);
  // In-memory points: no file or field, the message names the count or the degeneracy.
  EXPECT_ERROR(UmeyamaAlignment(src, src, false), {},
               "alignment needs at least 3 pose pairs, got 2");
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 10; ++i) line.emplace_back(i, 0, 0);
  EXPECT_ERROR(UmeyamaAlignment(line, line, false), {},
               "degenerate point configuration (covariance rank 1)");
  EXPECT_ERROR(UmeyamaAlignment(RandomPoints(4, 1), RandomPoints(5, 1), false), {},
               "same number of source and target points (4 vs 5)");
}

TEST(PositionYaw, RecoversYawAndTranslationOnly) {
  const auto src = RandomPoints(30, 5);
  Sim3d truth;
  truth.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(2.5, Eigen::Vector3d::UnitZ()));
  truth.translation = Eigen::Vector3d(3, 4, 5);
  std::vector<Eigen::Vector3d> dst;
  for (const auto& p : src) dst.push_back(truth * p);
  const Sim3d est = PositionYawAlignment(src, dst);
  EXPECT_TRUE(est.rotation.toRotationMatrix().isApprox(truth.rotation.toRotationMatrix(), 1e-10));
  EXPECT_TRUE(est.translation.isApprox(truth.translation, 1e-10));
  // A roll in the data cannot be absorbed: the yaw-only result keeps z axis fixed.
  EXPECT_NEAR((est.rotation * Eigen::Vector3d::UnitZ()).z(), 1.0, 1e-12);
}

}  // namespace
}  // namespace optinav
