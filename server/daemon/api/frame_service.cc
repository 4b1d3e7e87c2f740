// FrameService: the loop's frames at each client's own rate (topology once, then positions).
#include <google/protobuf/util/time_util.h>

#include <algorithm>
#include <cmath>
#include <thread>

#include "daemon/api/convert.h"
#include "daemon/api/services.h"

namespace rheo::daemon {
namespace {

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

// Positions as 16-bit fractions of the object's bounding box (ObjectState.positions_q).
void Quantize(const float* xyz, uint32_t vertex_count, v1::ObjectState* os) {
  float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  for (uint32_t i = 0; i < vertex_count; ++i)
    for (int a = 0; a < 3; ++a) {
      const float v = xyz[3 * i + a];
      if (i == 0 || v < lo[a]) lo[a] = v;
      if (i == 0 || v > hi[a]) hi[a] = v;
    }
  auto set = [](v1::Vec3* v, const float* c) {
    v->set_x(c[0]);
    v->set_y(c[1]);
    v->set_z(c[2]);
  };
  set(os->mutable_bounds_min(), lo);
  set(os->mutable_bounds_max(), hi);
  std::string* out = os->mutable_positions_q();
  out->resize(6u * vertex_count);
  auto* bytes = reinterpret_cast<unsigned char*>(out->data());
  for (uint32_t i = 0; i < 3u * vertex_count; ++i) {
    const int a = static_cast<int>(i % 3);
    const float span = hi[a] - lo[a];
    const float t = span > 0.0f ? (xyz[i] - lo[a]) / span : 0.0f;
    const auto q = static_cast<uint16_t>(std::lround(std::clamp(t, 0.0f, 1.0f) * 65535.0f));
    bytes[2 * i] = static_cast<unsigned char>(q & 0xff);
    bytes[2 * i + 1] = static_cast<unsigned char>(q >> 8);
  }
}

grpc::Status ShuttingDown() {
  return grpc::Status(grpc::StatusCode::UNAVAILABLE, "rheod is shutting down");
}

}  // namespace

void FillFrame(const DaemonContext& ctx, const LoopFrame& f, const FrameContent& what,
               v1::Frame* out) {
  v1::Frame& frame = *out;
  frame.mutable_stamp()->set_tick(f.tick);
  frame.mutable_stamp()->set_sim_time(f.sim_time);
  *frame.mutable_stamp()->mutable_wall_time() = google::protobuf::util::TimeUtil::GetCurrentTime();
  *frame.mutable_stamp()->mutable_published() =
      google::protobuf::util::TimeUtil::NanosecondsToTimestamp(f.published_unix_ns);
  frame.set_paused(f.paused);
  frame.set_topology_revision(f.scene_revision);
  for (uint32_t i = 0; i < f.object_count; ++i) {
    const FrameObject& fo = f.objects[i];
    auto entry = ctx.scene->Find(fo.instance_id);
    if (!entry) continue;  // being removed
    if (what.topology) {
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
    os->set_unstable(fo.unstable);
    os->set_multi_rate(fo.multi_rate);
    const float* p = f.positions.data() + 3u * fo.first;
    os->set_volume(EnclosedVolume(p, fo.vertex_count, entry->triangles));
    if (what.positions && what.quantized)
      Quantize(p, fo.vertex_count, os);
    else if (what.positions)
      os->mutable_positions()->Add(p, p + 3u * fo.vertex_count);
  }
  if (f.tool.present)
    FillToolState(f.tool, ctx.leases ? ctx.leases->Holder().first : std::string(),
                  frame.mutable_tool());
  frame.mutable_loop()->set_ticks(f.ticks);
  frame.mutable_loop()->set_late_ticks(f.late_ticks);
  frame.mutable_loop()->set_last_work_us(f.work_ns / 1e3);
}

grpc::Status FrameServiceImpl::WatchFrames(grpc::ServerContext* context,
                                           const v1::WatchFramesRequest* request,
                                           grpc::ServerWriter<v1::Frame>* writer) {
  if (grpc::Status s = CheckRequest(*request); !s.ok()) return s;
  double rate = request->rate_hz() == 0 ? 60.0 : request->rate_hz();
  if (!(rate >= 1.0 && rate <= 1000.0))
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "rate_hz must be between 1 and 1000 (0 means 60); got " +
                            std::to_string(request->rate_hz()));
  FrameHub& hub = *ctx_.hub;
  if (hub.stopping()) return ShuttingDown();
  Quotas::Stream slot;
  if (grpc::Status s = HoldStream(ctx_, context, "WatchFrames", &slot); !s.ok()) return s;
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
    slot.Touch();  // waiting for the loop is not the client's idleness
    if (context->IsCancelled())
      return grpc::Status(grpc::StatusCode::CANCELLED, "client cancelled");
    if (hub.stopping()) return ShuttingDown();
    if (!snap) continue;
    last_seq = snap->seq;
    const LoopFrame& f = snap->frame;
    const bool send_topology = f.scene_revision != revision_sent;
    revision_sent = f.scene_revision;
    frame.Clear();
    FillFrame(ctx_, f, {send_topology, request->positions(), request->quantized()}, &frame);
    frame.set_dropped_frames(dropped);
    if (!writer->Write(frame)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
    slot.Touch();
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

}  // namespace rheo::daemon
