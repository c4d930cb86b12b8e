#include "optinav/util/queue.h"

#include <chrono>
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

TEST(NumberedMailbox, ReaderGetsTheNumberedMessageWhateverTheWriterIsAt) {
  NumberedMailbox<int> box;
  // The writer is ahead: message 1 is taken although 2 and 3 were posted after it.
  box.Post(1, 10);
  box.Post(2, 20);
  box.Post(3, 30);
  EXPECT_EQ(box.WaitFor(1), 10);
  EXPECT_EQ(box.pending(), 2u);
  EXPECT_EQ(box.WaitFor(3), 30);  // 2 is dropped: messages are taken in increasing order
  EXPECT_EQ(box.pending(), 0u);
  // The writer is behind: the reader waits for it.
  std::thread writer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    box.Post(4, 40);
  });
  EXPECT_EQ(box.WaitFor(4), 40);
  writer.join();
}

TEST(NumberedMailbox, CancelWakesAWaitingReader) {
  NumberedMailbox<int> box;
  std::thread canceller([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    box.Cancel();
  });
  EXPECT_EQ(box.WaitFor(7), std::nullopt);
  canceller.join();
  box.Post(8, 80);
  EXPECT_EQ(box.WaitFor(8), std::nullopt);  // cancelled for good
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
