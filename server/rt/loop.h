// The fixed-rate real-time loop: one thread, absolute deadlines, measured timing.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <thread>

#include "rt/histogram.h"

namespace rheo::rt {

/// What the loop passes to the tick function.
struct TickInfo {
  uint64_t tick = 0;        // index of this tick, from 0
  int64_t deadline_ns = 0;  // CLOCK_MONOTONIC time this tick was due [ns]
  int64_t start_ns = 0;     // when it actually started [ns]
  double dt = 0.0;          // nominal period [s]
};

/// Timing statistics, readable from any thread while the loop runs.
struct LoopStats {
  std::atomic<uint64_t> ticks{0};
  std::atomic<uint64_t> late_ticks{0};     // started later than the late threshold after deadline
  std::atomic<uint64_t> overruns{0};       // work ended after the next deadline
  std::atomic<uint64_t> skipped_ticks{0};  // whole periods dropped after a stall (not replayed)
  Histogram period;                        // start-to-start interval [ns]
  Histogram wake_latency;                  // start - deadline [ns]
  Histogram work;                          // time spent in the tick function [ns]
};

struct LoopOptions {
  int64_t period_ns = 1'000'000;          // 1 kHz
  int64_t late_threshold_ns = 1'000'000;  // a tick that starts a whole period late is late
  bool realtime_priority = true;          // try SCHED_FIFO
  int priority = 80;                      // SCHED_FIFO priority when permitted
  bool lock_memory = true;                // try mlockall
  int cpu = -1;                           // pin to this CPU when >= 0
};

/// What the loop could get from the OS, for a log line by the owner (the loop itself never logs).
struct LoopEnvironment {
  bool realtime = false;
  bool memory_locked = false;
  bool pinned = false;
  std::string notes;  // human-readable reasons for what was refused
};

/// Runs tick(info) every period on its own thread until Stop(). The tick function must not
/// allocate, lock contended mutexes, log or block. When a tick overruns, missed periods are
/// counted and skipped rather than replayed in a burst.
class Loop {
 public:
  using TickFn = std::function<void(const TickInfo&)>;

  Loop(LoopOptions options, TickFn tick);
  ~Loop();
  Loop(const Loop&) = delete;
  Loop& operator=(const Loop&) = delete;

  /// Starts the thread; returns once it has set itself up (so environment() is final).
  void Start();
  /// Asks the thread to end after its current tick and joins it. Safe to call twice.
  void Stop();
  bool running() const { return running_.load(std::memory_order_acquire); }

  const LoopStats& stats() const { return stats_; }
  LoopStats& mutable_stats() { return stats_; }
  const LoopEnvironment& environment() const { return env_; }
  const LoopOptions& options() const { return options_; }

  /// Time of the last completed tick start [ns, CLOCK_MONOTONIC]; used by a watchdog.
  int64_t last_tick_ns() const { return last_tick_ns_.load(std::memory_order_relaxed); }

  static int64_t NowNs();

 private:
  void Run();
  void SetUpThread();

  LoopOptions options_;
  TickFn tick_;
  LoopStats stats_;
  LoopEnvironment env_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> running_{false};
  std::atomic<bool> ready_{false};
  std::atomic<int64_t> last_tick_ns_{0};
};

}  // namespace rheo::rt
