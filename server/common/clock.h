// The monotonic clock every timed part of the server reads (loop, drivers, watchdog, emulator).
#pragma once

#include <time.h>

#include <cstdint>

namespace rheo {

/// CLOCK_MONOTONIC now [ns]: the clock of the real-time loop's deadlines (clock_nanosleep with
/// TIMER_ABSTIME on CLOCK_MONOTONIC) and of the drivers' timeouts and watchdog.
inline int64_t MonotonicNowNs() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace rheo
