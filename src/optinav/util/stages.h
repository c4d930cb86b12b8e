// Three pipeline modules in their own threads: source -> stage -> sink, joined by bounded
// ThreadSafeQueues, with error propagation: the first exception thrown in any thread closes both
// queues (every thread then stops at its next queue operation), all threads are joined and the
// exception is rethrown to the caller. No deadlock at the end of the stream (the source returns:
// the queues close in order and drain) or on an error.
#pragma once

#include <atomic>
#include <cstddef>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "optinav/util/queue.h"

namespace optinav {

// `source(emit)` produces items in order through `emit`, which returns false once the pipeline
// stopped (the source should then return). `stage` maps each item, `sink` consumes the results
// in order. `capacity`: of each queue (> 0). `on_fail`, when set, runs once on the first error
// (in the failing thread), e.g. to wake a stage that waits on something other than the queues.
template <typename A, typename B>
void RunThreeStages(size_t capacity,
                    const std::function<void(const std::function<bool(A)>& emit)>& source,
                    const std::function<B(A)>& stage, const std::function<void(B)>& sink,
                    const std::function<void()>& on_fail = nullptr) {
  ThreadSafeQueue<A> first(capacity);
  ThreadSafeQueue<B> second(capacity);
  std::mutex error_mutex;
  std::exception_ptr error;
  std::atomic<bool> failed = false;
  auto fail = [&](std::exception_ptr e) {
    bool first_error = false;
    {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!error) error = e, first_error = true;
    }
    failed = true;
    first.Close();
    second.Close();
    if (first_error && on_fail) on_fail();
  };
  auto run_source = [&] {
    try {
      source([&](A item) { return !failed && first.Push(std::move(item)); });
    } catch (...) {
      fail(std::current_exception());
    }
    first.Close();
  };
  auto run_stage = [&] {
    try {
      while (std::optional<A> item = first.Pop()) {
        if (failed) break;
        if (!second.Push(stage(std::move(*item)))) break;
      }
    } catch (...) {
      fail(std::current_exception());
    }
    second.Close();
    first.Close();  // the source stops when this stage stopped early
  };
  auto run_sink = [&] {
    try {
      while (std::optional<B> item = second.Pop()) {
        if (failed) break;
        sink(std::move(*item));
      }
    } catch (...) {
      fail(std::current_exception());
    }
    second.Close();
    first.Close();
  };
  std::vector<std::thread> threads;
  try {
    threads.emplace_back(run_source);
    threads.emplace_back(run_stage);
    threads.emplace_back(run_sink);
  } catch (...) {  // a thread could not be started: stop the others
    fail(std::current_exception());
  }
  for (std::thread& t : threads) t.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace optinav
