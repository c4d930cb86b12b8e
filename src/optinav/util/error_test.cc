#include "optinav/util/error.h"

#include <stdexcept>

#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include "optinav/util/testing.h"

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

void Throw(const char* file, int64_t line, const char* field) {
  throw Error("not a number", {.file = file, .line = line, .field = field});
}

TEST(ExpectError, PassesOnlyOnMatchingContextAndMessage) {
  EXPECT_ERROR(Throw("/tmp/x/imu0/data.csv", 3, "t"),
               {.file = "imu0/data.csv", .line = 3, .field = "t"}, "number");
  EXPECT_ERROR(Throw("/tmp/x/data.csv", 3, "t"), {.file = "/tmp/x/data.csv"}, "");
  EXPECT_ERROR(Throw("", 0, ""), {.file = "", .line = 0, .field = ""}, "not a number");
  // Each wrong part is a failure: the suffix only on a path-component boundary.
  EXPECT_NONFATAL_FAILURE(EXPECT_ERROR(Throw("/tmp/xdata.csv", 3, "t"), {.file = "data.csv"}, ""),
                          "file: expected suffix 'data.csv', got '/tmp/xdata.csv'");
  EXPECT_NONFATAL_FAILURE(EXPECT_ERROR(Throw("a.csv", 3, "t"), {.file = ""}, ""), "got 'a.csv'");
  EXPECT_NONFATAL_FAILURE(EXPECT_ERROR(Throw("a.csv", 3, "t"), {.line = 4}, ""),
                          "line: expected 4, got 3");
  EXPECT_NONFATAL_FAILURE(EXPECT_ERROR(Throw("a.csv", 3, "t"), {.field = "x"}, ""),
                          "field: expected 'x', got 't'");
  EXPECT_NONFATAL_FAILURE(EXPECT_ERROR(Throw("a.csv", 3, "t"), {}, "a letter"),
                          "message: expected to contain 'a letter'");
  EXPECT_NONFATAL_FAILURE(EXPECT_ERROR((void)0, {}, ""), "threw nothing");
  EXPECT_NONFATAL_FAILURE(EXPECT_ERROR(throw std::runtime_error("x"), {}, ""),
                          "expected optinav::Error");
}

TEST(ErrorDeathTest, CheckAborts) {
  EXPECT_DEATH(OPTINAV_CHECK_MSG(1 + 1 == 3, "math"), "1 \\+ 1 == 3.*math");
}

}  // namespace
}  // namespace optinav
