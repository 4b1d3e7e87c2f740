// Triple buffer: one writer publishes whole values, one reader takes the newest, neither waits.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace rheo::rt {

/// Single-producer single-consumer latest-value channel. The writer fills back(), then Publish();
/// the reader calls Acquire() and reads front(). Values are preallocated by the owner (Reset each
/// slot before use) so publishing never allocates.
template <typename T>
class TripleBuffer {
 public:
  TripleBuffer() = default;

  /// Slot the writer fills next. Only the writer thread may touch it.
  T& back() { return slots_[back_]; }

  /// Makes back() the newest value and hands the writer a free slot.
  void Publish() {
    uint32_t prev = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel);
    back_ = prev & kIndex;
  }

  /// Takes the newest published value if there is one; returns false when nothing new.
  bool Acquire() {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0) return false;
    uint32_t prev = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = prev & kIndex;
    return true;
  }

  /// Value the reader holds. Only the reader thread may touch it.
  const T& front() const { return slots_[front_]; }
  T& front_mutable() { return slots_[front_]; }

  /// All three slots, for preallocation before the threads start.
  std::array<T, 3>& slots() { return slots_; }

 private:
  static constexpr uint32_t kFresh = 4;
  static constexpr uint32_t kIndex = 3;
  std::array<T, 3> slots_{};
  uint32_t back_ = 0;                // writer-owned
  uint32_t front_ = 1;               // reader-owned
  std::atomic<uint32_t> middle_{2};  // shared: index | kFresh
};

}  // namespace rheo::rt
