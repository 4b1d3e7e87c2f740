// The device-independent haptic device interface the daemon's 1 kHz loop talks to.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <string>

#include "common/geometry.h"
#include "common/status.h"
#include "drivers/transport.h"

namespace rheo::drivers {

/// Most strings (or motors) any supported device has; status arrays have this size.
inline constexpr int kMaxMotors = 8;

/// A rigid pose in the device frame (x right, y up, z towards the user; origin at the frame
/// centre).
struct Pose {
  Vec3 position = Vec3::Zero();                                     // [m]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // unit quaternion
};

/// A force and a torque about the grip centre, in the device frame.
struct Wrench {
  Vec3 force = Vec3::Zero();   // [N]
  Vec3 torque = Vec3::Zero();  // [N m]
};

/// What the device measured at the last Exchange().
struct ToolState {
  Pose pose;
  Vec3 linear_velocity = Vec3::Zero();   // [m/s], low-pass filtered
  Vec3 angular_velocity = Vec3::Zero();  // [rad/s], device frame, low-pass filtered
  uint32_t buttons = 0;                  // bit i set while button i is pressed
  uint64_t exchanges = 0;                // successful exchanges since Open()
};

/// Fault bits. Transient faults clear themselves when the condition goes away; latched faults
/// stay until ClearFaults() (or a successful Calibrate()). While any fault is set the device
/// displays no wrench: every motor is at its minimum tension.
enum Fault : uint32_t {
  kFaultNone = 0,
  kFaultNotConnected = 1u << 0,   // latched: no link to the controller
  kFaultProtocol = 1u << 1,       // latched: a reply was missing, short or malformed
  kFaultNotCalibrated = 1u << 2,  // transient: cleared by Calibrate()
  kFaultZeroLength = 1u << 3,     // latched: a string length at or below the guard length
  kFaultSlackString = 1u << 4,    // transient: a string disagrees with the pose (slack or slipped)
  kFaultWorkspace = 1u << 5,      // transient: the grip is outside the workspace
  kFaultSolver = 1u << 6,         // latched: the pose solver produced a non-finite pose
  kFaultSafeStop = 1u << 7,       // latched: SafeStop() was called (watchdog, e-stop, shutdown)
};

/// Human-readable names of the bits set in `faults`, comma separated ("" when none).
std::string FaultNames(uint32_t faults);

/// Device health and what it is displaying.
struct DeviceStatus {
  bool connected = false;
  bool calibrated = false;
  uint32_t faults = kFaultNone;               // Fault bits
  int num_motors = 0;                         // entries used in the arrays below
  std::array<double, kMaxMotors> tensions{};  // commanded string tensions [N]
  std::array<double, kMaxMotors> lengths{};   // measured string lengths [m]
  Wrench requested;                           // after force and force-rate limits
  Wrench displayed;                           // what the tensions actually produce
  bool limited = false;                       // the force or force-rate limit cut the request
  uint64_t protocol_errors = 0;               // replies missing or malformed since Open()
  /// The line to the controller, for devices whose line can go away and be reopened (a USB
  /// serial adapter); `line.up` false: connected is false and kFaultNotConnected is set.
  LineStats line;
};

/// Fixed facts about a device, for the daemon's status API and the haptic renderer's limits.
struct DeviceInfo {
  std::string name;   // e.g. "SPIDAR-G X5"
  std::string model;  // controller, e.g. "open UART motor board model 7"
  int degrees_of_freedom = 6;
  double max_force = 0.0;                     // [N]
  double max_torque = 0.0;                    // [N m]
  double max_force_rate = 0.0;                // [N/s]
  Vec3 workspace_half_extent = Vec3::Zero();  // box around the origin [m]
};

/// A haptic device. The daemon's loop thread calls everything except SafeStop(), which any
/// thread may call at any time (the watchdog does). Nothing here allocates after Open().
///
/// Per tick the loop does: Exchange(dt) -> state() -> (render) -> SetWrench(w) -> Post().
/// Exchange reads the sensors; Post sends the command SetWrench computed right away, so a slow
/// link's reply arrives while the loop sleeps and the next Exchange only reads it. A device
/// whose link cannot split the exchange ignores Post, and Exchange sends the command first.
/// Either way the command displayed during a tick was computed from the previous sensor
/// reading: the order only moves the wait for the reply out of the tick.
///
/// How to add a device (the numbered skeleton; SpidarG in spidar_g.h is a full example):
///  1. Describe the device in a configuration file and a parser that returns rheo::Result with
///     the failing field named; keep every number (geometry, gains, limits) out of the code.
///  2. Keep the wire format in a pure codec (bytes in, values out, no I/O) so it is unit-tested
///     without hardware; mark anything not confirmed on hardware as unverified.
///  3. Put the OS side (serial port, USB, socket) behind a small transport interface so tests and
///     an emulator can stand in for the hardware.
///  4. Open(): connect, identify the controller, check it matches the configuration, put every
///     actuator in its safe state, and fill DeviceInfo.
///  5. Calibrate(): establish the reference pose with actuators safe; clear latched faults.
///  6. Exchange(dt): send the last command, read sensors, compute the pose and the filtered
///     velocities, run the guards (workspace, implausible readings) and set or clear faults.
///     Bound its time: a missing reply is a fault, never an indefinite wait.
///  7. SetWrench(w): apply the force and force-rate limits, turn the wrench into actuator
///     commands, record what will really be displayed; with any fault set, command the safe
///     state instead.
///  8. SafeStop(): thread-safe, idempotent, latches kFaultSafeStop; also called by the
///     destructor.
///  9. Write the emulator or loopback test that runs the real code path end to end.
class HapticDevice {
 public:
  virtual ~HapticDevice() = default;

  /// Connects and identifies the controller; leaves every motor at its minimum tension.
  virtual Status Open() = 0;
  /// Safe-stops and releases the connection. Open() may be called again.
  virtual void Close() = 0;
  /// Sets the reference pose: the user holds the grip at the frame centre with identity
  /// orientation. Clears latched faults when it succeeds.
  virtual Status Calibrate() = 0;
  /// Sends the last command and reads the sensors; dt is the time since the previous call [s].
  virtual Status Exchange(double dt) = 0;
  /// Sets the wrench for the next Exchange() (limits applied; see status().requested).
  virtual void SetWrench(const Wrench& wrench) = 0;
  /// Sends the command SetWrench computed now, when the link can overlap the reply with the
  /// loop's sleep; the next Exchange() then reads that reply instead of sending again. Default:
  /// nothing (Exchange() sends and reads in one go).
  virtual Status Post() { return Status::Ok(); }
  /// Every motor to minimum tension now, from any thread; latches kFaultSafeStop.
  virtual void SafeStop() = 0;
  /// Clears latched faults (not kFaultNotConnected while disconnected).
  virtual void ClearFaults() = 0;

  virtual const ToolState& state() const = 0;
  virtual const DeviceStatus& status() const = 0;
  virtual const DeviceInfo& info() const = 0;
};

}  // namespace rheo::drivers
