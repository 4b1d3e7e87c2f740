#include "drivers/spidar_config.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "drivers/spidar_kinematics.h"
#include "drivers/tension_qp.h"

namespace rheo::drivers {
namespace {

using nlohmann::json;

// Reads fields of one JSON object; the first failure is kept with the full field path.
class Reader {
 public:
  Reader(const json& j, std::string path, std::string* error)
      : j_(j), path_(std::move(path)), error_(error) {}

  bool ok() const { return error_->empty(); }
  std::string Field(std::string_view key) const {
    return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
  }
  void Fail(const std::string& field, const std::string& what) {
    if (error_->empty()) *error_ = field + ": " + what;
  }
  const json* Get(std::string_view key, bool required = true) {
    if (!ok()) return nullptr;
    auto it = j_.find(key);
    if (it == j_.end()) {
      if (required) Fail(Field(key), "missing");
      return nullptr;
    }
    return &*it;
  }
  // Number in [lo, hi]; `lo_open` makes the lower bound exclusive.
  void Number(std::string_view key, double* out, double lo, double hi, bool lo_open = false,
              bool required = true) {
    const json* v = Get(key, required);
    if (v == nullptr) return;
    if (!v->is_number()) return Fail(Field(key), "expected a number");
    double x = v->get<double>();
    std::ostringstream range;
    if (!std::isfinite(x) || (lo_open ? x <= lo : x < lo) || x > hi) {
      range << "must be in " << (lo_open ? "(" : "[") << lo << ", " << hi << "] (got " << x << ")";
      return Fail(Field(key), range.str());
    }
    *out = x;
  }
  void Integer(std::string_view key, int* out, int lo, int hi, bool required = true) {
    const json* v = Get(key, required);
    if (v == nullptr) return;
    if (!v->is_number_integer()) return Fail(Field(key), "expected an integer");
    int64_t x = v->get<int64_t>();
    if (x < lo || x > hi) {
      return Fail(Field(key), "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                                  "] (got " + std::to_string(x) + ")");
    }
    *out = static_cast<int>(x);
  }
  void Vector(std::string_view key, Vec3* out, double max_abs) {
    const json* v = Get(key);
    if (v == nullptr) return;
    if (!v->is_array() || v->size() != 3) return Fail(Field(key), "expected an array of 3 numbers");
    for (int k = 0; k < 3; ++k) {
      if (!(*v)[k].is_number())
        return Fail(Field(key) + "[" + std::to_string(k) + "]", "expected a number");
      double x = (*v)[k].get<double>();
      if (!std::isfinite(x) || std::abs(x) > max_abs) {
        return Fail(Field(key) + "[" + std::to_string(k) + "]",
                    "must be finite and within +-" + std::to_string(max_abs) + " m");
      }
      (*out)[k] = x;
    }
  }
  void String(std::string_view key, std::string* out, bool required = true) {
    const json* v = Get(key, required);
    if (v == nullptr) return;
    if (!v->is_string()) return Fail(Field(key), "expected a string");
    *out = v->get<std::string>();
  }
  // A child object reader; null when missing (the failure is recorded).
  const json* Object(std::string_view key) {
    const json* v = Get(key);
    if (v == nullptr) return nullptr;
    if (!v->is_object()) {
      Fail(Field(key), "expected an object");
      return nullptr;
    }
    return v;
  }

 private:
  const json& j_;
  std::string path_;
  std::string* error_;
};

constexpr double kMaxCoordinate = 2.0;  // no desk-top frame is larger than this [m]

}  // namespace

Result<SpidarConfig> ParseSpidarConfig(std::string_view json_text, std::string_view source) {
  json j;
  try {
    j = json::parse(json_text.begin(), json_text.end());
  } catch (const json::parse_error& e) {
    return InvalidArgument(std::string(source) + ": not valid JSON: " + e.what());
  }
  if (!j.is_object()) return InvalidArgument(std::string(source) + ": expected a JSON object");

  SpidarConfig c;
  std::string error;
  Reader top(j, "", &error);
  top.String("name", &c.name);
  top.String("description", &c.description, /*required=*/false);
  top.Number("grip_radius_m", &c.grip_radius, 0.0, 0.2, /*lo_open=*/true);

  if (const json* strings = top.Get("strings")) {
    if (!strings->is_array() || strings->size() != kSpidarStrings) {
      top.Fail("strings",
               "expected an array of " + std::to_string(kSpidarStrings) + " strings (got " +
                   (strings->is_array() ? std::to_string(strings->size()) : "no array") + ")");
    } else {
      for (int i = 0; i < kSpidarStrings && error.empty(); ++i) {
        std::string path = "strings[" + std::to_string(i) + "]";
        if (!(*strings)[i].is_object()) {
          top.Fail(path, "expected an object");
          break;
        }
        Reader r((*strings)[i], path, &error);
        SpidarString& s = c.strings[i];
        r.Vector("motor_exit_m", &s.motor_exit, kMaxCoordinate);
        r.Vector("grip_point_m", &s.grip_point, kMaxCoordinate);
        r.Number("metres_per_count", &s.metres_per_count, -1e-2, 1e-2);
        r.Number("volts_per_newton", &s.volts_per_newton, 0.0, 100.0, /*lo_open=*/true);
        r.Integer("command_sign", &s.command_sign, -1, 1);
        r.Number("min_tension_n", &s.min_tension, 0.0, 1000.0, /*lo_open=*/true);
        r.Number("max_tension_n", &s.max_tension, 0.0, 1000.0, /*lo_open=*/true);
      }
    }
  }

  if (const json* b = top.Object("board")) {
    Reader r(*b, "board", &error);
    std::string type;
    r.String("type", &type);
    if (error.empty()) {
      if (type == "uart") {
        c.board.type = BoardType::kUart;
      } else if (type == "sh4") {
        c.board.type = BoardType::kSh4;
      } else {
        r.Fail("board.type", "expected \"uart\" or \"sh4\" (got \"" + type + "\")");
      }
    }
    if (c.board.type == BoardType::kUart) {
      if (const json* ids = r.Get("board_ids")) {
        if (!ids->is_array() || ids->empty()) {
          r.Fail("board.board_ids", "expected a non-empty array of board ids");
        } else {
          c.board.board_ids.clear();
          for (size_t k = 0; k < ids->size(); ++k) {
            const json& id = (*ids)[k];
            if (!id.is_number_integer() || id.get<int>() < 0 || id.get<int>() > 7) {
              r.Fail("board.board_ids[" + std::to_string(k) + "]", "expected an id in [0, 7]");
              break;
            }
            c.board.board_ids.push_back(id.get<int>());
          }
        }
      }
    }
    r.Number("digits_per_volt", &c.board.digits_per_volt, 0.0, 1e6, /*lo_open=*/true);
    r.Integer("max_digits", &c.board.max_digits, 1, 32767);
    int mask = 0;
    r.Integer("button_mask", &mask, 0, 0xFFFF, /*required=*/false);
    c.board.button_mask = static_cast<uint32_t>(mask);
  }

  if (const json* w = top.Object("workspace")) {
    Reader r(*w, "workspace", &error);
    r.Vector("half_extent_m", &c.workspace.half_extent, kMaxCoordinate);
    double tilt_deg = 0.0;
    r.Number("max_tilt_deg", &tilt_deg, 0.0, 90.0, /*lo_open=*/true);
    c.workspace.max_tilt = tilt_deg * std::numbers::pi / 180.0;
  }
  if (const json* l = top.Object("limits")) {
    Reader r(*l, "limits", &error);
    r.Number("max_force_n", &c.limits.max_force, 0.0, 1000.0, true);
    r.Number("max_torque_nm", &c.limits.max_torque, 0.0, 100.0, true);
    r.Number("max_force_rate_n_per_s", &c.limits.max_force_rate, 0.0, 1e7, true);
    r.Number("max_torque_rate_nm_per_s", &c.limits.max_torque_rate, 0.0, 1e6, true);
  }
  if (const json* g = top.Object("guards")) {
    Reader r(*g, "guards", &error);
    r.Number("min_string_length_m", &c.guards.min_string_length, 0.0, 1.0, true);
    r.Number("slack_residual_m", &c.guards.slack_residual, 0.0, 1.0, true);
  }
  if (const json* p = top.Object("pose_solver")) {
    Reader r(*p, "pose_solver", &error);
    r.Integer("iterations", &c.pose_solver.iterations, 1, 20);
    r.Number("damping", &c.pose_solver.damping, 0.0, 1.0);
    r.Number("max_rotation_step_rad", &c.pose_solver.max_rotation_step, 0.0, 1.0, true);
    r.Number("bias_gain", &c.pose_solver.bias_gain, 0.0, 1.0);
    r.Number("velocity_filter", &c.pose_solver.velocity_filter, 0.0, 1.0, true);
  }
  if (const json* q = top.Object("tension_qp")) {
    Reader r(*q, "tension_qp", &error);
    r.Number("force_weight", &c.tension_qp.force_weight, 0.0, 1e6, true);
    r.Number("torque_weight", &c.tension_qp.torque_weight, 0.0, 1e6, true);
    r.Number("regularisation", &c.tension_qp.regularisation, 0.0, 1.0, true);
    r.Integer("max_iterations", &c.tension_qp.max_iterations, 1, 1000);
  }
  if (top.Get("haptics", /*required=*/false)) {
    if (const json* h = top.Object("haptics")) {
      Reader r(*h, "haptics", &error);
      r.Number("device_damping_n_s_per_m", &c.mechanism.damping, 0.0, 1000.0, /*lo_open=*/true,
               /*required=*/false);
    }
  }
  if (!error.empty()) return InvalidArgument(std::string(source) + ": " + error);
  Status valid = ValidateSpidarConfig(c, source);
  if (!valid.ok()) return valid.error();
  return c;
}

Status ValidateSpidarConfig(const SpidarConfig& c, std::string_view source) {
  auto fail = [&](const std::string& what) -> Status {
    return InvalidArgument(std::string(source) + ": " + what);
  };
  if (!(c.grip_radius > 0.0)) return fail("grip_radius_m: must be > 0");
  for (int i = 0; i < kSpidarStrings; ++i) {
    const SpidarString& s = c.strings[i];
    std::string path = "strings[" + std::to_string(i) + "]";
    if (s.metres_per_count == 0.0) return fail(path + ".metres_per_count: must not be 0");
    if (s.command_sign != 1 && s.command_sign != -1) {
      return fail(path + ".command_sign: must be +1 or -1");
    }
    if (!(s.min_tension > 0.0)) return fail(path + ".min_tension_n: must be > 0");
    if (!(s.max_tension > s.min_tension)) {
      return fail(path + ".max_tension_n: must exceed min_tension_n (" +
                  std::to_string(s.min_tension) + " N)");
    }
    if (s.grip_point.norm() > 2.0 * c.grip_radius + 1e-9) {
      return fail(path + ".grip_point_m: lies " + std::to_string(s.grip_point.norm()) +
                  " m from the grip centre, more than twice grip_radius_m");
    }
    double home = (s.motor_exit - s.grip_point).norm();
    if (home <= c.guards.min_string_length) {
      return fail(path + ": length at home " + std::to_string(home) +
                  " m is not above guards.min_string_length_m");
    }
    if (c.board.max_digits > 0 && c.board.digits_per_volt > 0.0 &&
        s.min_tension * s.volts_per_newton * c.board.digits_per_volt >= c.board.max_digits) {
      return fail(path + ".min_tension_n: needs more than board.max_digits");
    }
  }
  if (c.board.type == BoardType::kUart && c.board.board_ids.empty()) {
    return fail("board.board_ids: at least one board");
  }
  for (int k = 0; k < 3; ++k) {
    if (!(c.workspace.half_extent[k] > 0.0)) {
      return fail("workspace.half_extent_m[" + std::to_string(k) + "]: must be > 0");
    }
  }
  // The workspace corners at the largest tilt must keep every string usable and the pose
  // observable, or the solver and the guards would fight the configuration.
  for (int corner = 0; corner < 8; ++corner) {
    Pose pose;
    for (int k = 0; k < 3; ++k) {
      pose.position[k] = ((corner >> k) & 1 ? 1.0 : -1.0) * c.workspace.half_extent[k];
    }
    for (int axis = 0; axis < 3; ++axis) {
      pose.orientation = Eigen::AngleAxisd(c.workspace.max_tilt, Vec3::Unit(axis));
      StringGeometry g;
      ComputeStringGeometry(c, pose, &g);
      for (int i = 0; i < kSpidarStrings; ++i) {
        if (g.length[i] <= c.guards.min_string_length) {
          return fail("workspace: string " + std::to_string(i) + " is shorter than " +
                      "guards.min_string_length_m at a workspace corner");
        }
      }
      Eigen::Matrix<double, 6, 6> n = g.a * g.a.transpose();
      double min_eig =
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(n, Eigen::EigenvaluesOnly)
              .eigenvalues()
              .minCoeff();
      if (!(min_eig > 1e-12)) {
        return fail("workspace: the pose is not observable from the strings at a corner");
      }
      // Inside the frame the strings nearly balance the grip at low tension (a tilted grip may
      // keep a few mN); outside the frame they all pull one way.
      TensionSolver qp(c);
      const TensionSolution& balance = qp.Solve(g.a, Wrench());
      const double net = balance.displayed.force.norm();
      if (net > c.strings[0].min_tension) {
        std::ostringstream msg;
        msg << "workspace: at corner (" << pose.position.transpose() << ") m tilted about axis "
            << axis << ", the strings cannot balance the grip (net force " << net
            << " N at minimum tension): the workspace reaches outside the frame";
        return fail(msg.str());
      }
    }
  }
  return Status::Ok();
}

}  // namespace rheo::drivers
