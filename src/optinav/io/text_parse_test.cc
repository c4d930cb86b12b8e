#include "optinav/io/text_parse.h"

#include <filesystem>
#include <random>

#include <fmt/format.h>
#include <gtest/gtest.h>

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
    SCOPED_TRACE(bad);
    EXPECT_ERROR(ParseSecondsToNs(bad, ctx), {.file = "f", .line = 3, .field = "t"},
                 std::string(bad) == "1e30" ? "timestamp out of range: '1e30'"
                                            : "not a timestamp: '" + std::string(bad) + "'");
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
  // The caller's context (file, line, column) is what the error reports.
  const ErrorContext at{.file = "imu.csv", .line = 7, .field = "w_x"};
  const testing::ExpectedError where{.file = "imu.csv", .line = 7, .field = "w_x"};
  EXPECT_ERROR(ParseFiniteDouble("nan", at), where, "value is not finite: 'nan'");
  EXPECT_ERROR(ParseFiniteDouble("inf", at), where, "value is not finite: 'inf'");
  EXPECT_ERROR(ParseFiniteDouble("1.0abc", at), where, "not a number: '1.0abc'");
  EXPECT_ERROR(ParseFiniteDouble("", at), where, "not a number: ''");
  EXPECT_ERROR(ParseFiniteDouble("1e999", at), where, "number out of range: '1e999'");
  EXPECT_EQ(ParseInt64("1403715273262142976", ctx), 1403715273262142976);
  EXPECT_ERROR(ParseInt64("14.5", at), where, "not an integer: '14.5'");
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
  EXPECT_ERROR(WriteFileAtomically((dir / "d").string(), "data"), {.file = (dir / "d").string()},
               "cannot rename temporary file into place");
  EXPECT_TRUE(std::filesystem::is_directory(dir / "d" / "x"));
  EXPECT_FALSE(std::filesystem::exists(dir / "d.tmp"));
  EXPECT_ERROR(ReadFileToString((dir / "missing").string()), {.file = (dir / "missing").string()},
               "cannot open file");
  EXPECT_ERROR(ReadFileToString(dir.string()), {.file = dir.string()},
               "is a directory, not a file");
}

}  // namespace
}  // namespace optinav::io

namespace optinav::io {
namespace {

TEST(ParseNumberLine, FastPathAgreesWithStrictParsers) {
  double v[8];
  int64_t t = 0;
  ASSERT_TRUE(ParseNumberLine("1305031102.175304 1.344379 -0.627206 1e-3 0.5 0.1 -0.2 0.3", ' ', 8,
                              true, false, &t, v));
  EXPECT_EQ(t, 1305031102175304000);
  EXPECT_EQ(v[1], 1.344379);
  EXPECT_EQ(v[2], -0.627206);
  EXPECT_EQ(v[3], 1e-3);
  // 17 significant digits take the exact slow path and still round-trip.
  ASSERT_TRUE(ParseNumberLine("1 0.12345678901234567 2 3 4 5 6 7", ' ', 8, true, false, &t, v));
  EXPECT_EQ(v[1], 0.12345678901234567);
  ASSERT_TRUE(
      ParseNumberLine("1403715524907143168, 0.5,1,2,3,4,5,6,7,8", ',', 8, false, true, &t, v, 8));
  EXPECT_EQ(t, 1403715524907143168);
  EXPECT_EQ(v[7], 6.0);
}

TEST(ParseNumberLine, RejectsIrregularLines) {
  double v[8];
  int64_t t = 0;
  for (const char* bad : {"1 2 3 4 5 6 7", "1 2 3 4 5 6 7 8 9", "1 2 3 nan 5 6 7 8",
                          "1 2 3 4x 5 6 7 8", ". 2 3 4 5 6 7 8", "1 2 3 inf 5 6 7 8"}) {
    EXPECT_FALSE(ParseNumberLine(bad, ' ', 8, true, false, &t, v)) << bad;
  }
  EXPECT_FALSE(ParseNumberLine("1,2,3,4,5,6,7,8,", ',', 8, false, true, &t, v));
  EXPECT_FALSE(ParseNumberLine("1.5,2,3,4,5,6,7,8", ',', 8, false, true, &t, v));
}

TEST(ParseNumberLine, MatchesFromCharsOnRandomDecimals) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1e4, 1e4);
  double v[1];
  int64_t t;
  for (int i = 0; i < 20000; ++i) {
    const std::string text = fmt::format("{:.{}f}", u(rng), static_cast<int>(rng() % 12));
    ASSERT_TRUE(ParseNumberLine(text, ' ', 1, false, false, &t, v)) << text;
    EXPECT_EQ(v[0], std::stod(text)) << text;
  }
}

}  // namespace
}  // namespace optinav::io
