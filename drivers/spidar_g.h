// The SPIDAR-G string haptic device: HapticDevice over a MotorLink (UART boards or SH4).
#pragma once

#include <array>
#include <atomic>
#include <memory>
#include <mutex>

#include "drivers/haptic_device.h"
#include "drivers/pi_mutex.h"
#include "drivers/spidar_config.h"
#include "drivers/spidar_kinematics.h"
#include "drivers/tension_qp.h"
#include "drivers/transport.h"

namespace rheo::drivers {

/// SPIDAR-G: 8 strings, pose by damped Gauss-Newton, tensions by the box QP, with guards.
///
/// Each Exchange() sends the motor command computed by the last SetWrench() (minimum tension
/// while any fault is set, before calibration, or after SafeStop()), reads the encoders, updates
/// the pose and velocities and runs the zero-length, slack-string and workspace guards.
/// SetWrench() applies the force and force-rate limits and solves the QP at the current pose.
/// Post() (UART boards) sends that command at once; the next Exchange() then only reads the
/// reply. A SafeStop() between the two reads the outstanding reply itself and sends minimum
/// tension, and Exchange() falls back to a full exchange.
///
/// A link with a line source (UartMotorLink::SetLineSource) whose line goes away reports it as
/// disconnected (kFaultNotConnected, latched; status().line says how the reopening goes), every
/// exchange fails at once without I/O until a reopened line is there, and the first commands on
/// that line are at minimum tension until ClearFaults().
///
/// Threads: everything but SafeStop() on one thread (the loop). SafeStop() may come from any
/// thread; it serialises with Exchange() on an internal mutex (waiting at most one reply
/// timeout) so the serial stream never interleaves, and latches the safe state for every later
/// exchange. Nothing allocates after Open() except on error paths.
class SpidarG final : public HapticDevice {
 public:
  /// `config` must be valid (ParseSpidarConfig). The link is owned.
  SpidarG(SpidarConfig config, std::unique_ptr<MotorLink> link);
  /// Safe-stops (minimum tension) before releasing the link.
  ~SpidarG() override;

  Status Open() override;
  void Close() override;
  Status Calibrate() override;
  Status Exchange(double dt) override;
  void SetWrench(const Wrench& wrench) override;
  Status Post() override;
  void SafeStop() override;
  void ClearFaults() override;

  const ToolState& state() const override { return state_; }
  const DeviceStatus& status() const override { return status_; }
  const DeviceInfo& info() const override { return info_; }

  const SpidarConfig& config() const { return config_; }
  /// Per-string tension ceiling actually used: the config's, or less when the controller's
  /// command range cannot express it [N].
  const StringVector& max_tension() const { return qp_.max_tension(); }
  /// Motor command digits the next Exchange() sends (when no fault forces minimum tension).
  const std::array<int16_t, kSpidarStrings>& command() const { return command_; }

 private:
  static constexpr uint32_t kLatched =
      kFaultNotConnected | kFaultProtocol | kFaultZeroLength | kFaultSolver | kFaultSafeStop;
  // Reads the reply to a posted command, or sends `command` and reads counts; holds io_mutex_
  // for the duration.
  Status ExchangeLocked(const std::array<int16_t, kSpidarStrings>& command, uint32_t* buttons);
  void EncodeTensions(const StringVector& tensions, std::array<int16_t, kSpidarStrings>* out) const;
  void ShowMinimumTension();
  // connected and kFaultNotConnected from status_.line (the link's line, read under io_mutex_).
  void NoteLine();

  SpidarConfig config_;
  std::unique_ptr<MotorLink> link_;
  PoseSolver solver_;
  TensionSolver qp_;
  ToolState state_;
  DeviceStatus status_;
  DeviceInfo info_;

  PiMutex io_mutex_;  // serialises link_ between the loop and SafeStop (any thread)
  std::atomic<bool> stop_requested_{false};  // set by SafeStop, folded into faults by the loop
  std::atomic<bool> open_{false};
  std::array<int16_t, kSpidarStrings> command_{};       // next command [digits]
  std::array<int16_t, kSpidarStrings> min_command_{};   // every string at minimum [digits]
  std::array<int64_t, kSpidarStrings> counts_{};        // continuous encoder counts
  std::array<int64_t, kSpidarStrings> count_offset_{};  // counts at calibration
  StringVector home_length_ = StringVector::Zero();     // lengths at the calibration pose [m]
  double last_dt_ = 1e-3;                               // [s]
  bool have_velocity_ = false;
};

}  // namespace rheo::drivers
