#include "optinav/util/timer.h"

#include <algorithm>
#include <cmath>

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
  s.median_s = v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  // Nearest-rank percentile.
  const size_t rank = static_cast<size_t>(std::ceil(0.95 * v.size()));
  s.p95_s = v[std::max<size_t>(rank, 1) - 1];
  s.max_s = v.back();
  return s;
}

std::vector<std::string> TimingStats::Stages() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::string> names;
  for (const auto& [name, unused] : samples_) names.push_back(name);
  return names;
}

}  // namespace optinav
