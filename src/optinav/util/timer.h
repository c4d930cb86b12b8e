// Wall-clock timing and per-stage statistics (median, p95) for timing reports. The quantiles
// are util/statistics.h's (linear interpolation, as numpy).
#pragma once

#include <chrono>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace optinav {

class Timer {
 public:
  Timer() : start_(std::chrono::steady_clock::now()) {}
  void Restart() { start_ = std::chrono::steady_clock::now(); }
  double ElapsedSeconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  double ElapsedMs() const { return 1e3 * ElapsedSeconds(); }

 private:
  std::chrono::steady_clock::time_point start_;
};

struct TimingSummary {
  size_t count = 0;
  double total_s = 0, mean_s = 0, median_s = 0, p95_s = 0, max_s = 0;
};

// Collects samples per named stage; thread-safe.
class TimingStats {
 public:
  void Add(const std::string& stage, double seconds);
  TimingSummary Summary(const std::string& stage) const;
  std::vector<std::string> Stages() const;

 private:
  mutable std::mutex mutex_;
  std::map<std::string, std::vector<double>> samples_;
};

// Adds the lifetime of the scope to a stage of a TimingStats.
class ScopedTimer {
 public:
  ScopedTimer(TimingStats& stats, std::string stage) : stats_(stats), stage_(std::move(stage)) {}
  ~ScopedTimer() { stats_.Add(stage_, timer_.ElapsedSeconds()); }
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

 private:
  TimingStats& stats_;
  std::string stage_;
  Timer timer_;
};

}  // namespace optinav
