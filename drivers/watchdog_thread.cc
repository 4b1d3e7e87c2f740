#include "drivers/watchdog_thread.h"

#include <pthread.h>
#include <sched.h>

#include <ctime>

namespace rheo::drivers {

WatchdogThread::WatchdogThread(Watchdog& watchdog, int realtime_priority) : watchdog_(watchdog) {
  thread_ = std::thread([this, realtime_priority] {
    if (realtime_priority > 0) {
      sched_param param{};
      param.sched_priority = realtime_priority;
      realtime_ = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
    }
    const int64_t period = watchdog_.poll_period_ns();
    int64_t next = MonotonicNowNs();
    while (!stop_.load(std::memory_order_acquire)) {
      const bool was_tripped = watchdog_.tripped();
      if (watchdog_.Check(MonotonicNowNs()) && !was_tripped) {
        stop_done_ns_.store(MonotonicNowNs(), std::memory_order_release);
      }
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
