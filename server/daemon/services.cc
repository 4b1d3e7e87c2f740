#include "daemon/services.h"

#include <google/protobuf/util/time_util.h>

#include <algorithm>
#include <cmath>

#include "daemon/grpc_status.h"

namespace rheo::daemon {
namespace {

void FillPercentiles(const rt::Histogram& h, v1::Percentiles* out) {
  out->set_p50_us(h.Quantile(0.5) / 1e3);
  out->set_p99_us(h.Quantile(0.99) / 1e3);
  out->set_p999_us(h.Quantile(0.999) / 1e3);
  out->set_max_us(h.max_ns() / 1e3);
  out->set_mean_us(h.mean_ns() / 1e3);
  out->set_count(h.count());
}

// Volume enclosed by `triangles` (outward, 3 indices each) over the frame's float positions
// (x, y, z per vertex) [m^3]; computed here, off the loop, for the frames a client takes.
double EnclosedVolume(const float* xyz, uint32_t vertex_count,
                      const std::vector<uint32_t>& triangles) {
  auto at = [&](uint32_t i) {
    return i < vertex_count ? Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]) : Vec3::Zero();
  };
  double v = 0.0;
  for (size_t t = 0; t + 2 < triangles.size(); t += 3)
    v += at(triangles[t]).dot(at(triangles[t + 1]).cross(at(triangles[t + 2])));
  return v / 6.0;
}

void SetVec(const std::array<double, 3>& a, v1::Vec3* out) {
  out->set_x(a[0]);
  out->set_y(a[1]);
  out->set_z(a[2]);
}

void FillFrameTool(const ToolTelemetry& t, const DaemonContext& ctx, v1::ToolState* out) {
  out->set_present(true);
  SetVec(t.device_position, out->mutable_device_pose()->mutable_position());
  auto* q = out->mutable_device_pose()->mutable_orientation();
  q->set_w(t.device_orientation[0]);
  q->set_x(t.device_orientation[1]);
  q->set_y(t.device_orientation[2]);
  q->set_z(t.device_orientation[3]);
  SetVec(t.proxy, out->mutable_proxy_position());
  out->set_tip_radius(t.tip_radius);
  out->set_in_contact(t.in_contact);
  SetVec(t.displayed_force, out->mutable_wrench()->mutable_force());
  SetVec(t.displayed_torque, out->mutable_wrench()->mutable_torque());
  SetVec(t.requested_force, out->mutable_requested()->mutable_force());
  SetVec(t.requested_torque, out->mutable_requested()->mutable_torque());
  SetVec(t.object_force, out->mutable_object_force());
  if (ctx.leases) out->set_lease_holder(ctx.leases->Holder().first);
  for (const std::string& f : DeviceFaultList(t)) out->add_faults(f);
  out->set_contact_instance_id(t.contact_instance);
  out->set_emergency_stopped(t.emergency_stopped);
}

grpc::Status ShuttingDown() {
  return grpc::Status(grpc::StatusCode::UNAVAILABLE, "rheod is shutting down");
}

}  // namespace

// ---- DaemonService ----

grpc::Status DaemonServiceImpl::GetStatus(grpc::ServerContext*, const v1::GetStatusRequest*,
                                          v1::DaemonStatus* out) {
  const rt::Loop& loop = ctx_.engine->loop();
  const rt::LoopStats& s = loop.stats();
  out->set_version(ctx_.version);
  out->set_uptime_s(
      std::chrono::duration<double>(std::chrono::steady_clock::now() - ctx_.started).count());
  out->set_listen_address(ctx_.listen_address);
  out->set_data_dir(ctx_.data_dir);
  v1::LoopStatus* l = out->mutable_loop();
  l->set_rate_hz(1e9 / static_cast<double>(loop.options().period_ns));
  l->set_ticks(s.ticks.load());
  l->set_late_ticks(s.late_ticks.load());
  l->set_overruns(s.overruns.load());
  l->set_skipped_ticks(s.skipped_ticks.load());
  FillPercentiles(s.period, l->mutable_period());
  FillPercentiles(s.wake_latency, l->mutable_wake_latency());
  FillPercentiles(s.work, l->mutable_work());
  l->set_realtime_priority(loop.environment().realtime);
  l->set_memory_locked(loop.environment().memory_locked);
  l->set_notes(loop.environment().notes);
  l->set_commands_applied(ctx_.engine->commands_applied());
  l->set_commands_rejected(ctx_.engine->commands_rejected());
  l->set_restores(ctx_.engine->restores());
  out->set_device(ctx_.device);
  if (ctx_.device_link) out->add_capabilities("device");
  out->set_frame_clients(static_cast<uint32_t>(ctx_.hub->clients()));
  out->set_scene_objects(static_cast<uint32_t>(ctx_.scene->size()));
  if (auto n = ctx_.store->Count(); n.ok()) out->set_stored_objects(static_cast<uint32_t>(*n));
  out->set_running_jobs(static_cast<uint32_t>(ctx_.jobs->in_flight()));
  for (const char* c : {"loop", "frames", "sketch", "mesh", "store", "sim"})
    out->add_capabilities(c);
  return grpc::Status::OK;
}

// ---- FrameService ----

grpc::Status FrameServiceImpl::WatchFrames(grpc::ServerContext* context,
                                           const v1::WatchFramesRequest* request,
                                           grpc::ServerWriter<v1::Frame>* writer) {
  double rate = request->rate_hz() == 0 ? 60.0 : request->rate_hz();
  if (!(rate >= 1.0 && rate <= 1000.0))
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "rate_hz must be between 1 and 1000 (0 means 60); got " +
                            std::to_string(request->rate_hz()));
  FrameHub& hub = *ctx_.hub;
  if (hub.stopping()) return ShuttingDown();
  const int handle = hub.Register(rate);
  struct Unreg {
    FrameHub& h;
    int id;
    ~Unreg() { h.Unregister(id); }
  } unreg{hub, handle};

  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::nanoseconds(static_cast<int64_t>(1e9 / rate));
  auto due = Clock::now();
  // The first frame is copied after this call began, so it shows every object whose addition
  // was acknowledged before.
  uint64_t last_seq = hub.latest_seq();
  uint64_t sent = 0;
  uint64_t revision_sent = 0;
  uint64_t dropped = 0;
  v1::Frame frame;
  while (request->max_frames() == 0 || sent < request->max_frames()) {
    auto snap = hub.WaitNewer(last_seq, Clock::now() + std::chrono::seconds(5),
                              [&] { return context->IsCancelled(); });
    if (context->IsCancelled())
      return grpc::Status(grpc::StatusCode::CANCELLED, "client cancelled");
    if (hub.stopping()) return ShuttingDown();
    if (!snap) continue;
    last_seq = snap->seq;
    const LoopFrame& f = snap->frame;
    frame.Clear();
    frame.mutable_stamp()->set_tick(f.tick);
    frame.mutable_stamp()->set_sim_time(f.sim_time);
    *frame.mutable_stamp()->mutable_wall_time() =
        google::protobuf::util::TimeUtil::GetCurrentTime();
    frame.set_paused(f.paused);
    frame.set_topology_revision(f.scene_revision);
    const bool send_topology = f.scene_revision != revision_sent;
    revision_sent = f.scene_revision;
    for (uint32_t i = 0; i < f.object_count; ++i) {
      const FrameObject& fo = f.objects[i];
      auto entry = ctx_.scene->Find(fo.instance_id);
      if (!entry) continue;  // being removed
      if (send_topology) {
        v1::Topology* t = frame.add_topology();
        t->set_instance_id(fo.instance_id);
        t->set_vertex_count(fo.vertex_count);
        t->mutable_triangles()->Add(entry->triangles.begin(), entry->triangles.end());
        t->set_revision(f.scene_revision);
      }
      v1::ObjectState* os = frame.add_objects();
      os->set_instance_id(fo.instance_id);
      os->set_sleeping(fo.sleeping);
      os->set_kinetic_energy(fo.kinetic_energy);
      os->set_restores(fo.restores);
      const float* p = f.positions.data() + 3u * fo.first;
      os->set_volume(EnclosedVolume(p, fo.vertex_count, entry->triangles));
      if (request->positions()) os->mutable_positions()->Add(p, p + 3u * fo.vertex_count);
    }
    if (f.tool.present) FillFrameTool(f.tool, ctx_, frame.mutable_tool());
    frame.mutable_loop()->set_ticks(f.ticks);
    frame.mutable_loop()->set_late_ticks(f.late_ticks);
    frame.mutable_loop()->set_last_work_us(f.work_ns / 1e3);
    frame.set_dropped_frames(dropped);
    if (!writer->Write(frame)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
    ++sent;
    // Pace to the client's rate; frames that a slow client could not take are counted, not queued.
    due += period;
    auto now = Clock::now();
    if (now > due + period) {
      dropped = static_cast<uint64_t>((now - due) / period);
      due = now;
    } else {
      dropped = 0;
      std::this_thread::sleep_until(due);
    }
  }
  return grpc::Status::OK;
}

grpc::Status QueueFull() {
  return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      "the loop's command queue is full; retry shortly");
}

grpc::Status NotApplied(const char* what) {
  return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                      std::string("the loop did not take the ") + what + " within 2 s");
}

grpc::Status SubmitAndWait(Engine& engine, const Command& c) {
  const uint64_t seq = engine.Submit(c);
  if (seq == 0) return QueueFull();
  if (!engine.WaitApplied(seq, kApplyTimeoutNs)) return NotApplied("command");
  return grpc::Status::OK;
}

}  // namespace rheo::daemon
