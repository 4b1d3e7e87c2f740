#include "drivers/watchdog_thread.h"

#include <ctime>

namespace rheo::drivers {

int64_t MonotonicNowNs() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

WatchdogThread::WatchdogThread(Watchdog& watchdog) : watchdog_(watchdog) {
  thread_ = std::thread([this] {
    const int64_t period = watchdog_.poll_period_ns();
    int64_t next = MonotonicNowNs();
    while (!stop_.load(std::memory_order_acquire)) {
      watchdog_.Check(MonotonicNowNs());
      next += period;
      timespec ts{static_cast<time_t>(next / 1'000'000'000),
                  static_cast<long>(next % 1'000'000'000)};
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    }
  });
}

WatchdogThread::~WatchdogThread() {
  Stop();
}

void WatchdogThread::Stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

}  // namespace rheo::drivers
