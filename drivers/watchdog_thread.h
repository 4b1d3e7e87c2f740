// Runs a Watchdog's Check() on a thread of its own at the watchdog's poll period.
#pragma once

#include <atomic>
#include <thread>

#include "drivers/watchdog.h"

namespace rheo::drivers {

/// Starts polling on construction; stops (joins) on Stop() or destruction. The daemon may run
/// Watchdog::Check() from its own thread instead.
class WatchdogThread {
 public:
  explicit WatchdogThread(Watchdog& watchdog);
  ~WatchdogThread();
  WatchdogThread(const WatchdogThread&) = delete;
  WatchdogThread& operator=(const WatchdogThread&) = delete;
  void Stop();

 private:
  Watchdog& watchdog_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// CLOCK_MONOTONIC now [ns], the clock Watchdog expects.
int64_t MonotonicNowNs();

}  // namespace rheo::drivers
