// DeviceService: status, calibration, the control lease, the emergency stop, the network tool's
// stream and the emulated hand.
#include <google/protobuf/util/time_util.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "daemon/api/convert.h"
#include "daemon/api/grpc_status.h"
#include "daemon/api/limits.h"
#include "daemon/api/services.h"
#include "daemon/device/tool_placement.h"

namespace rheo::daemon {
namespace {

grpc::Status NoDevice() {
  return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                      "no haptic device is attached: start rheod with --device sim-spidar-g, "
                      "spidar-g or network");
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

void FillStatus(const DaemonContext& ctx, const ToolTelemetry& t, v1::DeviceStatus* out) {
  FillDeviceStatus(*ctx.device_link, ctx.device, t, ctx.leases->Holder(),
                   ctx.engine->loop().stats(), out);
}

// The lease is needed when someone holds it (or when `always`).
grpc::Status NeedLease(const DaemonContext& ctx, const grpc::ServerContext* context,
                       const std::string& lease_id, bool always) {
  if (!always && ctx.leases->Holder().first.empty()) return grpc::Status::OK;
  if (Status s = ctx.leases->Check(lease_id, CallerOf(context).token_name); !s.ok())
    return ToGrpc(s.error());
  return grpc::Status::OK;
}

}  // namespace

grpc::Status DeviceServiceImpl::GetDeviceStatus(grpc::ServerContext*,
                                                const v1::GetDeviceStatusRequest* req,
                                                v1::DeviceStatus* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.device_link) {
    out->set_kind(ctx_.device);
    out->set_model("none");
    out->set_connected(false);
    return grpc::Status::OK;
  }
  FillStatus(ctx_, ctx_.engine->tool(), out);
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::Calibrate(grpc::ServerContext* context,
                                          const v1::CalibrateRequest* req,
                                          v1::CalibrateResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.device_link) return NoDevice();
  if (grpc::Status s =
          NeedLease(ctx_, context, req->lease_id(), ctx_.device_link->emergency_stopped());
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

grpc::Status DeviceServiceImpl::AcquireLease(grpc::ServerContext* context,
                                             const v1::AcquireLeaseRequest* req, v1::Lease* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.device_link) return NoDevice();
  if (grpc::Status s = CheckLeaseDuration(req->duration_s()); !s.ok()) return s;
  auto l =
      ctx_.leases->Acquire(req->client_name(), CallerOf(context).token_name, req->duration_s());
  if (!l.ok()) return ToGrpc(l.error());
  FillLease(*l, out);
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::RenewLease(grpc::ServerContext* context,
                                           const v1::RenewLeaseRequest* req, v1::Lease* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.device_link) return NoDevice();
  if (grpc::Status s = CheckLeaseDuration(req->duration_s()); !s.ok()) return s;
  auto l = ctx_.leases->Renew(req->lease_id(), CallerOf(context).token_name, req->duration_s());
  if (!l.ok()) return ToGrpc(l.error());
  FillLease(*l, out);
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::ReleaseLease(grpc::ServerContext* context,
                                             const v1::ReleaseLeaseRequest* req,
                                             v1::ReleaseLeaseResponse*) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.device_link) return NoDevice();
  if (Status s = ctx_.leases->Release(req->lease_id(), CallerOf(context).token_name); !s.ok())
    return ToGrpc(s.error());
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::RevokeLease(grpc::ServerContext*, const v1::RevokeLeaseRequest* req,
                                            v1::RevokeLeaseResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.device_link) return NoDevice();
  out->set_holder(ctx_.leases->Revoke());
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::EmergencyStop(grpc::ServerContext* context,
                                              const v1::EmergencyStopRequest* req,
                                              v1::EmergencyStopResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.device_link) return NoDevice();
  if (req->engage()) {
    ctx_.device_link->EmergencyStop();
  } else {
    if (grpc::Status s = NeedLease(ctx_, context, req->lease_id(), /*always=*/true); !s.ok())
      return s;
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
  Quotas::Stream slot;
  if (grpc::Status s = HoldStream(ctx_, context, "ToolStream", &slot); !s.ok()) return s;
  v1::ToolInput in;
  v1::ToolFeedback fb;
  std::string lease_id;
  uint64_t used = 0;
  while (stream->Read(&in)) {
    slot.Touch();
    if (grpc::Status s = CheckRequest(in); !s.ok()) return s;
    if (lease_id.empty()) lease_id = in.lease_id();
    if (!in.lease_id().empty() && in.lease_id() != lease_id)
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "lease_id changed within one stream; open a new stream");
    if (Status s = ctx_.leases->Check(lease_id, CallerOf(context).token_name); !s.ok())
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
    slot.Touch();
  }
  return grpc::Status::OK;
}

grpc::Status DeviceServiceImpl::SimulatedHand(grpc::ServerContext* context,
                                              const v1::SimulatedHandRequest* req,
                                              v1::SimulatedHandResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.device_link) return NoDevice();
  drivers::SpidarEmulator* emu = ctx_.device_link->emulator();
  if (!emu)
    return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                        std::string("the simulated hand exists only with --device sim-spidar-g; "
                                    "this rheod runs --device ") +
                            DeviceKindName(ctx_.device_link->kind()));
  if (grpc::Status s = NeedLease(ctx_, context, req->lease_id(), false); !s.ok()) return s;
  switch (req->action_case()) {
    case v1::SimulatedHandRequest::kHold: {
      const auto& p = req->hold().position();
      drivers::Pose pose;
      pose.position = Vec3(p.x(), p.y(), p.z());
      if (req->hold().has_orientation()) {
        const auto& o = req->hold().orientation();
        const Eigen::Quaterniond q(o.w(), o.x(), o.y(), o.z());
        if (!q.coeffs().allFinite() || !(q.norm() > 1e-6))
          return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                              "hold orientation must be a finite, non-zero quaternion (w, x, y, "
                              "z); leave it unset for upright");
        pose.orientation = q.normalized();
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
  const v1::Press& press = req->press();
  const ToolTelemetry t = ctx_.engine->tool();
  // The press is planned on objects at rest: a surface measured while the object still falls
  // would be left behind (wait up to 3 s of loop time for every vertex to move less than 1 cm/s).
  // Loop time, not wall time: a loaded machine or a sanitizer build skips periods, and 3 s of wall
  // time there had left the heart falling under a press aimed at where it was. The wall clock
  // only caps the wait at 8 s, and a second before the caller's deadline.
  auto snap = ctx_.hub->WaitNewer(0, std::chrono::steady_clock::now() + std::chrono::seconds(2),
                                  [] { return false; });
  if (!snap) return grpc::Status(grpc::StatusCode::UNAVAILABLE, "no frame from the loop yet");
  const uint64_t settle_ticks =
      3'000'000'000ull / std::max<uint64_t>(1, ctx_.engine->loop().options().period_ns);
  const uint64_t settle_from = snap->frame.tick;
  auto settle_end = std::chrono::steady_clock::now() + std::chrono::seconds(8);
  if (context->deadline() != std::chrono::system_clock::time_point::max()) {
    const auto left = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        context->deadline() - std::chrono::system_clock::now() - std::chrono::seconds(1));
    settle_end = std::min(settle_end, std::chrono::steady_clock::now() + left);
  }
  while (std::chrono::steady_clock::now() < settle_end &&
         snap->frame.tick - settle_from < settle_ticks) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    auto next = ctx_.hub->WaitNewer(snap->seq, settle_end, [] { return false; });
    if (!next) break;
    // `prev` keeps the older snapshot alive while the two are compared (the hub has let go of it).
    const std::shared_ptr<const FrameSnapshot> prev = std::exchange(snap, next);
    const LoopFrame& a = prev->frame;
    const LoopFrame& b = snap->frame;
    const double dt = static_cast<double>(b.tick - a.tick) *
                      static_cast<double>(ctx_.engine->loop().options().period_ns) * 1e-9;
    if (a.scene_revision != b.scene_revision || a.positions.size() != b.positions.size()) continue;
    float moved = 0.0f;
    for (size_t k = 0; k < a.positions.size(); ++k)
      moved = std::max(moved, std::abs(b.positions[k] - a.positions[k]));
    if (dt > 0.0 && moved < 0.01 * dt) break;  // every vertex slower than 1 cm/s
  }
  const LoopFrame& f = snap->frame;
  if (f.object_count == 0)
    return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                        "the scene is empty: add an object first (AddToScene)");
  // The press line: a given point, a given object's top, the tool's own line, or the first
  // object's top when nothing is under the tool.
  const Vec3 tool = ToVec(t.device_position);
  // Each object's surface triangles, looked up once (the entries keep them alive).
  const auto entries = ctx_.scene->All();
  auto triangles_of = [&entries](uint32_t instance_id) -> std::span<const uint32_t> {
    for (const auto& e : entries)
      if (e->instance_id == instance_id) return e->triangles;
    return {};
  };
  auto object_top = [&](uint32_t instance_id) -> std::optional<Vec3> {
    const std::span<const uint32_t> triangles = triangles_of(instance_id);
    for (uint32_t i = 0; !triangles.empty() && i < f.object_count; ++i) {
      const FrameObject& fo = f.objects[i];
      if (fo.instance_id != instance_id) continue;
      std::vector<Vec3> x(fo.vertex_count);
      const float* p = f.positions.data() + 3u * fo.first;
      for (uint32_t k = 0; k < fo.vertex_count; ++k)
        x[k] = Vec3(p[3 * k], p[3 * k + 1], p[3 * k + 2]);
      return PressPoint(triangles, x);
    }
    return std::nullopt;
  };
  Vec3 line = tool;
  PressTarget target;
  if (press.has_at()) {
    line = Vec3(press.at().x(), 0.0, press.at().z());
    if (!line.allFinite())
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "press.at must be finite");
    target = FindPressTarget(f, line, triangles_of);
    if (!target.found)
      return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                          "no scene object lies under press.at");
  } else if (press.instance_id() != 0) {
    auto top = object_top(press.instance_id());
    if (!top)
      return grpc::Status(grpc::StatusCode::NOT_FOUND, "no scene object with instance_id " +
                                                           std::to_string(press.instance_id()));
    line = *top;
    target = FindPressTarget(f, line, triangles_of);
  } else {
    target = FindPressTarget(f, tool, triangles_of);
    if (!target.found) {
      auto top = object_top(f.objects[0].instance_id);
      if (!top) return grpc::Status(grpc::StatusCode::UNAVAILABLE, "the scene is changing; retry");
      line = *top;
      target = FindPressTarget(f, line, triangles_of);
    }
  }
  if (!target.found)
    return grpc::Status(grpc::StatusCode::UNAVAILABLE, "the object moved away; retry");

  // The hand's path (device frame): over every object to the press line, then down; the
  // workspace is re-placed over the line first when the object is out of the device's reach.
  const Vec3 origin = ToVec(t.tool_origin);
  double highest = -1e30;
  for (size_t k = 1; k < f.positions.size(); k += 3)
    highest = std::max(highest, double(f.positions[k]));
  PressRequest pr;
  pr.line = line;
  pr.surface_y = target.surface_y;
  pr.highest_y = highest;
  pr.depth = depth;
  pr.seconds = seconds;
  pr.grip = emu->Snapshot().pose.position;
  pr.origin = origin;
  pr.half_extent = ctx_.device_link->info().workspace_half_extent;
  pr.tip_radius = t.tip_radius;
  auto plan = PlanPress(pr);
  if (!plan.ok()) return ToGrpc(plan.error());
  auto follow = [emu](const std::vector<PressPlan::Waypoint>& points) {
    const drivers::GripSnapshot grip = emu->Snapshot();
    std::vector<std::pair<double, Vec3>> path{{0.0, grip.pose.position}};
    for (const auto& w : points) path.emplace_back(path.back().first + w.duration, w.grip);
    const double t0 = grip.time;
    emu->ScriptHand([path, t0](double now) {
      const double s = now - t0;
      drivers::Pose p;
      p.position = path.back().second;
      for (size_t i = 1; i < path.size(); ++i) {
        if (s >= path[i].first) continue;
        const double span = path[i].first - path[i - 1].first;
        const double u = span > 0.0 ? std::clamp((s - path[i - 1].first) / span, 0.0, 1.0) : 1.0;
        p.position = path[i - 1].second + u * (path[i].second - path[i - 1].second);
        break;
      }
      return p;
    });
    return path.back().first;
  };
  const double before_s = follow(plan->before);
  double after_s = 0.0;
  if (plan->replace_origin) {
    // A clutch: once the grip is at the centre column above every object, the workspace moves
    // so the tool stands over the press line at that height; then the press goes down.
    std::this_thread::sleep_for(std::chrono::duration<double>(before_s + 0.2));
    Command oc;
    oc.type = Command::Type::kSetToolOrigin;
    oc.vec = {plan->new_origin.x(), plan->new_origin.y(), plan->new_origin.z()};
    if (grpc::Status s = SubmitAndWait(*ctx_.engine, oc); !s.ok()) return s;
    after_s = follow(plan->after);
  }
  out->set_seconds(plan->replace_origin ? after_s : before_s);
  const Vec3 goal = plan->goal;
  SetVec(goal, out->mutable_target()->mutable_position());
  out->mutable_target()->mutable_orientation()->set_w(1.0);
  out->set_surface_y(target.surface_y);
  out->set_instance_id(target.instance_id);
  return grpc::Status::OK;
}

}  // namespace rheo::daemon
