#include "optinav/geometry/trajectory.h"

#include <gtest/gtest.h>

namespace optinav {
namespace {

Trajectory Line() {
  Trajectory t;
  for (int i = 0; i < 5; ++i) {
    t.Add(int64_t{i} * 1'000'000'000,
          Rigid3d(ExpSO3(Eigen::Vector3d(0, 0, 0.1 * i)), Eigen::Vector3d(i, 0, 0)));
  }
  return t;
}

TEST(Trajectory, InterpolateAtTimestamp) {
  const Trajectory t = Line();
  const auto mid = t.InterpolateAt(1'500'000'000);
  ASSERT_TRUE(mid.has_value());
  EXPECT_TRUE(mid->translation.isApprox(Eigen::Vector3d(1.5, 0, 0)));
  EXPECT_NEAR(LogSO3(mid->rotation).z(), 0.15, 1e-12);
  EXPECT_NEAR(LogSO3(t.quaternion(3)).z(), 0.3, 1e-12);
  EXPECT_TRUE(t.InterpolateAt(0)->translation.isZero());
  EXPECT_TRUE(t.InterpolateAt(4'000'000'000)->translation.isApprox(Eigen::Vector3d(4, 0, 0)));
  EXPECT_FALSE(t.InterpolateAt(-1).has_value());
  EXPECT_FALSE(t.InterpolateAt(4'000'000'001).has_value());
}

TEST(Trajectory, PathLengthSubsetTransform) {
  Trajectory t = Line();
  EXPECT_DOUBLE_EQ(t.PathLength(), 4.0);
  const Trajectory s = t.Subset({4, 0, 0});
  EXPECT_EQ(s.size(), 3u);
  EXPECT_EQ(s.t_ns[0], 4'000'000'000);
  Trajectory in_place = t, repeated = t;
  in_place.KeepOnly({1, 3, 4});
  EXPECT_EQ(in_place.t_ns, (std::vector<int64_t>{1'000'000'000, 3'000'000'000, 4'000'000'000}));
  EXPECT_TRUE(in_place.positions[1].isApprox(Eigen::Vector3d(3, 0, 0)));
  repeated.KeepOnly({2, 2, 0});
  EXPECT_EQ(repeated.t_ns, (std::vector<int64_t>{2'000'000'000, 2'000'000'000, 0}));
  Sim3d sim;
  sim.scale = 2;
  sim.translation = Eigen::Vector3d(0, 1, 0);
  t.Transform(sim);
  EXPECT_TRUE(t.positions[2].isApprox(Eigen::Vector3d(4, 1, 0)));
  EXPECT_DOUBLE_EQ(t.PathLength(), 8.0);
}

}  // namespace
}  // namespace optinav
