// What the loop hands a session recorder every tick: one plain-data record into a preallocated
// lock-free single-producer single-consumer ring, only while a recording is active.
#pragma once

#include <algorithm>
#include <atomic>
#include <boost/lockfree/spsc_queue.hpp>
#include <cstddef>
#include <cstdint>
#include <span>

#include "daemon/loop/engine.h"
#include "rt/loop.h"

namespace rheo::daemon {

/// One tick as the loop saw it.
struct TickRecord {
  uint32_t session = 0;  // the recording it was taken for (TickRing::Begin)
  bool paused = false;
  uint64_t tick = 0;
  int64_t deadline_ns = 0;  // CLOCK_MONOTONIC time the tick was due [ns]
  int64_t start_ns = 0;     // when it started [ns]
  double sim_time = 0.0;    // [s]
  ToolTelemetry tool;
  uint32_t applied_count = 0;  // commands the loop applied at the start of the tick
  std::array<AppliedCommand, kMaxCommandsPerTick> applied{};
};

/// The loop (producer) pushes a TickRecord per tick while a session is active; the recorder
/// thread (consumer) pops them. The storage is a fixed array inside the object (8192 records of
/// 936 bytes, 7.7 MB: allocate the ring once, off the loop). A push into a full ring drops
/// the record and counts it: the loop never waits for the recorder.
class TickRing {
 public:
  static constexpr size_t kCapacity = 8192;  // ticks (8.2 s at 1 kHz)

  /// Every slot is written once here, off the loop, so that its pages are resident (and locked)
  /// before the loop first pushes into them.
  TickRing() {
    for (size_t i = 0; i < kCapacity && ring_.push(scratch_); ++i) {
    }
    TickRecord r;
    while (ring_.pop(r)) {
    }
  }

  /// Loop thread: offers this tick; does nothing (one relaxed load) unless a session is active.
  /// Never allocates, locks or waits.
  void Offer(const rt::TickInfo& info, double sim_time, bool paused, const ToolTelemetry& tool,
             std::span<const AppliedCommand> applied = {}) {
    const uint32_t session = session_.load(std::memory_order_acquire);
    if (session == 0) return;
    TickRecord& r = scratch_;
    r.session = session;
    r.paused = paused;
    r.tick = info.tick;
    r.deadline_ns = info.deadline_ns;
    r.start_ns = info.start_ns;
    r.sim_time = sim_time;
    r.tool = tool;
    r.applied_count = static_cast<uint32_t>(std::min(applied.size(), r.applied.size()));
    std::copy_n(applied.begin(), r.applied_count, r.applied.begin());
    if (!ring_.push(r)) dropped_.fetch_add(1, std::memory_order_relaxed);
    last_offered_.store(info.tick, std::memory_order_release);
  }

  /// Recorder thread: starts a session and returns its number (records of earlier sessions
  /// still in the ring carry another and are to be skipped).
  uint32_t Begin() {
    uint32_t s = next_session_++;
    if (s == 0) s = next_session_++;  // 0 means none
    session_.store(s, std::memory_order_release);
    return s;
  }
  /// Ends the session: the loop stops offering from its next tick (the tick under way may still
  /// push one record of it).
  void End() { session_.store(0, std::memory_order_release); }
  bool active() const { return session_.load(std::memory_order_acquire) != 0; }

  /// Recorder thread: up to `max` records into `out`; returns how many.
  size_t Pop(TickRecord* out, size_t max) { return ring_.pop(out, max); }
  /// Records waiting (recorder thread).
  size_t waiting() const { return ring_.read_available(); }
  /// Records dropped because the ring was full, over every session.
  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  /// The newest tick offered to a session (recorded or dropped): where a recording whose last
  /// ticks were dropped really ends.
  uint64_t last_offered() const { return last_offered_.load(std::memory_order_acquire); }

 private:
  boost::lockfree::spsc_queue<TickRecord, boost::lockfree::capacity<kCapacity>> ring_;
  std::atomic<uint32_t> session_{0};
  std::atomic<uint64_t> dropped_{0};
  std::atomic<uint64_t> last_offered_{0};
  TickRecord scratch_;         // loop thread only
  uint32_t next_session_ = 1;  // Begin's caller only (one at a time)
};

}  // namespace rheo::daemon
