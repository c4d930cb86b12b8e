#include "optinav/util/statistics.h"

#include <cmath>

#include <gtest/gtest.h>

#include "optinav/util/error.h"

namespace optinav {
namespace {

TEST(Quantile, InterpolatesLikeNumpy) {
  // numpy.quantile([4, 1, 3, 2], [0, 0.25, 0.5, 0.95, 1]) = 1, 1.75, 2.5, 3.85, 4
  const std::vector<double> v = {4, 1, 3, 2};
  EXPECT_DOUBLE_EQ(Quantile(v, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(Quantile(v, 0.25), 1.75);
  EXPECT_DOUBLE_EQ(Quantile(v, 0.5), 2.5);
  EXPECT_NEAR(Quantile(v, 0.95), 3.85, 1e-12);
  EXPECT_DOUBLE_EQ(Quantile(v, 1.0), 4.0);
  EXPECT_DOUBLE_EQ(Median({5, 1, 3}), 3.0);
  EXPECT_TRUE(std::isnan(Quantile({}, 0.5)));
}

TEST(ComputeStatistics, MatchesNumpyDefinitions) {
  // numpy: mean 2.5, median 2.5, std (population) 1.118033988749895, rmse sqrt(7.5).
  const Statistics s = ComputeStatistics({4, 1, 3, 2});
  EXPECT_EQ(s.n, 4u);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_NEAR(s.std, 1.118033988749895, 1e-15);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(s.sse, 30.0);
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 4.0);
  EXPECT_NEAR(s.p95, 3.85, 1e-12);
}

TEST(ComputeStatistics, EmptyInputIsAnError) {
  try {
    ComputeStatistics({});
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("empty input"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace optinav
