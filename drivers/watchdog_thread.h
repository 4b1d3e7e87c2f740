// Runs a Watchdog's Check() on a thread of its own at the watchdog's poll period.
#pragma once

#include <atomic>
#include <thread>

#include "common/clock.h"
#include "drivers/watchdog.h"

namespace rheo::drivers {

/// Starts polling on construction; stops (joins) on Stop() or destruction. The daemon may run
/// Watchdog::Check() from its own thread instead.
class WatchdogThread {
 public:
  /// `realtime_priority` > 0: try SCHED_FIFO at that priority (above the loop's, so a runaway
  /// loop cannot starve its own watchdog); without permission the thread runs at normal priority.
  explicit WatchdogThread(Watchdog& watchdog, int realtime_priority = 90);
  ~WatchdogThread();
  WatchdogThread(const WatchdogThread&) = delete;
  WatchdogThread& operator=(const WatchdogThread&) = delete;
  void Stop();
  /// Whether SCHED_FIFO was granted (valid once the thread has started polling).
  bool realtime() const { return realtime_.load(std::memory_order_acquire); }
  /// When SafeStop() returned after the last trip (CLOCK_MONOTONIC [ns]; 0: never tripped).
  int64_t stop_done_ns() const { return stop_done_ns_.load(std::memory_order_acquire); }

 private:
  Watchdog& watchdog_;
  std::atomic<bool> realtime_{false};
  std::atomic<int64_t> stop_done_ns_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// CLOCK_MONOTONIC now [ns], the clock Watchdog expects (common/clock.h).
using rheo::MonotonicNowNs;

}  // namespace rheo::drivers
