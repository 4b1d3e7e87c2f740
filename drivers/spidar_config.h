// SPIDAR-G frame layouts: the configuration a JSON file describes, parsed and validated.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"

namespace rheo::drivers {

/// A SPIDAR-G always has 8 strings: 4 grip points, 8 motors.
inline constexpr int kSpidarStrings = 8;

using StringVector = Eigen::Matrix<double, kSpidarStrings, 1>;  // one value per string

/// One string: motor, encoder, amplifier and its tension range.
struct SpidarString {
  Vec3 motor_exit = Vec3::Zero();  // where the string leaves the frame, frame coordinates [m]
  Vec3 grip_point = Vec3::Zero();  // attachment on the grip, grip coordinates [m]
  double metres_per_count = 0.0;   // signed string length per encoder count [m]
  double volts_per_newton = 0.0;   // amplifier input per newton of tension [V/N]
  int command_sign = 1;            // +1 or -1: sign of the motor command that pulls the string
  double min_tension = 0.0;        // [N], > 0 so the string never goes slack
  double max_tension = 0.0;        // [N]
};

enum class BoardType { kUart, kSh4 };

/// The motor controller and how tensions become its command digits.
struct BoardConfig {
  BoardType type = BoardType::kUart;
  std::vector<int> board_ids = {0};  // UART boards, in motor order (ids 0-7)
  double digits_per_volt = 0.0;      // command digits per volt [1/V]
  int max_digits = 0;                // commands are clamped to +-max_digits
  uint32_t button_mask = 0;          // SH4: digital inputs that are grip buttons
};

struct WorkspaceConfig {
  Vec3 half_extent = Vec3::Zero();  // allowed box around the frame centre [m]
  double max_tilt = 0.0;            // allowed rotation from identity [rad]
};

struct LimitsConfig {
  double max_force = 0.0;        // [N]
  double max_torque = 0.0;       // [N m]
  double max_force_rate = 0.0;   // [N/s]
  double max_torque_rate = 0.0;  // [N m/s]
};

struct GuardsConfig {
  double min_string_length = 0.0;  // shorter than this is a zero-length fault [m]
  double slack_residual = 0.0;     // a string off the solved pose by more is slack [m]
};

struct PoseSolverConfig {
  int iterations = 3;              // damped Gauss-Newton iterations per tick
  double damping = 1e-3;           // sigma, on the Jacobian scaled by the grip radius [1]
  double max_rotation_step = 0.2;  // per iteration [rad]
  double bias_gain = 1e-5;         // per tick adaptation of the per-string length bias [1]
  double velocity_filter = 0.2;    // weight of the newest velocity sample [1]
};

struct TensionQpConfig {
  double force_weight = 1.0;      // lt [1/N^2]
  double torque_weight = 6.0;     // lr [1/(N m)^2]
  double regularisation = 1e-10;  // tie-break towards low tensions [1/N^2]
  int max_iterations = 40;        // active-set changes per solve
};

/// A whole SPIDAR-G frame. Parse with ParseSpidarConfig; every field is then valid.
/// What a haptic renderer must know of the mechanism beyond the driver's limits (the optional
/// "haptics" block of a frame file; the driver itself does not use it).
struct MechanismConfig {
  /// The mechanism's own viscous damping b [N s/m]: the passivity bound K < 2 (b - B) / T of
  /// the renderer's coupling, and the emulator's damping.
  double damping = 2.0;
};

struct SpidarConfig {
  std::string name;
  std::string description;
  double grip_radius = 0.0;  // [m], scales the rotational part of the pose solver
  std::array<SpidarString, kSpidarStrings> strings;
  BoardConfig board;
  WorkspaceConfig workspace;
  LimitsConfig limits;
  GuardsConfig guards;
  PoseSolverConfig pose_solver;
  TensionQpConfig tension_qp;
  MechanismConfig mechanism;
};

/// Parses and validates a frame layout (JSON text, SI units). Errors name the field, e.g.
/// "strings[3].min_tension_n: must be > 0 (got -1)". `source` names the input in messages.
Result<SpidarConfig> ParseSpidarConfig(std::string_view json_text,
                                       std::string_view source = "SPIDAR-G config");

/// Checks a config built in code the same way the parser does.
Status ValidateSpidarConfig(const SpidarConfig& config, std::string_view source = "config");

}  // namespace rheo::drivers
