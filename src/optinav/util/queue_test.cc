#include "optinav/util/queue.h"

#include <cstdlib>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "optinav/util/progress.h"

namespace optinav {
namespace {

TEST(ThreadSafeQueue, ProducerConsumerKeepsOrderAndAllItems) {
  ThreadSafeQueue<int> q(4);  // small capacity forces blocking on Push
  constexpr int kN = 10000;
  std::thread producer([&] {
    for (int i = 0; i < kN; ++i) ASSERT_TRUE(q.Push(i));
    q.Close();
  });
  std::vector<int> got;
  while (auto x = q.Pop()) got.push_back(*x);
  producer.join();
  ASSERT_EQ(got.size(), static_cast<size_t>(kN));
  for (int i = 0; i < kN; ++i) EXPECT_EQ(got[i], i);
}

TEST(ThreadSafeQueue, CloseDrainsThenStops) {
  ThreadSafeQueue<int> q;
  q.Push(1);
  q.Close();
  EXPECT_FALSE(q.Push(2));
  EXPECT_EQ(q.Pop(), 1);
  EXPECT_EQ(q.Pop(), std::nullopt);
  EXPECT_EQ(q.TryPop(), std::nullopt);
}

TEST(ProgressBar, SilentWhenNotATerminalOrDisabled) {
  ::unsetenv("OPTINAV_NO_PROGRESS");
  if (!::isatty(STDERR_FILENO)) {
    // Under ctest stderr is a pipe: the bar must not draw into logs.
    EXPECT_FALSE(ProgressBar(10, "pipe").enabled());
  }
  ::setenv("OPTINAV_NO_PROGRESS", "1", 1);
  ProgressBar bar(10, "off");
  EXPECT_FALSE(bar.enabled());
  bar.Advance(20);  // beyond the total: clamped, no crash
  bar.Finish();
  ::unsetenv("OPTINAV_NO_PROGRESS");
}

}  // namespace
}  // namespace optinav
