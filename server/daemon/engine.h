// The engine: the 1 kHz loop, the queue of scene commands into it and the frames out of it.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "rt/command_queue.h"
#include "rt/loop.h"
#include "rt/triple_buffer.h"

namespace rheo::daemon {

/// A scene command, plain data so the queue never allocates. Payloads that need memory are
/// allocated by the sender and handed over by pointer; the loop hands them back for freeing
/// through the retire queue.
struct Command {
  enum class Type : uint8_t { kNone, kPause, kResume, kReset, kStep };
  Type type = Type::kNone;
  uint64_t seq = 0;  // assigned by Engine::Submit; the loop acknowledges it in applied_seq
};

/// What the loop publishes every tick. Preallocated; the loop fills it without allocating.
struct LoopFrame {
  uint64_t tick = 0;
  double sim_time = 0.0;  // [s]
  bool paused = false;
  int64_t work_ns = 0;  // time spent in the previous tick [ns]
  uint64_t late_ticks = 0;
  uint64_t ticks = 0;
  uint64_t scene_revision = 0;
};

struct EngineOptions {
  rt::LoopOptions loop;
};

/// Owns the real-time loop thread. Everything inside Tick() is allocation-free and lock-free;
/// other threads talk to it only through Submit() and the frame triple buffer.
class Engine {
 public:
  explicit Engine(EngineOptions options);
  ~Engine();

  void Start();
  void Stop();

  /// Queues a command for the next tick. Returns its sequence number, or 0 when the queue is full.
  uint64_t Submit(Command command);
  /// Sequence number of the last command the loop applied.
  uint64_t applied_seq() const { return applied_seq_.load(std::memory_order_acquire); }
  /// Waits (polling, off the loop) until the loop applied `seq` or `timeout_ns` passed.
  bool WaitApplied(uint64_t seq, int64_t timeout_ns) const;

  /// Frame reader side: only one thread (the frame hub) may call these.
  bool AcquireFrame() { return frames_.Acquire(); }
  const LoopFrame& frame() const { return frames_.front(); }

  const rt::Loop& loop() const { return loop_; }
  uint64_t commands_applied() const { return commands_applied_.load(std::memory_order_relaxed); }
  uint64_t commands_rejected() const { return commands_rejected_.load(std::memory_order_relaxed); }
  bool paused() const { return paused_.load(std::memory_order_relaxed); }
  double sim_time() const { return sim_time_.load(std::memory_order_relaxed); }

 private:
  void Tick(const rt::TickInfo& info);
  void Apply(const Command& c);

  rt::Loop loop_;
  rt::CommandQueue<Command, 1024> commands_;
  rt::TripleBuffer<LoopFrame> frames_;
  std::atomic<uint64_t> next_seq_{1};
  std::atomic<uint64_t> applied_seq_{0};
  std::atomic<uint64_t> commands_applied_{0};
  std::atomic<uint64_t> commands_rejected_{0};
  std::atomic<bool> paused_{false};
  std::atomic<double> sim_time_{0.0};

  // Loop-thread state.
  bool step_once_ = false;
  uint64_t sim_ticks_ = 0;  // ticks simulated since the last reset (time = ticks x dt)
  int64_t last_work_ns_ = 0;
  uint64_t scene_revision_ = 1;
};

}  // namespace rheo::daemon
