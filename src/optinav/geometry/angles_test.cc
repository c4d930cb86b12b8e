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

}  // namespace
}  // namespace optinav
