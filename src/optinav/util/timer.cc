#include "optinav/util/timer.h"

#include <algorithm>
#include <cmath>

#include "optinav/util/statistics.h"

namespace optinav {

void TimingStats::Add(const std::string& stage, double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  samples_[stage].push_back(seconds);
}

TimingSummary TimingStats::Summary(const std::string& stage) const {
  std::vector<double> v;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = samples_.find(stage);
    if (it == samples_.end()) return {};
    v = it->second;
  }
  TimingSummary s;
  s.count = v.size();
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  for (double x : v) s.total_s += x;
  s.mean_s = s.total_s / v.size();
  s.max_s = v.back();
  // The same quantiles as every other report (util/statistics.h): p95 interpolates.
  s.median_s = Quantile(v, 0.5);
  s.p95_s = Quantile(std::move(v), 0.95);
  return s;
}

std::vector<std::string> TimingStats::Stages() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::string> names;
  for (const auto& [name, unused] : samples_) names.push_back(name);
  return names;
}

}  // namespace optinav
