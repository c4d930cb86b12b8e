// A bounded, closable, thread-safe FIFO queue joining pipeline modules, and a numbered mailbox
// for feedback between them.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>

namespace optinav {

template <typename T>
class ThreadSafeQueue {
 public:
  // capacity 0 means unbounded.
  explicit ThreadSafeQueue(size_t capacity = 0) : capacity_(capacity) {}

  // Blocks while full. Returns false (dropping the item) once the queue is closed.
  bool Push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    not_full_.wait(lock, [&] { return closed_ || capacity_ == 0 || items_.size() < capacity_; });
    if (closed_) return false;
    items_.push_back(std::move(item));
    not_empty_.notify_one();
    return true;
  }

  // Blocks until an item arrives; returns nullopt when closed and drained.
  std::optional<T> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    return PopLocked();
  }

  // Never blocks.
  std::optional<T> TryPop() {
    std::lock_guard<std::mutex> lock(mutex_);
    return PopLocked();
  }

  // Wakes all waiters; Pop keeps returning remaining items, then nullopt.
  void Close() {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
    not_empty_.notify_all();
    not_full_.notify_all();
  }

  size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return items_.size();
  }
  bool closed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return closed_;
  }

 private:
  std::optional<T> PopLocked() {
    if (items_.empty()) return std::nullopt;
    T item = std::move(items_.front());
    items_.pop_front();
    not_full_.notify_one();
    return item;
  }

  size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable not_empty_, not_full_;
  std::deque<T> items_;
  bool closed_ = false;
};

// Numbered messages from one thread to another, taken by number: the reader asks for message n
// and waits until the writer has posted it, so what the reader sees depends only on the message
// numbers, never on how far the writer has got (a pipeline's feedback then gives the same result
// whether its threads run in step or not). Messages are taken once, in increasing order; older
// ones are dropped when a newer one is taken. Cancel() wakes every waiter (nullopt) for good.
template <typename T>
class NumberedMailbox {
 public:
  void Post(uint64_t number, T message) {
    std::lock_guard<std::mutex> lock(mutex_);
    messages_[number] = std::move(message);
    posted_.notify_all();
  }
  // Blocks until message `number` is posted; nullopt once cancelled.
  std::optional<T> WaitFor(uint64_t number) {
    std::unique_lock<std::mutex> lock(mutex_);
    posted_.wait(lock, [&] { return cancelled_ || messages_.count(number) > 0; });
    if (cancelled_) return std::nullopt;
    T message = std::move(messages_.at(number));
    messages_.erase(messages_.begin(), messages_.upper_bound(number));
    return message;
  }
  void Cancel() {
    std::lock_guard<std::mutex> lock(mutex_);
    cancelled_ = true;
    posted_.notify_all();
  }
  size_t pending() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return messages_.size();
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable posted_;
  std::map<uint64_t, T> messages_;
  bool cancelled_ = false;
};

}  // namespace optinav
