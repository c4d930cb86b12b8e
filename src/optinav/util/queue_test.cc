#include "optinav/util/queue.h"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

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

TEST(ProgressBar, SilentWhenNotATerminal) {
  // Under ctest stderr is a pipe, so the bar must not draw.
  ProgressBar bar(10, "test");
  bar.Advance(5);
  bar.Finish();
  SUCCEED();
}

}  // namespace
}  // namespace optinav
