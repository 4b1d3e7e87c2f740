// A latest-value slot for plain data: one writer stores whole values, any number of readers load
// the newest consistent copy; neither side blocks or allocates (a sequence lock).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <thread>
#include <type_traits>

namespace rheo::daemon {

/// The payload lives in atomic words, so concurrent loads and stores are data-race free
/// (ThreadSanitizer sees only atomics); the sequence number tells a reader to retry a torn copy.
/// Store() must come from one thread at a time.
template <typename T>
class SeqSlot {
  static_assert(std::is_trivially_copyable_v<T>, "SeqSlot holds plain data only");

 public:
  SeqSlot() { Store(T{}); }

  /// Writer side (one thread at a time). Never blocks.
  void Store(const T& value) {
    std::array<uint64_t, kWords> buf{};
    std::memcpy(buf.data(), &value, sizeof(T));
    const uint64_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);
    // Release on every word keeps the odd sequence number ahead of it (no fences: TSan and
    // GCC's -Wtsan do not model them).
    for (size_t i = 0; i < kWords; ++i) words_[i].store(buf[i], std::memory_order_release);
    seq_.store(s + 2, std::memory_order_release);
  }

  /// Reader side, any thread: the newest complete value.
  T Load() const {
    std::array<uint64_t, kWords> buf{};
    for (int spins = 0;; ++spins) {
      const uint64_t s0 = seq_.load(std::memory_order_acquire);
      if ((s0 & 1) == 0) {
        // Acquire on every word keeps the second sequence load behind it.
        for (size_t i = 0; i < kWords; ++i) buf[i] = words_[i].load(std::memory_order_acquire);
        if (seq_.load(std::memory_order_relaxed) == s0) break;
      }
      if (spins > 64) std::this_thread::yield();
    }
    T out;
    std::memcpy(static_cast<void*>(&out), buf.data(), sizeof(T));
    return out;
  }

  /// How many values were stored.
  uint64_t version() const { return seq_.load(std::memory_order_acquire) / 2; }

 private:
  static constexpr size_t kWords = (sizeof(T) + 7) / 8;
  std::atomic<uint64_t> seq_{0};
  std::array<std::atomic<uint64_t>, kWords> words_{};
};

}  // namespace rheo::daemon
