#include "drivers/spidar_g.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

namespace rheo::drivers {
namespace {

StringVector MinTensions(const SpidarConfig& c) {
  StringVector v;
  for (int i = 0; i < kSpidarStrings; ++i) v[i] = c.strings[i].min_tension;
  return v;
}

// The config's ceiling, lowered to what `max_digits` can command.
StringVector MaxTensions(const SpidarConfig& c, int max_digits) {
  StringVector v;
  for (int i = 0; i < kSpidarStrings; ++i) {
    const SpidarString& s = c.strings[i];
    v[i] = std::min(s.max_tension, max_digits / (s.volts_per_newton * c.board.digits_per_volt));
  }
  return v;
}

// Scales `v` down to at most `limit` in norm; true when it did.
bool ClampNorm(Vec3* v, double limit) {
  const double n = v->norm();
  if (n > limit) {
    *v *= limit / n;
    return true;
  }
  return false;
}

}  // namespace

SpidarG::SpidarG(SpidarConfig config, std::unique_ptr<MotorLink> link)
    : config_(std::move(config)),
      link_(std::move(link)),
      solver_(config_),
      qp_(config_.tension_qp, MinTensions(config_),
          MaxTensions(config_, config_.board.max_digits)) {
  info_.name = "SPIDAR-G " + config_.name;
  info_.model = "not opened";
  info_.degrees_of_freedom = 6;
  info_.max_force = config_.limits.max_force;
  info_.max_torque = config_.limits.max_torque;
  info_.max_force_rate = config_.limits.max_force_rate;
  info_.workspace_half_extent = config_.workspace.half_extent;
  status_.num_motors = kSpidarStrings;
  status_.faults = kFaultNotConnected | kFaultNotCalibrated;
  EncodeTensions(MinTensions(config_), &min_command_);
  command_ = min_command_;
}

SpidarG::~SpidarG() {
  Close();
}

Status SpidarG::Open() {
  std::lock_guard lock(io_mutex_);
  if (Status s = link_->Open(kSpidarStrings); !s.ok()) {
    status_.faults |= kFaultNotConnected;
    return s;
  }
  // The board may accept less than the configured range: the QP must not ask for more.
  const int max_digits = std::min(config_.board.max_digits, link_->max_command());
  qp_ = TensionSolver(config_.tension_qp, MinTensions(config_), MaxTensions(config_, max_digits));
  info_.model = link_->model();
  open_ = true;
  status_.line = link_->line_stats();
  status_.connected = true;
  status_.faults &= ~(kFaultNotConnected | kFaultProtocol);
  command_ = min_command_;
  // First exchange: strings taut at minimum tension and the counters' starting values.
  uint32_t buttons = 0;
  if (Status s = link_->Exchange(min_command_, counts_, &buttons); !s.ok()) {
    status_.faults |= kFaultProtocol;
    return s;
  }
  ShowMinimumTension();
  return Status::Ok();
}

void SpidarG::Close() {
  if (!open_) return;
  SafeStop();
  open_ = false;
  status_.connected = false;
  status_.faults |= kFaultNotConnected;
}

Status SpidarG::ExchangeLocked(const std::array<int16_t, kSpidarStrings>& command,
                               uint32_t* buttons) {
  std::lock_guard lock(io_mutex_);
  const bool stop = stop_requested_.load(std::memory_order_acquire);
  if (link_->posted()) {
    Status s = link_->Collect(counts_, buttons);
    // A SafeStop that could not reach the link leaves the posted command on the motors: replace
    // it now rather than a tick later.
    if (!s.ok() || !stop) {
      status_.line = link_->line_stats();
      return s;
    }
  }
  // A SafeStop that arrived before we took the lock wins over the command we were given.
  Status s = link_->Exchange(stop ? min_command_ : command, counts_, buttons);
  status_.line = link_->line_stats();
  return s;
}

void SpidarG::NoteLine() {
  status_.connected = status_.line.up;
  if (!status_.line.up) status_.faults |= kFaultNotConnected;
}

Status SpidarG::Post() {
  if (!open_ || !link_->can_post()) return Status::Ok();
  std::lock_guard lock(io_mutex_);
  const bool safe = status_.faults != kFaultNone || stop_requested_.load(std::memory_order_acquire);
  Status s = link_->Post(safe ? min_command_ : command_);
  status_.line = link_->line_stats();
  NoteLine();
  // A line that is away is a lost connection, not a bad reply.
  if (!s.ok() && status_.line.up) {
    status_.faults |= kFaultProtocol;
    ++status_.protocol_errors;
  }
  return s;
}

Status SpidarG::Calibrate() {
  if (!open_) return FailedPrecondition("SPIDAR-G: Calibrate() before Open()");
  // Minimum tension on every string while the user holds the grip at the centre.
  uint32_t buttons = 0;
  for (int k = 0; k < 3; ++k) {
    std::lock_guard lock(io_mutex_);
    if (Status s = link_->Exchange(min_command_, counts_, &buttons); !s.ok()) {
      status_.faults |= kFaultProtocol;
      ++status_.protocol_errors;
      return s;
    }
  }
  for (int i = 0; i < kSpidarStrings; ++i) {
    const SpidarString& s = config_.strings[i];
    home_length_[i] = (s.motor_exit - s.grip_point).norm();
    count_offset_[i] = counts_[i];
    status_.lengths[i] = home_length_[i];
  }
  solver_.Reset(Pose());
  qp_.Reset();
  state_ = ToolState();
  state_.buttons = buttons;
  have_velocity_ = false;
  stop_requested_ = false;
  status_.calibrated = true;
  status_.faults &= ~(kLatched & ~kFaultNotConnected);
  status_.faults &= ~(kFaultNotCalibrated | kFaultSlackString | kFaultWorkspace);
  command_ = min_command_;
  ShowMinimumTension();
  return Status::Ok();
}

Status SpidarG::Exchange(double dt) {
  if (!open_) return FailedPrecondition("SPIDAR-G: Exchange() before Open()");
  last_dt_ = dt > 0.0 ? dt : last_dt_;
  const bool safe = status_.faults != kFaultNone;
  uint32_t buttons = 0;
  Status io = ExchangeLocked(safe ? min_command_ : command_, &buttons);
  if (stop_requested_.load(std::memory_order_acquire)) status_.faults |= kFaultSafeStop;
  // A line that went away (and, with a line source, is being reopened elsewhere) is reported as
  // a lost connection; the fault stays latched after the line is back, until ClearFaults().
  NoteLine();
  if (!io.ok()) {
    if (status_.line.up) {
      status_.faults |= kFaultProtocol;
      ++status_.protocol_errors;
    }
    return io;
  }
  state_.buttons = buttons;
  ++state_.exchanges;
  if (!status_.calibrated) return Status::Ok();

  StringVector lengths;
  bool zero_length = false;
  for (int i = 0; i < kSpidarStrings; ++i) {
    lengths[i] =
        home_length_[i] + config_.strings[i].metres_per_count * (counts_[i] - count_offset_[i]);
    status_.lengths[i] = lengths[i];
    zero_length |= !(lengths[i] > config_.guards.min_string_length);
  }
  // A string at (or past) zero length has no direction: the solver must not see it.
  if (zero_length) {
    status_.faults |= kFaultZeroLength;
    return Status::Ok();
  }
  const Pose before = solver_.pose();
  if (!solver_.Update(lengths)) {
    status_.faults |= kFaultSolver;
    return Status::Ok();
  }
  const Pose& pose = solver_.pose();
  state_.pose = pose;

  // Velocities by finite difference, low-pass filtered.
  const double a = config_.pose_solver.velocity_filter;
  const Vec3 v = (pose.position - before.position) / last_dt_;
  const Eigen::AngleAxisd turn(pose.orientation * before.orientation.conjugate());
  const Vec3 w = turn.axis() * turn.angle() / last_dt_;
  if (have_velocity_) {
    state_.linear_velocity = (1.0 - a) * state_.linear_velocity + a * v;
    state_.angular_velocity = (1.0 - a) * state_.angular_velocity + a * w;
  } else {
    state_.linear_velocity = v;
    state_.angular_velocity = w;
    have_velocity_ = true;
  }

  // Guards. A string that disagrees with the pose is slack or slipped; outside the workspace the
  // pose (and any wrench) is not trusted.
  const bool slack = solver_.residual().cwiseAbs().maxCoeff() > config_.guards.slack_residual;
  const Vec3& p = pose.position;
  const bool outside = (p.cwiseAbs().array() > config_.workspace.half_extent.array()).any() ||
                       Eigen::AngleAxisd(pose.orientation).angle() > config_.workspace.max_tilt;
  status_.faults = slack ? status_.faults | kFaultSlackString : status_.faults & ~kFaultSlackString;
  status_.faults = outside ? status_.faults | kFaultWorkspace : status_.faults & ~kFaultWorkspace;
  return Status::Ok();
}

void SpidarG::SetWrench(const Wrench& wrench) {
  if (stop_requested_.load(std::memory_order_acquire)) status_.faults |= kFaultSafeStop;
  if (status_.faults != kFaultNone || !wrench.force.allFinite() || !wrench.torque.allFinite()) {
    ShowMinimumTension();
    return;
  }
  const LimitsConfig& lim = config_.limits;
  Wrench w = wrench;
  bool limited = ClampNorm(&w.force, lim.max_force);
  limited |= ClampNorm(&w.torque, lim.max_torque);
  // Rate limit against what was requested last tick (zero after any fault).
  Vec3 df = w.force - status_.requested.force;
  Vec3 dtau = w.torque - status_.requested.torque;
  limited |= ClampNorm(&df, lim.max_force_rate * last_dt_);
  limited |= ClampNorm(&dtau, lim.max_torque_rate * last_dt_);
  w.force = status_.requested.force + df;
  w.torque = status_.requested.torque + dtau;

  const TensionSolution& sol = qp_.Solve(solver_.geometry().a, w);
  EncodeTensions(sol.tensions, &command_);
  status_.requested = w;
  status_.displayed = sol.displayed;
  status_.limited = limited;
  for (int i = 0; i < kSpidarStrings; ++i) status_.tensions[i] = sol.tensions[i];
}

void SpidarG::ShowMinimumTension() {
  command_ = min_command_;
  status_.requested = Wrench();
  status_.limited = false;
  const StringVector t = MinTensions(config_);
  const Eigen::Matrix<double, 6, 1> shown = solver_.geometry().a * t;
  status_.displayed.force = shown.head<3>();
  status_.displayed.torque = shown.tail<3>();
  for (int i = 0; i < kSpidarStrings; ++i) status_.tensions[i] = t[i];
}

void SpidarG::SafeStop() {
  stop_requested_.store(true, std::memory_order_release);
  if (!open_) return;
  // Wait at most a little longer than one exchange can take; if the loop holds the link that
  // long, its own exchange is about to end and every later one sends minimum tension anyway.
  // try_lock in a loop rather than timed_mutex: ThreadSanitizer does not see timed locks.
  std::unique_lock lock(io_mutex_, std::try_to_lock);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::microseconds(2500);
  while (!lock.owns_lock()) {
    if (std::chrono::steady_clock::now() > deadline) return;
    std::this_thread::yield();
    lock.try_lock();
  }
  // The counts read here are dropped: counts_ belongs to the loop thread, and the link keeps
  // its own unwrapping state, so the loop's next exchange is still continuous.
  uint32_t buttons = 0;
  std::array<int64_t, kSpidarStrings> counts;
  (void)link_->Exchange(min_command_, counts, &buttons);
}

void SpidarG::ClearFaults() {
  stop_requested_ = false;
  uint32_t keep = status_.faults & kFaultNotCalibrated;
  if (!open_ || !status_.line.up) keep |= kFaultNotConnected;
  status_.faults = keep;
}

void SpidarG::EncodeTensions(const StringVector& tensions,
                             std::array<int16_t, kSpidarStrings>* out) const {
  const int max_digits = config_.board.max_digits;
  for (int i = 0; i < kSpidarStrings; ++i) {
    const SpidarString& s = config_.strings[i];
    const double digits =
        s.command_sign * tensions[i] * s.volts_per_newton * config_.board.digits_per_volt;
    (*out)[i] =
        static_cast<int16_t>(std::clamp<long>(std::lround(digits), -max_digits, max_digits));
  }
}

}  // namespace rheo::drivers
