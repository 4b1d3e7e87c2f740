// A simulated SPIDAR-G: a grip on 8 strings with rigid-body dynamics and a hand, behind an open
// UART motor board that speaks the real protocol byte for byte on a pseudo-terminal.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "drivers/haptic_device.h"
#include "drivers/pi_mutex.h"
#include "drivers/spidar_config.h"
#include "drivers/uart_protocol.h"

namespace rheo::drivers {

struct EmulatorOptions {
  double grip_mass = 0.05;               // [kg]
  double grip_inertia = 0.0;             // [kg m^2]; 0: a solid ball of the config's grip radius
  double linear_damping = 0.2;           // air and string friction [N s/m]
  double angular_damping = 2e-5;         // [N m s/rad]
  Vec3 gravity = Vec3(0.0, -9.81, 0.0);  // [m/s^2], device frame (y up)
  double physics_step = 1e-4;            // integration step [s]
  // The hand: a spring-damper between the grip and a target pose while it holds the grip.
  double hand_stiffness = 2000.0;       // [N/m]
  double hand_damping = 10.0;           // [N s/m]
  double hand_angular_stiffness = 0.5;  // [N m/rad]
  double hand_angular_damping = 2e-3;   // [N m s/rad]
  Pose initial_pose;                    // grip pose at power-on (counters read 0 there)
  bool hand_holds_at_start = true;      // the hand holds the grip at initial_pose
  // Lockstep: physics advances lockstep_dt per "current" command instead of with the wall
  // clock, so tests are deterministic and need no sleeps.
  bool lockstep = false;
  double lockstep_dt = 1e-3;  // [s]
  int board_id = 0;
  int model = 7;  // reported model; 7: 8 motors, 4 force inputs
  // > 0: try SCHED_FIFO at this priority for the emulator thread, so that a busy machine does
  // not delay the emulated board's replies (a real board answers from its own processor).
  int realtime_priority = 0;
  // Where the stable name of the line goes (line_path()): a symbolic link to the present pty,
  // replaced if it is one already. Empty: "line" in a directory of the emulator's own under the
  // temporary directory, removed with the emulator.
  std::string line_path;
};

/// The true state of the emulated grip.
struct GripSnapshot {
  double time = 0.0;  // emulated time [s]
  Pose pose;
  Vec3 velocity = Vec3::Zero();                  // [m/s]
  Vec3 angular_velocity = Vec3::Zero();          // [rad/s]
  StringVector tensions = StringVector::Zero();  // tensions the strings pull with [N]
  StringVector lengths = StringVector::Zero();   // true string lengths [m]
  Wrench strings;  // the strings' wrench on the grip (about its centre)
  Wrench hand;     // the hand's wrench on the grip
  bool holding = false;
  uint64_t current_commands = 0;  // "current" commands received
  uint64_t enumerations = 0;      // board-info requests answered
  uint64_t protocol_errors = 0;   // bytes that were no known command
  int64_t last_command_ns = 0;    // CLOCK_MONOTONIC when the last current command arrived [ns]
  std::array<int16_t, kSpidarStrings> last_command{};  // its values [digits]
  bool plugged = true;                                 // the line is there (Unplug, Replug)
  uint64_t replugs = 0;                                // Replug() calls that made a new line
  uint64_t commands_on_line = 0;  // current commands received on the present line
  std::array<int16_t, kSpidarStrings> first_command_on_line{};  // the first of them [digits]
};

/// What the emulated board's end of the line does wrong (fault injection for tests and the
/// reliability bench): nothing; no replies at all (a cut line: commands still arrive); every
/// reply with its bytes damaged; every reply held back for a while.
enum class LineFault { kNone, kSilent, kCorrupt, kDelayed };

/// Runs its own thread from Start() to Stop()/destruction. Thread-safe API.
class SpidarEmulator {
 public:
  /// `config` describes the emulated hardware (geometry, encoders, amplifiers); the driver
  /// normally reads the same file. Strings must be driven by a UART board in the emulator, even
  /// if the config names another controller.
  static Result<std::unique_ptr<SpidarEmulator>> Start(const SpidarConfig& config,
                                                       const EmulatorOptions& options = {});
  ~SpidarEmulator();
  SpidarEmulator(const SpidarEmulator&) = delete;
  SpidarEmulator& operator=(const SpidarEmulator&) = delete;

  /// The stable name of the line: a symbolic link to the present pty, re-pointed by Replug()
  /// and gone while unplugged, as /dev/serial/by-id/... names a USB serial adapter whatever
  /// ttyUSB number it gets. Give this to the driver as its serial port.
  const std::string& line_path() const { return line_path_; }
  /// The slave side of the present pseudo-terminal (another one after each Replug(); "" while
  /// unplugged).
  std::string pty_path() const;

  /// The USB serial adapter pulled out: the emulator's end of the line closes (the driver's
  /// reads see a hang-up, its writes fail with EIO), the pty and the link at line_path() go
  /// away. The board keeps its power and the last command it received: the motors stay as they
  /// were until a command arrives on a new line. Not while Stop() runs.
  Status Unplug();
  /// Plugged in again: a new pty, line_path() pointing at it; the board answers identification
  /// and commands as before, and its counters carry on. Not while Stop() runs.
  Status Replug();

  /// The hand holds the grip, pulling it towards `target` through the hand spring.
  void HoldHand(const Pose& target);
  /// The hand follows `script(t)` (t: emulated time [s]) until another hand call.
  void ScriptHand(std::function<Pose(double)> script);
  /// The hand lets go: only strings, gravity and damping act.
  void ReleaseHand();
  /// An extra wrench the hand applies to the grip (a push), in addition to the spring.
  void SetHandWrench(const Wrench& wrench);

  GripSnapshot Snapshot() const;
  /// From now on the board's replies suffer `fault` (kDelayed: each is sent `delay_us` late);
  /// kNone restores the line.
  void SetLineFault(LineFault fault, int delay_us = 0);
  /// Whether the emulator thread got SCHED_FIFO (options.realtime_priority > 0 and permitted).
  bool realtime() const { return realtime_.load(std::memory_order_acquire); }
  /// Stops the thread; the pty closes. Idempotent.
  void Stop();

 private:
  SpidarEmulator(const SpidarConfig& config, const EmulatorOptions& options);
  void Run();
  void OnByte(uint8_t byte);
  void ApplyCurrentCommand();
  void Step(double h);
  void Advance(double seconds);
  void SendReply(std::span<const uint8_t> bytes);
  void Encoders(uart::SensorReply* reply) const;
  // Make and break the line (the emulator thread, or any thread while it does not run).
  Status OpenLine();
  void CloseLine();
  // Asks the emulator thread to plug (true) or unplug the line and waits for it.
  Status ChangeLine(bool plug);

  const SpidarConfig config_;
  const EmulatorOptions options_;
  uart::BoardInfo info_;
  // The line: the emulator thread's (Unplug/Replug hand it the change through line_want_).
  int master_fd_ = -1;
  int slave_fd_ = -1;  // kept open so the master survives the driver closing and reopening
  std::string line_path_;
  std::string own_dir_;            // the directory made for line_path_ ("" with options.line_path)
  bool opened_before_ = false;     // a line was made before (the next one is a replug)
  std::mutex line_call_;           // one Unplug/Replug at a time
  std::atomic<int> line_want_{1};  // 1: plugged, 0: unplugged
  std::atomic<uint64_t> line_request_{0};  // raised by ChangeLine
  std::atomic<uint64_t> line_done_{0};     // line_request_ the thread has carried out
  Status line_result_;                     // of the last change (under mutex_)
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> realtime_{false};
  std::atomic<LineFault> line_fault_{LineFault::kNone};
  std::atomic<int> line_delay_us_{0};

  // Guards everything below against the API threads; priority-inheriting, so an API thread
  // preempted while holding it cannot stall the (real-time) emulator thread.
  mutable PiMutex mutex_;
  GripSnapshot state_;
  std::string pty_path_;
  double inertia_ = 0.0;
  Pose hand_target_;
  std::function<Pose(double)> hand_script_;
  Wrench hand_wrench_;
  StringVector power_on_length_ = StringVector::Zero();
  StringVector last_length_ = StringVector::Zero();
  int64_t last_advance_ns_ = 0;
  double last_advance_s_ = 0.0;  // length of the last Advance() [s]

  // Parser state (emulator thread only).
  uart::Command pending_ = uart::Command::kNone;
  int pending_board_ = 0;
  size_t need_ = 0;
  std::array<uint8_t, uart::kMaxFrameSize> frame_{};
  size_t have_ = 0;
};

}  // namespace rheo::drivers
