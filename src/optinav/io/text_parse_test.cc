#include "optinav/io/text_parse.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "optinav/util/testing.h"

namespace optinav::io {
namespace {

TEST(ParseSecondsToNs, ExactDecimalAndScientific) {
  const ErrorContext ctx;
  EXPECT_EQ(ParseSecondsToNs("1305031102.175304", ctx), 1305031102175304000);
  EXPECT_EQ(ParseSecondsToNs("1.403715529112143517e+09", ctx), 1403715529112143517);
  EXPECT_EQ(ParseSecondsToNs("0.000000e+00", ctx), 0);
  EXPECT_EQ(ParseSecondsToNs("1.037359e-01", ctx), 103735900);
  EXPECT_EQ(ParseSecondsToNs("-2.5", ctx), -2500000000);
  EXPECT_EQ(ParseSecondsToNs("7", ctx), 7000000000);
  EXPECT_EQ(ParseSecondsToNs(".5", ctx), 500000000);
  EXPECT_EQ(ParseSecondsToNs("0.0000000015", ctx), 2);  // rounds half away from zero
  EXPECT_EQ(ParseSecondsToNs("1e-12", ctx), 0);
}

TEST(ParseSecondsToNs, Rejects) {
  const ErrorContext ctx{.file = "f", .line = 3, .field = "t"};
  for (const char* bad : {"", "abc", "1.2.3", "1e", "nan", "inf", "1x", "1e30"}) {
    EXPECT_THROW(ParseSecondsToNs(bad, ctx), Error) << bad;
  }
  try {
    ParseSecondsToNs("x", ctx);
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "f:3: field 't': not a timestamp: 'x'");
  }
}

TEST(ParseNumbers, StrictDoublesAndInts) {
  const ErrorContext ctx;
  EXPECT_EQ(ParseFiniteDouble("-1.5e3", ctx), -1500.0);
  EXPECT_EQ(ParseFiniteDouble("+2", ctx), 2.0);
  EXPECT_THROW(ParseFiniteDouble("nan", ctx), Error);
  EXPECT_THROW(ParseFiniteDouble("inf", ctx), Error);
  EXPECT_THROW(ParseFiniteDouble("1.0abc", ctx), Error);
  EXPECT_THROW(ParseFiniteDouble("", ctx), Error);
  EXPECT_THROW(ParseFiniteDouble("1e999", ctx), Error);
  EXPECT_EQ(ParseInt64("1403715273262142976", ctx), 1403715273262142976);
  EXPECT_THROW(ParseInt64("14.5", ctx), Error);
}

TEST(FormatNs, RoundTrips) {
  EXPECT_EQ(FormatNsAsSeconds(1305031102175304000), "1305031102.175304000");
  EXPECT_EQ(FormatNsAsSeconds(-1), "-0.000000001");
  EXPECT_EQ(ParseSecondsToNs(FormatNsAsSeconds(1403715529112143517), {}), 1403715529112143517);
}

TEST(SplitFields, WhitespaceAndComma) {
  std::vector<std::string_view> f;
  SplitFields("  1 \t2   3 ", ' ', &f);
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[2], "3");
  SplitFields("1, 2,,3", ',', &f);
  ASSERT_EQ(f.size(), 4u);
  EXPECT_EQ(f[1], "2");
  EXPECT_EQ(f[2], "");
}

TEST(LineCursor, CountsLinesAndHandlesCrlf) {
  LineCursor c("a\r\nb\n\nc");
  std::string_view line;
  std::vector<std::string> got;
  while (c.Next(&line)) got.emplace_back(line);
  EXPECT_EQ(got, (std::vector<std::string>{"a", "b", "", "c"}));
  EXPECT_EQ(c.line_number(), 4);
}

TEST(WriteFileAtomically, WritesAndNeverLeavesPartialFiles) {
  const auto dir = testing::MakeTempDir("atomic");
  const std::string path = (dir / "a.txt").string();
  WriteFileAtomically(path, "hello");
  EXPECT_EQ(ReadFileToString(path), "hello");
  // Renaming onto an existing non-empty directory fails: the directory stays, no .tmp is left.
  std::filesystem::create_directories(dir / "d" / "x");
  EXPECT_THROW(WriteFileAtomically((dir / "d").string(), "data"), Error);
  EXPECT_TRUE(std::filesystem::is_directory(dir / "d" / "x"));
  EXPECT_FALSE(std::filesystem::exists(dir / "d.tmp"));
  EXPECT_THROW(ReadFileToString((dir / "missing").string()), Error);
  EXPECT_THROW(ReadFileToString(dir.string()), Error);
}

}  // namespace
}  // namespace optinav::io
