#include "daemon/engine.h"

#include <thread>

namespace rheo::daemon {

Engine::Engine(EngineOptions options)
    : loop_(options.loop, [this](const rt::TickInfo& info) { Tick(info); }) {}

Engine::~Engine() {
  Stop();
}

void Engine::Start() {
  loop_.Start();
}
void Engine::Stop() {
  loop_.Stop();
}

uint64_t Engine::Submit(Command command) {
  command.seq = next_seq_.fetch_add(1, std::memory_order_relaxed);
  if (!commands_.Push(command)) {
    commands_rejected_.fetch_add(1, std::memory_order_relaxed);
    return 0;
  }
  return command.seq;
}

bool Engine::WaitApplied(uint64_t seq, int64_t timeout_ns) const {
  const int64_t end = rt::Loop::NowNs() + timeout_ns;
  while (applied_seq() < seq) {
    if (!loop_.running() || rt::Loop::NowNs() > end) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  return true;
}

void Engine::Apply(const Command& c) {
  switch (c.type) {
    case Command::Type::kPause: paused_.store(true, std::memory_order_relaxed); break;
    case Command::Type::kResume: paused_.store(false, std::memory_order_relaxed); break;
    case Command::Type::kReset:
      sim_ticks_ = 0;
      ++scene_revision_;
      break;
    case Command::Type::kStep: step_once_ = true; break;
    case Command::Type::kNone: break;
  }
  commands_applied_.fetch_add(1, std::memory_order_relaxed);
  applied_seq_.store(c.seq, std::memory_order_release);
}

void Engine::Tick(const rt::TickInfo& info) {
  Command c;
  // Bounded work per tick: a flood of commands is spread over ticks.
  for (int i = 0; i < 16 && commands_.Pop(c); ++i) Apply(c);

  const bool paused = paused_.load(std::memory_order_relaxed);
  if (!paused || step_once_) {
    ++sim_ticks_;
    step_once_ = false;
  }
  const double time = static_cast<double>(sim_ticks_) * info.dt;
  sim_time_.store(time, std::memory_order_relaxed);

  LoopFrame& f = frames_.back();
  f.tick = info.tick;
  f.sim_time = time;
  f.paused = paused;
  f.work_ns = last_work_ns_;
  const rt::LoopStats& s = loop_.stats();
  f.ticks = s.ticks.load(std::memory_order_relaxed);
  f.late_ticks = s.late_ticks.load(std::memory_order_relaxed);
  f.scene_revision = scene_revision_;
  frames_.Publish();
  last_work_ns_ = rt::Loop::NowNs() - info.start_ns;
}

}  // namespace rheo::daemon
