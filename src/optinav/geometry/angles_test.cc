#include "optinav/geometry/angles.h"

#include <gtest/gtest.h>

namespace optinav {
namespace {

TEST(Angles, Wrap) {
  EXPECT_DOUBLE_EQ(WrapDeg360(370), 10);
  EXPECT_DOUBLE_EQ(WrapDeg360(-10), 350);
  EXPECT_DOUBLE_EQ(WrapDeg360(-720), 0);
  EXPECT_LT(WrapDeg360(-1e-17), 360.0);
  EXPECT_DOUBLE_EQ(WrapDeg180(190), -170);
  EXPECT_DOUBLE_EQ(WrapDeg180(-190), 170);
  EXPECT_DOUBLE_EQ(WrapDeg180(180), -180);
  EXPECT_DOUBLE_EQ(WrapDeg180(-5), -5);
}

TEST(Angles, WrapRadians) {
  EXPECT_NEAR(WrapRadPi(1.5 * M_PI), -0.5 * M_PI, 1e-15);
  EXPECT_NEAR(WrapRadPi(-1.5 * M_PI), 0.5 * M_PI, 1e-15);
  EXPECT_NEAR(WrapRadPi(0.1 + 6 * M_PI), 0.1, 1e-14);
  EXPECT_DOUBLE_EQ(WrapRadPi(-0.3), -0.3);
  EXPECT_NEAR(std::abs(WrapRadPi(M_PI)), M_PI, 1e-15);  // either end of [-pi, pi]
}

}  // namespace
}  // namespace optinav
