// A progress bar on stderr, drawn only when stderr is a terminal (logs and CI stay clean).
#pragma once

#include <cstddef>
#include <mutex>
#include <string>

#include "optinav/util/timer.h"

namespace optinav {

class ProgressBar {
 public:
  // total: number of work units; label: shown before the bar.
  ProgressBar(size_t total, std::string label);
  ~ProgressBar();
  // Thread-safe; redraws at most ~10 times per second.
  void Advance(size_t n = 1);
  void Finish();
  // Whether this bar draws anything (stderr is a TTY and not disabled by OPTINAV_NO_PROGRESS).
  bool enabled() const { return enabled_; }

 private:
  void Draw();
  size_t total_;
  size_t done_ = 0;
  std::string label_;
  bool enabled_;
  bool finished_ = false;
  double last_draw_s_ = -1.0;
  Timer timer_;
  std::mutex mutex_;
};

}  // namespace optinav
