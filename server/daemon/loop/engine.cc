#include "daemon/loop/engine.h"

#include <chrono>
#include <thread>

#include "daemon/loop/tick_ring.h"

namespace rheo::daemon {

Engine::Engine(EngineOptions options)
    : options_(options), loop_(options.loop, [this](const rt::TickInfo& info) { Tick(info); }) {
  // Written once, not just reserved: the pages are resident (and locked) before the loop runs,
  // so a tick that first fills a large frame takes no page faults.
  for (LoopFrame& f : frames_.slots()) {
    f.positions.assign(3u * options_.max_frame_vertices, 0.0f);
    f.positions.clear();
  }
}

namespace {
// Frees what a command or a retired entry owns (outside the loop only).
template <typename Owner>
void FreeOwned(const Owner& o) {
  delete o.contact;
  delete o.object;
  delete o.multirate;
  delete o.params;
}
}  // namespace

Engine::~Engine() {
  Stop();
  for (int i = 0; i < slot_count_; ++i) {
    delete slots_[i].contact;
    delete slots_[i].object;
    delete slots_[i].multirate;
  }
  slot_count_ = 0;
  DrainRetired();
  Command c;
  while (commands_.Pop(c)) FreeOwned(c);
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

void Engine::DrainRetired() {
  Retired r;
  while (retired_.pop(r)) FreeOwned(r);
}

void Engine::Retire(Retired r) {
  // The retire queue is far larger than the command queue's per-tick budget; if it is ever full
  // the memory is leaked rather than freed on the loop thread.
  (void)retired_.push(r);
}

void Engine::MarkStable(EngineSlot& slot) {
  if (slot.unstable) unstable_objects_.fetch_sub(1, std::memory_order_relaxed);
  slot.unstable = false;
  slot.restores_in_window = 0;
}

int Engine::FindSlot(uint32_t instance_id) const {
  for (int i = 0; i < slot_count_; ++i)
    if (slots_[i].instance_id == instance_id) return i;
  return -1;
}

void Engine::Apply(const Command& c) {
  switch (c.type) {
    case Command::Type::kPause: paused_.store(true, std::memory_order_relaxed); break;
    case Command::Type::kResume: paused_.store(false, std::memory_order_relaxed); break;
    case Command::Type::kReset:
      sim_ticks_ = 0;
      for (int i = 0; i < slot_count_; ++i) {
        slots_[i].Reset();
        MarkStable(slots_[i]);
      }
      ++scene_revision_;
      break;
    case Command::Type::kStep: step_once_ = true; break;
    case Command::Type::kAddObject:
      if ((c.object != nullptr) != (c.multirate != nullptr) && slot_count_ < kMaxSceneObjects &&
          FindSlot(c.instance_id) < 0) {
        slots_[slot_count_++] = EngineSlot{c.instance_id, c.object, c.contact, c.multirate};
        ++scene_revision_;
      } else {
        // The service checked capacity; never leak.
        Retire({c.object, nullptr, c.contact, c.multirate});
      }
      break;
    case Command::Type::kRemoveObject: {
      int i = FindSlot(c.instance_id);
      if (i >= 0) {
        if (device_) device_->Forget(slots_[i]);
        MarkStable(slots_[i]);
        Retire({slots_[i].object, nullptr, slots_[i].contact, slots_[i].multirate});
        slots_[i] = slots_[slot_count_ - 1];
        --slot_count_;
        ++scene_revision_;
      }
      break;
    }
    case Command::Type::kSetParameters: {
      int i = FindSlot(c.instance_id);
      // The passes over the elements were done by SimObject::Prepare on the service's thread;
      // this copies the result in without allocating.
      if (i >= 0 && c.params && slots_[i].multirate) {
        // Taken in by the whole's thread at its next step (and freed there).
        Retire({nullptr, slots_[i].multirate->RequestParameters(c.params)});
        MarkStable(slots_[i]);
        break;
      }
      if (i >= 0 && c.params) {
        (void)slots_[i].object->SetParameters(*c.params);
        MarkStable(slots_[i]);  // new parameters get a new chance
      }
      Retire({nullptr, c.params});
      break;
    }
    case Command::Type::kDeviceCalibrate:
    case Command::Type::kDeviceClear:
    case Command::Type::kSetToolOrigin:
      if (device_) device_->Apply(c);
      break;
    case Command::Type::kNone: break;
  }
  commands_applied_.fetch_add(1, std::memory_order_relaxed);
  last_applied_seq_ = c.seq;
}

void Engine::Tick(const rt::TickInfo& info) {
  Command c;
  // Bounded work per tick: a flood of commands is spread over ticks.
  applied_count_ = 0;
  while (applied_count_ < kMaxCommandsPerTick && commands_.Pop(c)) {
    Apply(c);
    applied_[applied_count_++] = AppliedCommand{c.type, c.seq, c.instance_id};
  }

  const bool paused = paused_.load(std::memory_order_relaxed);
  if (!paused || step_once_) {
    for (int i = 0; i < slot_count_; ++i) {
      EngineSlot& slot = slots_[i];
      if (slot.unstable) continue;
      const sim::StepResult r = slot.Step(info.dt);
      if (!r.restored) continue;
      restores_.fetch_add(1, std::memory_order_relaxed);
      if (info.tick - slot.restore_window_start >= kRestoreWindowTicks) {
        slot.restore_window_start = info.tick;
        slot.restores_in_window = 0;
      }
      if (++slot.restores_in_window >= kRestoresBeforeStop) {
        slot.unstable = true;
        unstable_objects_.fetch_add(1, std::memory_order_relaxed);
      }
    }
    ++sim_ticks_;
    step_once_ = false;
  }
  const double time = static_cast<double>(sim_ticks_) * info.dt;
  sim_time_.store(time, std::memory_order_relaxed);
  object_count_.store(slot_count_, std::memory_order_relaxed);

  if (device_) {
    device_->Tick(info, std::span<EngineSlot>(slots_.data(), slot_count_), &tool_scratch_);
    tool_scratch_.tick = info.tick;
    tool_.Store(tool_scratch_);
  }
  if (tick_ring_)
    tick_ring_->Offer(info, time, paused, tool_scratch_,
                      std::span<const AppliedCommand>(applied_.data(), applied_count_));

  LoopFrame& f = frames_.back();
  f.tool = tool_scratch_;
  f.tick = info.tick;
  f.sim_time = time;
  f.paused = paused;
  f.work_ns = last_work_ns_;
  const rt::LoopStats& s = loop_.stats();
  f.ticks = s.ticks.load(std::memory_order_relaxed);
  f.late_ticks = s.late_ticks.load(std::memory_order_relaxed);
  f.scene_revision = scene_revision_;
  // Positions: capacity was reserved at start and the service never admits more vertices than
  // that, so resize() below never allocates.
  size_t total = 0;
  for (int i = 0; i < slot_count_; ++i) total += slots_[i].positions().size();
  f.positions.resize(std::min(total, f.positions.capacity() / 3) * 3);
  uint32_t first = 0;
  f.object_count = 0;
  for (int i = 0; i < slot_count_; ++i) {
    const EngineSlot& slot = slots_[i];
    auto x = slot.positions();
    if ((first + x.size()) * 3 > f.positions.size()) break;
    float* out = f.positions.data() + 3u * first;
    for (size_t k = 0; k < x.size(); ++k) {
      out[3 * k] = static_cast<float>(x[k].x());
      out[3 * k + 1] = static_cast<float>(x[k].y());
      out[3 * k + 2] = static_cast<float>(x[k].z());
    }
    f.objects[f.object_count++] = FrameObject{slot.instance_id,
                                              first,
                                              static_cast<uint32_t>(x.size()),
                                              slot.sleeping(),
                                              slot.restores(),
                                              slot.kinetic_energy(),
                                              slot.unstable,
                                              slot.multirate != nullptr};
    first += static_cast<uint32_t>(x.size());
  }
  f.published_unix_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();  // a vDSO clock read: no system call, no allocation
  frames_.Publish();
  // Acknowledge only now, so a caller that waited sees the tick's effects (time, frame) too.
  applied_seq_.store(last_applied_seq_, std::memory_order_release);
  last_work_ns_ = rt::Loop::NowNs() - info.start_ns;
}

}  // namespace rheo::daemon
