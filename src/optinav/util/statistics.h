// The one definition of summary statistics and quantiles in optinav. Everything that reports a
// median, a percentile or an RMSE (evaluation, timing, mission and benchmark summaries) goes
// through here, so the same numbers mean the same thing everywhere.
//
// Quantiles interpolate linearly between order statistics (numpy's default, "type 7"): the median
// of an even count is the mean of the two middle values, as numpy and evo compute it. The
// standard deviation is the population one (numpy's np.std, which evo reports).
#pragma once

#include <cstddef>
#include <vector>

namespace optinav {

struct Statistics {
  size_t n = 0;
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0, sse = 0, p95 = 0;
};

// q in [0, 1]; NaN for an empty input.
double Quantile(std::vector<double> values, double q);
inline double Median(std::vector<double> values) { return Quantile(std::move(values), 0.5); }

// Throws optinav::Error for an empty input.
Statistics ComputeStatistics(const std::vector<double>& values);

}  // namespace optinav
