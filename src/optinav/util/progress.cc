#include "optinav/util/progress.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include <unistd.h>

namespace optinav {

ProgressBar::ProgressBar(size_t total, std::string label)
    : total_(total),
      label_(std::move(label)),
      enabled_(isatty(STDERR_FILENO) == 1 && std::getenv("OPTINAV_NO_PROGRESS") == nullptr) {}

ProgressBar::~ProgressBar() { Finish(); }

void ProgressBar::Advance(size_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  done_ = std::min(total_, done_ + n);
  if (!enabled_) return;
  const double now = timer_.ElapsedSeconds();
  if (done_ == total_ || now - last_draw_s_ >= 0.1) {
    last_draw_s_ = now;
    Draw();
  }
}

void ProgressBar::Finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (!enabled_) return;
  Draw();
  std::fputc('\n', stderr);
}

void ProgressBar::Draw() {
  constexpr int kWidth = 30;
  const double frac = total_ ? static_cast<double>(done_) / total_ : 1.0;
  const int filled = static_cast<int>(frac * kWidth);
  const double elapsed = timer_.ElapsedSeconds();
  const double eta = frac > 0 ? elapsed * (1.0 - frac) / frac : 0.0;
  std::fprintf(stderr, "\r%s [%.*s%*s] %zu/%zu %5.1f%% %.1fs eta %.1fs", label_.c_str(), filled,
               "##############################", kWidth - filled, "", done_, total_, 100.0 * frac,
               elapsed, eta);
  std::fflush(stderr);
}

}  // namespace optinav
