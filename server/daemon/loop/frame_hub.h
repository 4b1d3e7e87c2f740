// Fans the loop's frames out to any number of streaming clients, each at its own rate.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>

#include "daemon/loop/engine.h"

namespace rheo::daemon {

/// An immutable copy of one loop frame, shared by all clients that send it.
struct FrameSnapshot {
  uint64_t seq = 0;  // hub sequence number
  LoopFrame frame;
};

/// One thread copies the newest loop frame out of the triple buffer at the fastest rate any
/// client asked for; clients wait on the hub, never on the loop. A slow client simply finds a
/// newer snapshot next time.
class FrameHub {
 public:
  explicit FrameHub(Engine& engine);
  ~FrameHub();

  void Start();
  /// Wakes every waiting client with "shutting down" and joins the thread.
  void Stop();

  /// For a source other than the loop (rheod --replay's player, which then stands in for
  /// Start()): `frame` becomes the newest snapshot, and every waiting client wakes.
  void Publish(const LoopFrame& frame);

  /// Registers a client wanting `rate_hz`; returns a handle for Unregister.
  int Register(double rate_hz);
  void Unregister(int handle);
  int clients() const { return clients_.load(std::memory_order_relaxed); }

  /// Waits until a snapshot newer than `after_seq` exists, the deadline passes, the hub stops or
  /// `cancelled()` returns true (checked every 50 ms). Returns nullptr unless a snapshot came.
  template <typename CancelFn>
  std::shared_ptr<const FrameSnapshot> WaitNewer(uint64_t after_seq,
                                                 std::chrono::steady_clock::time_point deadline,
                                                 CancelFn cancelled) {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stopping_ && (!latest_ || latest_->seq <= after_seq)) {
      if (cancelled()) return nullptr;
      auto until =
          std::min(deadline, std::chrono::steady_clock::now() + std::chrono::milliseconds(50));
      if (cv_.wait_until(lock, until) == std::cv_status::timeout &&
          std::chrono::steady_clock::now() >= deadline)
        return nullptr;
    }
    if (stopping_) return nullptr;
    return latest_;
  }
  bool stopping() const { return stopping_flag_.load(std::memory_order_acquire); }
  /// Sequence number of the newest snapshot. A client that waits for a newer one sees the
  /// scene as it is now, not as it was when the hub last copied a frame (up to 100 ms idle).
  uint64_t latest_seq() {
    std::lock_guard<std::mutex> lock(mutex_);
    return latest_ ? latest_->seq : 0;
  }

 private:
  void Run();
  double MaxRate();
  // Logs each object the loop newly stopped after repeated restores (hub thread only).
  void ReportStopped(const LoopFrame& frame);
  std::vector<uint32_t> stopped_;

  Engine& engine_;
  std::thread thread_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::shared_ptr<const FrameSnapshot> latest_;
  bool stopping_ = false;
  std::atomic<bool> stopping_flag_{false};
  std::atomic<int> clients_{0};

  std::mutex rates_mutex_;
  std::vector<std::pair<int, double>> rates_;
  int next_handle_ = 1;
  uint64_t seq_ = 0;
};

}  // namespace rheo::daemon
