// The haptic device in the daemon: opens the configured device (the SPIDAR-G emulator, the
// SPIDAR-G hardware or the network tool), supervises it with a watchdog, and runs the tool
// against the scene on the loop thread (TickDevice::Tick).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <span>
#include <string>

#include "common/geometry.h"
#include "common/status.h"
#include "daemon/device/network_device.h"
#include "daemon/device/tool_contact.h"
#include "daemon/loop/engine.h"
#include "drivers/haptic_device.h"
#include "drivers/spidar_emulator.h"
#include "drivers/watchdog.h"
#include "drivers/watchdog_thread.h"
#include "haptics/haptics.h"

namespace rheo::daemon {

enum class DeviceKind { kNone, kSimSpidarG, kSpidarG, kNetwork };

/// "none", "sim-spidar-g", "spidar-g", "network".
const char* DeviceKindName(DeviceKind kind);

struct DeviceLinkOptions {
  DeviceKind kind = DeviceKind::kNone;
  std::string config_path;  // SPIDAR-G frame file (drivers/config/spidar_g_*.json)
  std::string port;         // spidar-g: serial device, e.g. /dev/ttyUSB0
  /// Watchdog: no loop feed for this long safe-stops the device [ns]. Motors reach minimum
  /// tension within timeout + timeout/8 (poll) + one exchange.
  int64_t watchdog_timeout_ns = 3'000'000;
  int reply_timeout_us = 2000;  // longest wait for a board reply [us]
  bool realtime = true;         // SCHED_FIFO for the watchdog and emulator threads when permitted
  double tool_radius = 3e-3;    // tool tip radius [m]
  /// A loop that fed the watchdog again for this many ticks in a row with good exchanges clears
  /// the stop the stall caused (not an emergency stop); force comes back as a ramp.
  int recover_after_ticks = 100;
  /// sim-spidar-g, spidar-g: a serial line that goes away (EIO, a hang-up) is reopened at the
  /// port on the driver's reopener thread, never on the loop, waiting this long before the first
  /// attempt and doubling the wait after each failure up to the cap [ns].
  int64_t reconnect_backoff_ns = 100'000'000;
  int64_t reconnect_backoff_max_ns = 2'000'000'000;
  /// Lines about the line going and coming back (the reopener's thread; null: none).
  std::function<void(const std::string&)> log;
};

/// Opened before the loop starts and attached with Engine::AttachDevice(); shut down after the
/// loop stopped. The TickDevice methods run on the loop thread; the rest is thread-safe.
class DeviceLink final : public TickDevice {
 public:
  /// Opens and calibrates the device, arms the watchdog. Errors say what to fix.
  static Result<std::unique_ptr<DeviceLink>> Open(const DeviceLinkOptions& options);
  ~DeviceLink() override;

  // TickDevice (loop thread).
  void Tick(const rt::TickInfo& info, std::span<EngineSlot> slots, ToolTelemetry* out) override;
  void Apply(const Command& command) override;
  void Forget(const EngineSlot& slot) override;

  /// Builds the renderer for a new object (allocates; outside the loop). `surface` indexes into
  /// `positions` (the object's nodes, placed in the scene); `tool` is where the tool is [m];
  /// `min_node_mass` is the lightest surface node's mass [kg]. The object's nodes take the
  /// coupling spring as an explicit force, so its stiffness is also held to k h^2 / m <= 2 (half
  /// the explicit stability bound of 4) with h the loop period.
  Result<std::unique_ptr<ObjectContact>> MakeContact(
      std::span<const std::array<int32_t, 3>> surface, std::span<const Vec3> positions,
      const Vec3& tool, double min_node_mass) const;

  /// What the device side needs for an object entering the scene, all built off the loop.
  struct ObjectAttachment {
    std::unique_ptr<ObjectContact> contact;  // the object's renderer, handed to the loop
    /// The object places the device's workspace (the scene was empty): the scene position for
    /// the device frame's origin, for kSetToolOrigin before the object enters.
    bool sets_origin = false;
    Vec3 tool_origin = Vec3::Zero();
    Vec3 tool = Vec3::Zero();  // where the renderer took the tool to be [m]
  };
  /// `surface` (the mesh's outward triangles, for the renderer) and `triangles` (the same, 3
  /// indices each, as the scene registry and frames keep them) index `positions` (the object's
  /// nodes, placed in the scene) and `masses` [kg]. `first_in_scene`: the scene is empty, so
  /// the workspace is placed over this object (WorkspaceOriginOver); `now`: the latest
  /// telemetry. The renderer checks the surface (a bad index is its error).
  Result<ObjectAttachment> PrepareObject(std::span<const std::array<int32_t, 3>> surface,
                                         std::span<const uint32_t> triangles,
                                         std::span<const Vec3> positions,
                                         std::span<const double> masses, bool first_in_scene,
                                         const ToolTelemetry& now) const;

  /// Any thread: every motor to minimum tension now; stays so until ClearStop via the loop.
  void EmergencyStop();
  bool emergency_stopped() const { return estop_.load(std::memory_order_acquire); }

  /// After the loop stopped: disarms the watchdog, safe-stops and closes the device, stops the
  /// emulator. Returns a line for the log (what the emulator saw last), "" without one.
  std::string Shutdown();

  DeviceKind kind() const { return options_.kind; }
  const drivers::DeviceInfo& info() const { return device_->info(); }
  const DeviceLinkOptions& options() const { return options_; }
  const haptics::RendererConfig& renderer_config() const { return renderer_config_; }
  /// The coupling stiffness a renderer built now would use [N/m].
  double effective_stiffness() const { return effective_stiffness_; }
  int64_t watchdog_timeout_ns() const { return dog_ ? dog_->timeout_ns() : 0; }
  bool watchdog_realtime() const { return dog_thread_ && dog_thread_->realtime(); }
  /// sim-spidar-g only (else null): the emulated hand and grip.
  drivers::SpidarEmulator* emulator() const { return emulator_.get(); }
  /// network only (else null).
  NetworkDevice* network() const { return network_; }
  /// Minimum string tension of the frame [N] (0 without strings).
  double min_tension() const { return min_tension_; }

 private:
  explicit DeviceLink(const DeviceLinkOptions& options) : options_(options) {}
  void ClearStop();

  DeviceLinkOptions options_;
  std::unique_ptr<drivers::SpidarEmulator> emulator_;
  std::unique_ptr<drivers::HapticDevice> device_;
  NetworkDevice* network_ = nullptr;  // device_ when kind is network
  std::unique_ptr<drivers::Watchdog> dog_;
  std::unique_ptr<drivers::WatchdogThread> dog_thread_;
  haptics::RendererConfig renderer_config_;
  double effective_stiffness_ = 0.0;
  double min_tension_ = 0.0;
  std::atomic<bool> estop_{false};

  // Loop thread.
  Vec3 origin_ = Vec3::Zero();  // scene position of the device frame's origin [m]
  ToolContact contact_;         // the tool against the scene
  int healthy_ticks_ = 0;
  bool dog_armed_ = false;
  /// Share of recent exchanges that failed (moving average over about 32 exchanges): past
  /// kLinkDownAbove the link is reported disconnected until it falls below kLinkUpBelow.
  double exchange_failure_share_ = 0.0;
  bool link_down_ = false;
  ToolTelemetry t_;
};

}  // namespace rheo::daemon
