#include "daemon/loop/frame_hub.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <vector>

namespace rheo::daemon {

FrameHub::FrameHub(Engine& engine) : engine_(engine) {}
FrameHub::~FrameHub() {
  Stop();
}

void FrameHub::Start() {
  thread_ = std::thread([this] { Run(); });
}

void FrameHub::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    stopping_flag_.store(true, std::memory_order_release);
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

int FrameHub::Register(double rate_hz) {
  std::lock_guard<std::mutex> lock(rates_mutex_);
  int h = next_handle_++;
  rates_.emplace_back(h, rate_hz);
  clients_.fetch_add(1, std::memory_order_relaxed);
  return h;
}

void FrameHub::Unregister(int handle) {
  std::lock_guard<std::mutex> lock(rates_mutex_);
  auto it = std::find_if(rates_.begin(), rates_.end(), [&](auto& p) { return p.first == handle; });
  if (it != rates_.end()) {
    rates_.erase(it);
    clients_.fetch_sub(1, std::memory_order_relaxed);
  }
}

double FrameHub::MaxRate() {
  std::lock_guard<std::mutex> lock(rates_mutex_);
  double r = 0;
  for (auto& [h, rate] : rates_) r = std::max(r, rate);
  return r;
}

void FrameHub::ReportStopped(const LoopFrame& f) {
  std::vector<uint32_t> now;
  for (uint32_t i = 0; i < f.object_count; ++i)
    if (f.objects[i].unstable) now.push_back(f.objects[i].instance_id);
  for (uint32_t id : now)
    if (std::find(stopped_.begin(), stopped_.end(), id) == stopped_.end())
      spdlog::warn(
          "scene object {} stopped: its state was restored {} times within {} ticks (it cannot "
          "run with these parameters at this tick); change them (SetParameters) or reset the "
          "scene",
          id, kRestoresBeforeStop, kRestoreWindowTicks);
  stopped_ = std::move(now);
}

void FrameHub::Publish(const LoopFrame& frame) {
  auto snap = std::make_shared<FrameSnapshot>();
  snap->frame = frame;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) return;
    snap->seq = ++seq_;
    latest_ = std::move(snap);
  }
  cv_.notify_all();
}

void FrameHub::Run() {
  pthread_setname_np(pthread_self(), "rheo-frames");
  auto next = std::chrono::steady_clock::now();
  while (!stopping_flag_.load(std::memory_order_acquire)) {
    double rate = MaxRate();
    // Without clients, idle at 10 Hz so a new client gets a frame quickly.
    auto period = std::chrono::nanoseconds(static_cast<int64_t>(1e9 / std::max(rate, 10.0)));
    next += period;
    auto now = std::chrono::steady_clock::now();
    if (next < now) next = now;
    std::this_thread::sleep_until(next);
    engine_.DrainRetired();
    if (!engine_.AcquireFrame() && latest_) continue;
    auto snap = std::make_shared<FrameSnapshot>();
    snap->frame = engine_.frame();
    ReportStopped(snap->frame);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      snap->seq = ++seq_;
      latest_ = std::move(snap);
    }
    cv_.notify_all();
  }
}

}  // namespace rheo::daemon
