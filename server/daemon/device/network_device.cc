#include "daemon/device/network_device.h"

#include <algorithm>

namespace rheo::daemon {

NetworkDevice::NetworkDevice(const NetworkDeviceOptions& options) : options_(options) {
  info_.name = "network tool";
  info_.model = "DeviceService.ToolStream client";
  info_.degrees_of_freedom = 6;
  info_.max_force = options.max_force;
  info_.max_torque = options.max_torque;
  info_.max_force_rate = options.max_force_rate;
  info_.workspace_half_extent = Vec3::Constant(options.workspace_half);
  status_.num_motors = 0;
  status_.faults = drivers::kFaultNotConnected;
}

uint64_t NetworkDevice::Push(const drivers::Pose& pose, uint32_t buttons) {
  std::lock_guard<std::mutex> lock(push_mutex_);
  NetworkToolInput in;
  in.seq = next_seq_++;
  in.position = {pose.position.x(), pose.position.y(), pose.position.z()};
  const Eigen::Quaterniond q = pose.orientation.normalized();
  in.orientation = {q.w(), q.x(), q.y(), q.z()};
  in.buttons = buttons;
  input_.Store(in);
  return in.seq;
}

Status NetworkDevice::Open() {
  status_.connected = true;
  return Status::Ok();
}

void NetworkDevice::Close() {
  SafeStop();
  status_.connected = false;
}

Status NetworkDevice::Calibrate() {
  // A client's pose needs no reference; calibrating clears latched faults.
  ClearFaults();
  status_.calibrated = true;
  return Status::Ok();
}

Status NetworkDevice::Exchange(double dt) {
  const NetworkToolInput in = input_.Load();
  since_input_s_ += dt;
  if (in.seq != 0 && in.seq != used_seq_) {
    const Vec3 p(in.position[0], in.position[1], in.position[2]);
    if (have_pose_ && since_input_s_ > 0.0) {
      const Vec3 v = (p - state_.pose.position) / since_input_s_;
      state_.linear_velocity =
          (1.0 - options_.velocity_filter) * state_.linear_velocity + options_.velocity_filter * v;
    }
    state_.pose.position = p;
    state_.pose.orientation = Eigen::Quaterniond(in.orientation[0], in.orientation[1],
                                                 in.orientation[2], in.orientation[3]);
    state_.buttons = in.buttons;
    ++state_.exchanges;
    used_seq_ = in.seq;
    since_input_s_ = 0.0;
    have_pose_ = true;
  }
  uint32_t faults = status_.faults & drivers::kFaultSafeStop;
  if (stop_requested_.load(std::memory_order_acquire)) faults |= drivers::kFaultSafeStop;
  if (!have_pose_ || since_input_s_ > options_.stale_after_s) {
    faults |= drivers::kFaultNotConnected;
    state_.linear_velocity.setZero();
  }
  if ((state_.pose.position.array().abs() > options_.workspace_half).any())
    faults |= drivers::kFaultWorkspace;
  status_.faults = faults;
  status_.connected = have_pose_ && since_input_s_ <= options_.stale_after_s;
  return Status::Ok();
}

void NetworkDevice::SetWrench(const drivers::Wrench& wrench) {
  if (!wrench.force.allFinite() || !wrench.torque.allFinite()) return;
  drivers::Wrench w = wrench;
  const double f = w.force.norm();
  const double t = w.torque.norm();
  status_.limited = f > options_.max_force || t > options_.max_torque;
  if (f > options_.max_force) w.force *= options_.max_force / f;
  if (t > options_.max_torque) w.torque *= options_.max_torque / t;
  status_.requested = w;
  status_.displayed = status_.faults == drivers::kFaultNone ? w : drivers::Wrench();
}

void NetworkDevice::SafeStop() {
  stop_requested_.store(true, std::memory_order_release);
}

void NetworkDevice::ClearFaults() {
  stop_requested_.store(false, std::memory_order_release);
  status_.faults &= ~drivers::kFaultSafeStop;
}

}  // namespace rheo::daemon
