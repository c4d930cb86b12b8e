#include "optinav/util/error.h"

#include <gtest/gtest.h>

namespace optinav {
namespace {

TEST(Error, MessageNamesFileLineAndField) {
  const Error e("not a number", {.file = "traj.txt", .line = 12, .field = "qw"});
  EXPECT_STREQ(e.what(), "traj.txt:12: field 'qw': not a number");
  EXPECT_EQ(e.context().line, 12);
  EXPECT_EQ(e.message(), "not a number");
}

TEST(Error, PartialContext) {
  EXPECT_STREQ(Error("boom").what(), "boom");
  EXPECT_STREQ(Error("boom", {.file = "a"}).what(), "a: boom");
  EXPECT_STREQ(Error("boom", {.line = 3}).what(), "line 3: boom");
  EXPECT_STREQ(Error("boom", {.field = "--x"}).what(), "field '--x': boom");
}

TEST(ErrorDeathTest, CheckAborts) {
  EXPECT_DEATH(OPTINAV_CHECK_MSG(1 + 1 == 3, "math"), "1 \\+ 1 == 3.*math");
}

}  // namespace
}  // namespace optinav
