// The network tool: a HapticDevice whose pose a gRPC client streams (DeviceService.ToolStream).
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>

#include "daemon/loop/seq_slot.h"
#include "drivers/haptic_device.h"

namespace rheo::daemon {

/// One pose from the client.
struct NetworkToolInput {
  uint64_t seq = 0;                               // 0: nothing received yet
  std::array<double, 3> position{};               // device frame [m]
  std::array<double, 4> orientation{1, 0, 0, 0};  // unit quaternion w, x, y, z
  uint32_t buttons = 0;
};

struct NetworkDeviceOptions {
  double max_force = 10.0;         // [N]
  double max_torque = 0.5;         // [N m]
  double max_force_rate = 2000.0;  // [N/s]
  double workspace_half = 0.2;     // [m]
  double stale_after_s = 0.2;      // no pose for this long: not connected, no force [s]
  double velocity_filter = 0.2;    // weight of the newest finite-difference velocity
};

/// Poses come in through a lock-free slot from gRPC threads (Push); the loop thread calls the
/// HapticDevice methods. The displayed wrench is the requested one after the force limit; what
/// the client does with it is its own business. Nothing here allocates after construction.
class NetworkDevice final : public drivers::HapticDevice {
 public:
  explicit NetworkDevice(const NetworkDeviceOptions& options = {});

  /// Any thread (writers serialise on a mutex the loop never takes). Returns the input's seq.
  uint64_t Push(const drivers::Pose& pose, uint32_t buttons);

  Status Open() override;
  void Close() override;
  Status Calibrate() override;
  Status Exchange(double dt) override;
  void SetWrench(const drivers::Wrench& wrench) override;
  void SafeStop() override;
  void ClearFaults() override;
  const drivers::ToolState& state() const override { return state_; }
  const drivers::DeviceStatus& status() const override { return status_; }
  const drivers::DeviceInfo& info() const override { return info_; }

  /// Loop thread: the input sequence number the last Exchange used.
  uint64_t used_seq() const { return used_seq_; }

 private:
  NetworkDeviceOptions options_;
  drivers::DeviceInfo info_;
  drivers::ToolState state_;
  drivers::DeviceStatus status_;
  SeqSlot<NetworkToolInput> input_;
  std::mutex push_mutex_;
  uint64_t next_seq_ = 1;  // guarded by push_mutex_
  std::atomic<bool> stop_requested_{false};
  // Loop thread.
  uint64_t used_seq_ = 0;
  double since_input_s_ = 0.0;  // time since the last new pose [s]
  bool have_pose_ = false;
};

}  // namespace rheo::daemon
