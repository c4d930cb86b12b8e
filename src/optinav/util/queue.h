// A bounded, closable, thread-safe FIFO queue joining pipeline modules, and a one-slot mailbox
// for feedback between them.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
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

// A thread-safe one-slot mailbox: the writer updates the pending message in place (overwrite or
// merge into what the reader has not taken yet); the reader takes it when there is one, without
// ever waiting for the writer.
template <typename T>
class Mailbox {
 public:
  // `update(T&)` runs under the lock on the pending message (default-constructed when none).
  template <typename F>
  void Update(F&& update) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!pending_) pending_.emplace();
    update(*pending_);
  }
  void Post(T message) {
    std::lock_guard<std::mutex> lock(mutex_);
    pending_ = std::move(message);
  }
  // The pending message (then none is pending), or nullopt. Never blocks on an empty box.
  std::optional<T> Take() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::optional<T> message = std::move(pending_);
    pending_.reset();
    return message;
  }

 private:
  std::mutex mutex_;
  std::optional<T> pending_;
};

}  // namespace optinav
