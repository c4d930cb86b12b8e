#include "optinav/util/timer.h"

#include <gtest/gtest.h>

namespace optinav {
namespace {

TEST(TimingStats, MedianAndP95) {
  TimingStats stats;
  for (int i = 1; i <= 100; ++i) stats.Add("stage", i * 0.001);
  const auto s = stats.Summary("stage");
  EXPECT_EQ(s.count, 100u);
  EXPECT_NEAR(s.median_s, 0.0505, 1e-12);
  EXPECT_NEAR(s.p95_s, 0.09505, 1e-12);  // interpolated: 0.95 * 99 = 94.05 -> 95 + 0.05 ms
  EXPECT_NEAR(s.max_s, 0.1, 1e-12);
  EXPECT_NEAR(s.mean_s, 0.0505, 1e-12);
  EXPECT_EQ(stats.Stages(), std::vector<std::string>{"stage"});
  EXPECT_EQ(stats.Summary("none").count, 0u);
}

TEST(TimingStats, ScopedTimerRecords) {
  TimingStats stats;
  { ScopedTimer t(stats, "x"); }
  EXPECT_EQ(stats.Summary("x").count, 1u);
  EXPECT_GE(stats.Summary("x").total_s, 0.0);
}

}  // namespace
}  // namespace optinav
