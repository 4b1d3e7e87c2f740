// DeviceService: status, calibration, the control lease, the emergency stop, the network tool's
// stream and the emulated hand.
#include <google/protobuf/util/time_util.h>

#include <cmath>
#include <sstream>
#include <thread>

#include "daemon/grpc_status.h"
#include "daemon/services.h"

namespace rheo::daemon {
namespace {

grpc::Status NoDevice() {
  return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                      "no haptic device is attached: start rheod with --device sim-spidar-g, "
                      "spidar-g or network");
}

void SetVec(const std::array<double, 3>& a, v1::Vec3* out) {
  out->set_x(a[0]);
  out->set_y(a[1]);
  out->set_z(a[2]);
}

Vec3 ToVec(const std::array<double, 3>& a) {
  return Vec3(a[0], a[1], a[2]);
}

void SetVec(const Vec3& a, v1::Vec3* out) {
  out->set_x(a.x());
  out->set_y(a.y());
  out->set_z(a.z());
}

// Waits until the loop published a tool state from a tick after `after_tick`.
ToolTelemetry WaitTool(const Engine& engine, uint64_t after_tick, int64_t timeout_ns) {
  const int64_t end = rt::Loop::NowNs() + timeout_ns;
  ToolTelemetry t = engine.tool();
  while (t.tick <= after_tick && rt::Loop::NowNs() < end && engine.loop().running()) {
    std::this_thread::sleep_for(std::chrono::microseconds(200));
    t = engine.tool();
  }
  return t;
}

grpc::Status CheckLeaseDuration(double seconds) {
  if (!(seconds >= 0.0) || seconds > LeaseManager::kMaxSeconds)
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "duration_s must be between 0 (10 s) and 3600 s");
  return grpc::Status::OK;
}

void FillLease(const LeaseManager::Lease& l, v1::Lease* out) {
  out->set_lease_id(l.id);
  out->set_holder(l.holder);
  out->set_expires_in_s(LeaseManager::SecondsLeft(l));
}

void FillStatus(const DaemonContext& ctx, const ToolTelemetry& t, v1::DeviceStatus* out) {
  const DeviceLink& link = *ctx.device_link;
  const drivers::DeviceInfo& info = link.info();
  out->set_kind(ctx.device);
  out->set_name(info.name);
  out->set_model(info.name + " (" + info.model + ")");
  out->set_connected(t.connected);
  out->set_calibrated(t.calibrated);
  out->set_emergency_stopped(t.emergency_stopped);
  for (int i = 0; i < t.num_motors; ++i) {
    out->add_string_tensions(t.tensions[i]);
    out->add_string_lengths(t.lengths[i]);
  }
  const Vec3 device_frame = ToVec(t.device_position) - ToVec(t.tool_origin);
  SetVec(device_frame, out->mutable_pose()->mutable_position());
  auto* q = out->mutable_pose()->mutable_orientation();
  q->set_w(t.device_orientation[0]);
  q->set_x(t.device_orientation[1]);
  q->set_y(t.device_orientation[2]);
  q->set_z(t.device_orientation[3]);
  SetVec(t.displayed_force, out->mutable_wrench()->mutable_force());
  SetVec(t.displayed_torque, out->mutable_wrench()->mutable_torque());
  SetVec(t.requested_force, out->mutable_requested_wrench()->mutable_force());
  SetVec(t.requested_torque, out->mutable_requested_wrench()->mutable_torque());
  out->set_max_force(info.max_force);
  out->set_max_stiffness(link.effective_stiffness());
  auto [holder, left] = ctx.leases->Holder();
  out->set_lease_holder(holder);
  out->set_lease_expires_in_s(left);
  for (const std::string& f : DeviceFaultList(t)) out->add_faults(f);
  out->set_fault_bits(t.faults);
  SetVec(t.proxy, out->mutable_proxy_position());
  out->set_in_contact(t.in_contact);
  SetVec(t.object_force, out->mutable_object_force());
  out->set_contact_instance_id(t.contact_instance);
  v1::DeviceCounters* c = out->mutable_counters();
  c->set_exchanges(t.exchanges);
  c->set_device_errors(t.device_errors);
  c->set_protocol_errors(t.protocol_errors);
  c->set_deadline_misses(t.deadline_misses);
  c->set_watchdog_trips(t.watchdog_trips);
  c->set_recoveries(t.recoveries);
  c->set_renderer_errors(t.renderer_errors);
  c->set_calibrations(t.calibrations);
  c->set_calibration_failures(t.calibration_failures);
  c->set_tick(t.tick);
  out->set_min_tension(link.min_tension());
  out->set_tip_radius(t.tip_radius);
  out->set_watchdog_timeout_ms(link.watchdog_timeout_ns() / 1e6);
  SetVec(t.tool_origin, out->mutable_tool_origin());
  const rt::LoopStats& s = ctx.engine->loop().stats();
  v1::Percentiles* p = out->mutable_loop_period();
  p->set_p50_us(s.period.Quantile(0.5) / 1e3);
  p->set_p99_us(s.period.Quantile(0.99) / 1e3);
  p->set_p999_us(s.period.Quantile(0.999) / 1e3);
  p->set_max_us(s.period.max_ns() / 1e3);
  p->set_mean_us(s.period.mean_ns() / 1e3);
  p->set_count(s.period.count());
  out->set_loop_late_ticks(s.late_ticks.load());
}

// The lease is needed when someone holds it (or when `always`).
grpc::Status NeedLease(const DaemonContext& ctx, const std::string& lease_id, bool always) {
  if (!always && ctx.leases->Holder().first.empty()) return grpc::Status::OK;
  if (Status s = ctx.leases->Check(lease_id); !s.ok()) return ToGrpc(s.error());
  return grpc::Status::OK;
}

}  // namespace

std::vector<std::string> DeviceFaultList(const ToolTelemetry& t) {
  std::vector<std::string> out;
  if (t.emergency_stopped) out.push_back("emergency stop engaged");
  if (t.watchdog_tripped) out.push_back("watchdog tripped (the loop stalled)");
  std::stringstream names(drivers::FaultNames(t.faults));
  std::string item;
  while (std::getline(names, item, ',')) {
    size_t a = item.find_first_not_of(' ');
    if (a != std::string::npos) out.push_back(item.substr(a));
  }
  return out;
}

grpc::Status DeviceServiceImpl::GetDeviceStatus(grpc::ServerContext*,
                                                const v1::GetDeviceStatusRequest*,
                                                v1::DeviceStatus* out) {
  if (!ctx_.device_link) {
    out->set_kind(ctx_.device);
    out->set_model("none");
    out->set_connected(false);
    return grpc::Status::OK;
  }
  FillStatus(ctx_, ctx_.engine->tool(), out);
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::Calibrate(grpc::ServerContext*, const v1::CalibrateRequest* req,
                                          v1::CalibrateResponse* out) {
  if (!ctx_.device_link) return NoDevice();
  if (grpc::Status s = NeedLease(ctx_, req->lease_id(), ctx_.device_link->emergency_stopped());
      !s.ok())
    return s;
  const uint64_t failures = ctx_.engine->tool().calibration_failures;
  Command c;
  c.type = Command::Type::kDeviceCalibrate;
  if (grpc::Status s = SubmitAndWait(*ctx_.engine, c); !s.ok()) return s;
  ToolTelemetry t = ctx_.engine->tool();
  FillStatus(ctx_, t, out->mutable_status());
  if (t.calibration_failures != failures)
    return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                        "calibration failed: the device did not answer; check the cable and the "
                        "controller's power, then retry");
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::AcquireLease(grpc::ServerContext*,
                                             const v1::AcquireLeaseRequest* req, v1::Lease* out) {
  if (!ctx_.device_link) return NoDevice();
  if (grpc::Status s = CheckLeaseDuration(req->duration_s()); !s.ok()) return s;
  auto l = ctx_.leases->Acquire(req->client_name(), req->duration_s());
  if (!l.ok()) return ToGrpc(l.error());
  FillLease(*l, out);
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::RenewLease(grpc::ServerContext*, const v1::RenewLeaseRequest* req,
                                           v1::Lease* out) {
  if (!ctx_.device_link) return NoDevice();
  if (grpc::Status s = CheckLeaseDuration(req->duration_s()); !s.ok()) return s;
  auto l = ctx_.leases->Renew(req->lease_id(), req->duration_s());
  if (!l.ok()) return ToGrpc(l.error());
  FillLease(*l, out);
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::ReleaseLease(grpc::ServerContext*,
                                             const v1::ReleaseLeaseRequest* req,
                                             v1::ReleaseLeaseResponse*) {
  if (!ctx_.device_link) return NoDevice();
  if (Status s = ctx_.leases->Release(req->lease_id()); !s.ok()) return ToGrpc(s.error());
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::EmergencyStop(grpc::ServerContext*,
                                              const v1::EmergencyStopRequest* req,
                                              v1::EmergencyStopResponse* out) {
  if (!ctx_.device_link) return NoDevice();
  if (req->engage()) {
    ctx_.device_link->EmergencyStop();
  } else {
    if (grpc::Status s = NeedLease(ctx_, req->lease_id(), /*always=*/true); !s.ok()) return s;
    Command c;
    c.type = Command::Type::kDeviceClear;
    if (grpc::Status s = SubmitAndWait(*ctx_.engine, c); !s.ok()) return s;
  }
  // Report a tick that has seen the change.
  const uint64_t now = ctx_.engine->tool().tick;
  FillStatus(ctx_, WaitTool(*ctx_.engine, now + 1, kApplyTimeoutNs), out->mutable_status());
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::ToolStream(
    grpc::ServerContext* context,
    grpc::ServerReaderWriter<v1::ToolFeedback, v1::ToolInput>* stream) {
  if (!ctx_.device_link) return NoDevice();
  NetworkDevice* net = ctx_.device_link->network();
  if (!net)
    return grpc::Status(
        grpc::StatusCode::FAILED_PRECONDITION,
        std::string("ToolStream moves the network tool; this rheod runs --device ") +
            DeviceKindName(ctx_.device_link->kind()) + " (start it with --device network)");
  v1::ToolInput in;
  v1::ToolFeedback fb;
  std::string lease_id;
  uint64_t used = 0;
  while (stream->Read(&in)) {
    if (lease_id.empty()) lease_id = in.lease_id();
    if (!in.lease_id().empty() && in.lease_id() != lease_id)
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "lease_id changed within one stream; open a new stream");
    if (Status s = ctx_.leases->Check(lease_id); !s.ok())
      return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                          "ToolStream needs the control lease: " + s.error().message);
    if (ctx_.shutting_down && ctx_.shutting_down->load())
      return grpc::Status(grpc::StatusCode::UNAVAILABLE, "rheod is shutting down");
    const auto& p = in.pose().position();
    const auto& o = in.pose().orientation();
    drivers::Pose pose;
    pose.position = Vec3(p.x(), p.y(), p.z());
    if (in.pose().has_orientation())
      pose.orientation = Eigen::Quaterniond(o.w(), o.x(), o.y(), o.z());
    if (!pose.position.allFinite() || !pose.orientation.coeffs().allFinite() ||
        (in.pose().has_orientation() && pose.orientation.norm() < 1e-6))
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "ToolInput.pose must be finite with a non-zero orientation quaternion");
    const uint64_t seq = net->Push(pose, in.buttons());
    // Answer with the tick that used this pose (or the newest, if the loop is slow).
    const int64_t end = rt::Loop::NowNs() + 50'000'000;
    ToolTelemetry t = ctx_.engine->tool();
    while (t.input_seq < seq && rt::Loop::NowNs() < end && !context->IsCancelled()) {
      std::this_thread::sleep_for(std::chrono::microseconds(100));
      t = ctx_.engine->tool();
    }
    if (t.input_seq >= seq) ++used;
    fb.Clear();
    fb.mutable_stamp()->set_tick(t.tick);
    fb.mutable_stamp()->set_sim_time(ctx_.engine->sim_time());
    *fb.mutable_stamp()->mutable_wall_time() = google::protobuf::util::TimeUtil::GetCurrentTime();
    SetVec(t.displayed_force, fb.mutable_wrench()->mutable_force());
    SetVec(t.displayed_torque, fb.mutable_wrench()->mutable_torque());
    SetVec(t.proxy, fb.mutable_proxy_position());
    fb.set_in_contact(t.in_contact);
    fb.set_input_seq(used);
    for (const std::string& f : DeviceFaultList(t)) fb.add_faults(f);
    if (!stream->Write(fb)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
  }
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::SimulatedHand(grpc::ServerContext*,
                                              const v1::SimulatedHandRequest* req,
                                              v1::SimulatedHandResponse* out) {
  if (!ctx_.device_link) return NoDevice();
  drivers::SpidarEmulator* emu = ctx_.device_link->emulator();
  if (!emu)
    return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                        std::string("the simulated hand exists only with --device sim-spidar-g; "
                                    "this rheod runs --device ") +
                            DeviceKindName(ctx_.device_link->kind()));
  if (grpc::Status s = NeedLease(ctx_, req->lease_id(), false); !s.ok()) return s;
  switch (req->action_case()) {
    case v1::SimulatedHandRequest::kHold: {
      const auto& p = req->hold().position();
      drivers::Pose pose;
      pose.position = Vec3(p.x(), p.y(), p.z());
      if (req->hold().has_orientation()) {
        const auto& o = req->hold().orientation();
        pose.orientation = Eigen::Quaterniond(o.w(), o.x(), o.y(), o.z()).normalized();
      }
      const Vec3 half = ctx_.device_link->info().workspace_half_extent;
      if (!pose.position.allFinite() || (pose.position.array().abs() > half.array()).any())
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                            "hold position must be inside the workspace (+-" +
                                std::to_string(half.x()) + " m on each axis)");
      emu->HoldHand(pose);
      *out->mutable_target() = req->hold();
      return grpc::Status::OK;
    }
    case v1::SimulatedHandRequest::kRelease: emu->ReleaseHand(); return grpc::Status::OK;
    case v1::SimulatedHandRequest::kPress: break;
    default:
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "give one action: hold, release or press");
  }
  const double depth = req->press().depth_m();
  const double seconds = req->press().seconds();
  if (!(depth >= 0.0 && depth <= 0.05) || !(seconds >= 0.0 && seconds <= 60.0))
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "press.depth_m must be in [0, 0.05] m and press.seconds in [0, 60] s");
  // Find the top of the object under the tool in the newest frame.
  const ToolTelemetry t = ctx_.engine->tool();
  auto snap = ctx_.hub->WaitNewer(0, std::chrono::steady_clock::now() + std::chrono::seconds(2),
                                  [] { return false; });
  if (!snap) return grpc::Status(grpc::StatusCode::UNAVAILABLE, "no frame from the loop yet");
  const LoopFrame& f = snap->frame;
  const Vec3 tool = ToVec(t.device_position);
  const double reach = std::max(3.0 * t.tip_radius, 0.005);  // [m]
  double top = -1e30;
  for (uint32_t i = 0; i < f.object_count; ++i) {
    const FrameObject& fo = f.objects[i];
    const float* x = f.positions.data() + 3u * fo.first;
    for (uint32_t k = 0; k < fo.vertex_count; ++k) {
      const double dx = x[3 * k] - tool.x(), dz = x[3 * k + 2] - tool.z();
      if (dx * dx + dz * dz <= reach * reach) top = std::max(top, double(x[3 * k + 1]));
    }
  }
  if (top < -1e29)
    return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                        "no scene object lies under the tool (within " + std::to_string(reach) +
                            " m of its vertical line); add an object or move the hand over one");
  const drivers::GripSnapshot grip = emu->Snapshot();
  const drivers::Pose start = grip.pose;
  const double target_y = top + t.tip_radius - depth - t.tool_origin[1];
  const double t0 = grip.time;
  emu->ScriptHand([start, target_y, t0, seconds](double now) {
    const double s = seconds > 0.0 ? std::clamp((now - t0) / seconds, 0.0, 1.0) : 1.0;
    drivers::Pose p;
    p.position = start.position;
    p.position.y() = start.position.y() + s * (target_y - start.position.y());
    return p;
  });
  SetVec(Vec3(start.position.x(), target_y, start.position.z()),
         out->mutable_target()->mutable_position());
  out->mutable_target()->mutable_orientation()->set_w(1.0);
  out->set_surface_y(top);
  return grpc::Status::OK;
}

}  // namespace rheo::daemon
