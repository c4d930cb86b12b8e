#include "optinav/util/stages.h"

#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "optinav/util/error.h"

namespace optinav {
namespace {

constexpr int kItems = 2000;

// Runs kItems items through the three threads; `throw_at(where, i)` decides where it throws.
std::vector<int> RunNumbers(const std::function<bool(const std::string&, int)>& throw_at) {
  std::vector<int> got;
  RunThreeStages<int, int>(
      2,  // small queues: the other threads are blocked on them when one throws
      [&](const std::function<bool(int)>& emit) {
        for (int i = 0; i < kItems; ++i) {
          if (throw_at("source", i)) throw Error("source failed at " + std::to_string(i));
          if (!emit(i)) return;
        }
      },
      [&](int i) {
        if (throw_at("stage", i)) throw Error("stage failed at " + std::to_string(i));
        return 2 * i;
      },
      [&](int i) {
        if (throw_at("sink", i / 2))
          throw std::runtime_error("sink failed at " + std::to_string(i));
        got.push_back(i);
      });
  return got;
}

TEST(RunThreeStages, KeepsOrderAndEveryItem) {
  const std::vector<int> got = RunNumbers([](const std::string&, int) { return false; });
  ASSERT_EQ(got.size(), static_cast<size_t>(kItems));
  for (int i = 0; i < kItems; ++i) EXPECT_EQ(got[i], 2 * i);
}

TEST(RunThreeStages, EmptySource) {
  std::vector<int> got;
  RunThreeStages<int, int>(
      4, [](const std::function<bool(int)>&) {}, [](int i) { return i; },
      [&](int i) { got.push_back(i); });
  EXPECT_TRUE(got.empty());
}

TEST(RunThreeStages, AnExceptionInAnyThreadReachesTheCallerAndAllThreadsStop) {
  for (const std::string where : {"source", "stage", "sink"}) {
    for (const int at : {0, 1, 50, kItems - 1}) {
      try {
        RunNumbers([&](const std::string& w, int i) { return w == where && i == at; });
        FAIL() << "no exception from " << where << " at " << at;
      } catch (const std::exception& e) {
        const std::string expected =
            where + " failed at " + std::to_string(where == "sink" ? 2 * at : at);
        EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
      }
    }
  }
}

TEST(RunThreeStages, TheFirstErrorWins) {
  // The stage throws at 10; the sink would throw later (it never sees item 10).
  try {
    RunNumbers([](const std::string& w, int i) {
      return (w == "stage" && i == 10) || (w == "sink" && i == 10);
    });
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("stage failed at 10"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace optinav
