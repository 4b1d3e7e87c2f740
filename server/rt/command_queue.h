// Bounded queue into the real-time loop: many producers (service threads), one consumer (loop).
#pragma once

#include <boost/lockfree/spsc_queue.hpp>
#include <cstddef>
#include <mutex>

namespace rheo::rt {

/// The consumer side is wait-free and never locks; producers serialise among themselves on a
/// mutex that the consumer never touches. Push fails (returns false) when the queue is full, so a
/// flood of requests is refused rather than growing memory or stalling the loop.
template <typename T, size_t Capacity>
class CommandQueue {
 public:
  bool Push(const T& value) {
    std::lock_guard<std::mutex> lock(producer_mutex_);
    return queue_.push(value);
  }
  /// Loop side: takes one command if any.
  bool Pop(T& out) { return queue_.pop(out); }
  size_t capacity() const { return Capacity; }

 private:
  std::mutex producer_mutex_;
  boost::lockfree::spsc_queue<T, boost::lockfree::capacity<Capacity>> queue_;
};

}  // namespace rheo::rt
