#include "optinav/util/statistics.h"

#include <algorithm>
#include <cmath>

#include "optinav/util/error.h"

namespace optinav {

namespace {

// Quantile of already sorted values.
double SortedQuantile(const std::vector<double>& v, double q) {
  if (v.empty()) return std::nan("");
  const double pos = std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1);
  const size_t i = static_cast<size_t>(pos);
  const double f = pos - static_cast<double>(i);
  // Weighted as (1 - f) a + f b, not a + f (b - a): at f = 0.5 this is bit for bit the mean of
  // the two middle values, (a + b) / 2, which is how numpy's (and so evo's) median is computed.
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

}  // namespace

double Quantile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  return SortedQuantile(values, q);
}

Statistics ComputeStatistics(const std::vector<double>& values) {
  if (values.empty()) throw Error("no values to summarise (empty input)");
  Statistics s;
  s.n = values.size();
  double sum = 0;
  for (double e : values) {
    sum += e;
    s.sse += e * e;
  }
  const double n = static_cast<double>(s.n);
  s.mean = sum / n;
  s.rmse = std::sqrt(s.sse / n);
  double var = 0;
  for (double e : values) var += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(var / n);
  std::vector<double> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  s.min = sorted.front();
  s.max = sorted.back();
  s.median = SortedQuantile(sorted, 0.5);
  s.p95 = SortedQuantile(sorted, 0.95);
  return s;
}

}  // namespace optinav
