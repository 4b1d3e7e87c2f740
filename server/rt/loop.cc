#include "rt/loop.h"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <time.h>

#include <cerrno>
#include <cstring>

#include "common/clock.h"

namespace rheo::rt {
namespace {

constexpr int64_t kNsPerS = 1'000'000'000;

timespec ToTimespec(int64_t ns) {
  timespec ts;
  ts.tv_sec = ns / kNsPerS;
  ts.tv_nsec = ns % kNsPerS;
  return ts;
}

}  // namespace

int64_t Loop::NowNs() {
  return MonotonicNowNs();
}

Loop::Loop(LoopOptions options, TickFn tick) : options_(options), tick_(std::move(tick)) {}

Loop::~Loop() {
  Stop();
}

void Loop::Start() {
  if (running_.load()) return;
  stop_.store(false);
  ready_.store(false);
  running_.store(true, std::memory_order_release);
  thread_ = std::thread([this] { Run(); });
  while (!ready_.load(std::memory_order_acquire)) std::this_thread::yield();
}

void Loop::Stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  running_.store(false, std::memory_order_release);
}

namespace {
// Touches the first 256 KiB of the calling thread's stack, so that the ticks' calls never fault
// a stack page in (with MCL_ONFAULT a page is locked once touched).
__attribute__((noinline)) void PrefaultStack() {
  volatile char page[256 * 1024];
  for (size_t i = 0; i < sizeof page; i += 4096) page[i] = 0;
}
}  // namespace

void Loop::SetUpThread() {
  pthread_setname_np(pthread_self(), "rheo-loop");
  // A normal-priority thread's timed sleeps may end up to 50 us late by default (timer slack);
  // 1 ns asks for the deadline itself. SCHED_FIFO threads have no slack anyway. On the
  // development machine the median wake latency of a normal-priority 1 kHz sleep went from 139
  // to 68 us, the machine's own timer latency.
  if (prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL) != 0) env_.notes += "timer slack unchanged; ";
  if (options_.lock_memory) {
    // MCL_ONFAULT: pages are locked as they are touched, not all at once. With MCL_FUTURE alone
    // every later mapping is locked whole, and each new thread's 8 MiB stack became resident:
    // 16 gRPC streams added 131 MB to rheod's RSS within a second. What the loop uses is
    // allocated and written before it starts (the engine's frames, the tick ring), so it is
    // resident, and locked, from the start.
    if (mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT) == 0 ||
        (errno == EINVAL && mlockall(MCL_CURRENT | MCL_FUTURE) == 0)) {
      env_.memory_locked = true;
      PrefaultStack();
    } else {
      env_.notes += std::string("mlockall refused (") + std::strerror(errno) +
                    "): pages may fault during ticks; ";
    }
  }
  if (options_.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(options_.cpu, &set);
    if (pthread_setaffinity_np(pthread_self(), sizeof(set), &set) == 0) {
      env_.pinned = true;
    } else {
      env_.notes += "CPU pinning refused; ";
    }
  }
  if (options_.realtime_priority) {
    sched_param sp{};
    sp.sched_priority = options_.priority;
    int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    if (rc == 0) {
      env_.realtime = true;
    } else {
      env_.notes += std::string("SCHED_FIFO refused (") + std::strerror(rc) +
                    "; grant CAP_SYS_NICE or an rtprio limit): the loop runs at normal priority; ";
    }
  }
}

void Loop::Run() {
  SetUpThread();
  ready_.store(true, std::memory_order_release);

  const int64_t period = options_.period_ns;
  const double dt = static_cast<double>(period) / kNsPerS;
  int64_t deadline = NowNs() + period;
  int64_t prev_start = 0;
  uint64_t tick = 0;
  while (!stop_.load(std::memory_order_acquire)) {
    timespec ts = ToTimespec(deadline);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    const int64_t start = NowNs();
    if (prev_start != 0) stats_.period.Add(start - prev_start);
    const int64_t latency = start - deadline;
    stats_.wake_latency.Add(latency);
    if (latency >= options_.late_threshold_ns)
      stats_.late_ticks.fetch_add(1, std::memory_order_relaxed);
    prev_start = start;
    last_tick_ns_.store(start, std::memory_order_relaxed);

    tick_(TickInfo{tick, deadline, start, dt});

    const int64_t end = NowNs();
    stats_.work.Add(end - start);
    stats_.ticks.fetch_add(1, std::memory_order_relaxed);
    ++tick;
    deadline += period;
    if (end > deadline) {
      stats_.overruns.fetch_add(1, std::memory_order_relaxed);
      // Drop whole periods we cannot catch up on, rather than replaying them back to back.
      int64_t behind = (end - deadline) / period;
      if (behind > 0) {
        stats_.skipped_ticks.fetch_add(static_cast<uint64_t>(behind), std::memory_order_relaxed);
        deadline += behind * period;
      }
    }
  }
}

}  // namespace rheo::rt
