// A stall watchdog for the haptic loop: fed every tick, it safe-stops the device when the feeds
// stop. It owns no thread; the daemon polls Check() from a thread of its own (or uses
// WatchdogThread from rheo_transport).
#pragma once

#include <atomic>
#include <cstdint>

#include "drivers/haptic_device.h"

namespace rheo::drivers {

/// Trips when no Feed() arrived for `timeout_ns`; tripping calls device.SafeStop() once.
/// With a poll period P and a SafeStop that takes S, motors reach minimum tension within
/// timeout + P + S of the last feed: 2 ms + 0.25 ms + about 0.2 ms by default (poll_period_ns()),
/// inside 5 ms. Feed() is lock-free and allocation-free (safe on the real-time thread).
class Watchdog {
 public:
  static constexpr int64_t kDefaultTimeoutNs = 2'000'000;  // 2 ms [ns]

  explicit Watchdog(HapticDevice& device, int64_t timeout_ns = kDefaultTimeoutNs)
      : device_(device), timeout_ns_(timeout_ns) {}

  /// Starts supervising; `now_ns` counts as the first feed (CLOCK_MONOTONIC [ns]).
  void Arm(int64_t now_ns) {
    last_feed_ns_.store(now_ns, std::memory_order_relaxed);
    tripped_.store(false, std::memory_order_relaxed);
    armed_.store(true, std::memory_order_release);
  }
  /// Stops supervising (an orderly pause: the owner puts the device in its safe state itself).
  void Disarm() { armed_.store(false, std::memory_order_release); }
  /// Loop thread, every tick.
  void Feed(int64_t now_ns) { last_feed_ns_.store(now_ns, std::memory_order_release); }

  /// Watchdog thread: trips (once) when armed and starved. Returns true while tripped.
  bool Check(int64_t now_ns) {
    if (!armed_.load(std::memory_order_acquire)) return false;
    if (tripped_.load(std::memory_order_relaxed)) return true;
    if (now_ns - last_feed_ns_.load(std::memory_order_acquire) <= timeout_ns_) return false;
    tripped_.store(true, std::memory_order_release);
    trips_.fetch_add(1, std::memory_order_relaxed);
    trip_ns_.store(now_ns, std::memory_order_relaxed);
    device_.SafeStop();
    return true;
  }

  bool tripped() const { return tripped_.load(std::memory_order_acquire); }
  uint64_t trips() const { return trips_.load(std::memory_order_relaxed); }
  /// The `now_ns` of the Check() that last tripped [ns].
  int64_t trip_ns() const { return trip_ns_.load(std::memory_order_relaxed); }
  /// The last feed [ns].
  int64_t last_feed_ns() const { return last_feed_ns_.load(std::memory_order_acquire); }
  int64_t timeout_ns() const { return timeout_ns_; }
  /// How often Check() should run [ns].
  int64_t poll_period_ns() const { return timeout_ns_ / 8; }

 private:
  HapticDevice& device_;
  const int64_t timeout_ns_;
  std::atomic<int64_t> last_feed_ns_{0};
  std::atomic<bool> armed_{false};
  std::atomic<bool> tripped_{false};
  std::atomic<uint64_t> trips_{0};
  std::atomic<int64_t> trip_ns_{0};
};

}  // namespace rheo::drivers
