// RecordingService: start, stop, list, export and delete session recordings; the scene and
// parameter events the scene service hands the recorder; the interceptor that records commands.
#include "daemon/api/recording_service.h"

#include <fcntl.h>
#include <google/protobuf/descriptor.h>
#include <google/protobuf/util/time_util.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <set>
#include <string_view>

#include "daemon/api/convert.h"
#include "daemon/api/grpc_status.h"
#include "daemon/api/limits.h"
#include "daemon/replay/player.h"

namespace rheo::daemon {
namespace {

namespace pb = google::protobuf;

grpc::Status NoRecorder() {
  return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                      "this rheod records no sessions (it was started without a recorder)");
}

// A name is a label for people: printable, no line breaks (it goes into logs and listings).
grpc::Status CheckName(const std::string& name) {
  for (unsigned char c : name)
    if (c < 0x20 || c == 0x7f)
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "name " + QuoteForMessage(name) +
                              " has a control character (a tab, a line break, ...); give a "
                              "printable label");
  return grpc::Status::OK;
}

}  // namespace

v1::SceneEvent MakeSceneEvent(v1::SceneEvent::Kind kind, const SceneEntry& entry,
                              const TetMesh* mesh) {
  v1::SceneEvent ev;
  ev.set_kind(kind);
  if (kind == v1::SceneEvent::KIND_REMOVED) {
    ev.mutable_object()->set_instance_id(entry.instance_id);
    ev.mutable_object()->set_object_id(entry.object_id);
    return ev;
  }
  FillSceneObject(entry, false, false, ev.mutable_object());
  v1::SceneMesh* m = ev.mutable_mesh();
  m->set_vertex_count(entry.vertex_count);
  m->mutable_triangles()->Add(entry.triangles.begin(), entry.triangles.end());
  if (entry.has_contact) {
    const haptics::RendererConfig& rc = entry.contact_config;
    v1::ContactSetup* c = ev.mutable_contact();
    SetVec(entry.contact_tool, c->mutable_tool());
    c->set_tool_radius(rc.tool_radius);
    c->set_coupling_stiffness(rc.coupling_stiffness);
    c->set_coupling_damping(rc.coupling_damping);
    c->set_stability_margin(rc.stability_margin);
    c->set_static_friction(rc.static_friction);
    c->set_dynamic_friction(rc.dynamic_friction);
    c->set_max_step(rc.max_step);
    c->set_max_surface_speed(rc.max_surface_speed);
    c->set_rebin_faces_per_tick(rc.rebin_faces_per_tick);
    c->set_cell_size(rc.cell_size);
    c->set_device_max_force(rc.device.max_force);
    c->set_device_max_stiffness(rc.device.max_stiffness);
    c->set_device_max_force_rate(rc.device.max_force_rate);
    c->set_device_damping(rc.device.damping);
    c->set_device_tick(rc.device.tick);
  }
  if (!mesh) return ev;
  // AddToScene builds the object on the mesh moved so that its rest shape's centre is at
  // entry.position: the same sums here give the same doubles.
  const Vec3 shift = PlacementShift(*mesh, entry.position);
  m->mutable_rest_positions()->Reserve(static_cast<int>(3 * mesh->positions.size()));
  for (const Vec3& x : mesh->positions) {
    const Vec3 p = x + shift;
    m->add_rest_positions(p.x());
    m->add_rest_positions(p.y());
    m->add_rest_positions(p.z());
  }
  m->mutable_tetrahedra()->Reserve(static_cast<int>(4 * mesh->tets.size()));
  for (const auto& t : mesh->tets)
    for (int32_t v : t) m->add_tetrahedra(static_cast<uint32_t>(v));
  return ev;
}

void RecordSceneAdded(const DaemonContext& ctx, const SceneEntry& entry, const TetMesh& mesh,
                      uint64_t seq) {
  if (!ctx.recorder || !ctx.recorder->recording()) return;
  v1::SceneEvent ev = MakeSceneEvent(v1::SceneEvent::KIND_ADDED, entry, &mesh);
  ev.set_command_seq(seq);
  ctx.recorder->Post(std::move(ev));
}

void RecordSceneRemoved(const DaemonContext& ctx, const SceneEntry& entry, uint64_t seq) {
  if (!ctx.recorder || !ctx.recorder->recording()) return;
  v1::SceneEvent ev = MakeSceneEvent(v1::SceneEvent::KIND_REMOVED, entry, nullptr);
  ev.set_command_seq(seq);
  ctx.recorder->Post(std::move(ev));
}

void RecordParameters(const DaemonContext& ctx, const SceneEntry& entry, uint64_t seq) {
  if (!ctx.recorder || !ctx.recorder->recording()) return;
  v1::ParameterChange change;
  change.set_instance_id(entry.instance_id);
  change.set_preset(entry.preset);
  change.set_command_seq(seq);
  FillParameters(entry.params, change.mutable_parameters());
  ctx.recorder->Post(std::move(change));
}

grpc::Status RecordingServiceImpl::StartRecording(grpc::ServerContext*,
                                                  const v1::StartRecordingRequest* req,
                                                  v1::Recording* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (grpc::Status s = RefuseWhilePlayingBack(ctx_, "a new recording"); !s.ok()) return s;
  if (!ctx_.recorder) return NoRecorder();
  if (grpc::Status s = CheckName(req->name()); !s.ok()) return s;
  const double hz = req->has_frames_hz() ? req->frames_hz() : 60.0;
  // The objects in the scene now, with their meshes, under the scene's mutation mutex: no
  // object enters or leaves between this list and the recording's start, so each is in the
  // file once (as present, or as added afterwards).
  std::lock_guard<std::mutex> mutation(ctx_.scene->mutation_mutex());
  std::vector<v1::SceneEvent> initial;
  for (const auto& e : ctx_.scene->All()) {
    auto stored = ctx_.store->Get(e->object_id, /*with_mesh=*/true);
    // A stored object deleted while its instance stays in the scene: the surface still goes in.
    initial.push_back(
        MakeSceneEvent(v1::SceneEvent::KIND_PRESENT, *e, stored.ok() ? &stored->mesh : nullptr));
  }
  auto r = ctx_.recorder->Start(req->name(), hz, std::move(initial));
  if (!r.ok()) return ToGrpc(r.error());
  *out = std::move(r).value();
  return grpc::Status::OK;
}

grpc::Status RecordingServiceImpl::StopRecording(grpc::ServerContext*,
                                                 const v1::StopRecordingRequest* req,
                                                 v1::Recording* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.recorder) return NoRecorder();
  auto r = ctx_.recorder->Stop();
  if (!r.ok()) return ToGrpc(r.error());
  *out = std::move(r).value();
  return grpc::Status::OK;
}

grpc::Status RecordingServiceImpl::ListRecordings(grpc::ServerContext*,
                                                  const v1::ListRecordingsRequest* req,
                                                  v1::ListRecordingsResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.recorder) return grpc::Status::OK;
  for (v1::Recording& r : ctx_.recorder->List()) *out->add_recordings() = std::move(r);
  return grpc::Status::OK;
}

grpc::Status RecordingServiceImpl::ExportRecording(grpc::ServerContext* context,
                                                   const v1::ExportRecordingRequest* req,
                                                   grpc::ServerWriter<v1::RecordingChunk>* writer) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.recorder) return NoRecorder();
  auto file = ctx_.recorder->FileFor(req->id());
  if (!file.ok()) return ToGrpc(file.error());
  Quotas::Stream slot;
  if (grpc::Status s = HoldStream(ctx_, context, "ExportRecording", &slot); !s.ok()) return s;
  const int fd = ::open(file->c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT)
      return grpc::Status(grpc::StatusCode::NOT_FOUND,
                          "recording " + req->id() + " was deleted (" + *file + " is gone)");
    return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                        "cannot open " + *file + ": " + std::strerror(err));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  constexpr size_t kChunk = 1 << 20;
  v1::RecordingChunk chunk;
  std::string* data = chunk.mutable_data();
  for (;;) {
    if (context->IsCancelled())
      return grpc::Status(grpc::StatusCode::CANCELLED, "client cancelled");
    data->resize(kChunk);
    const ssize_t n = ::read(fd, data->data(), kChunk);
    if (n < 0) {
      if (errno == EINTR) continue;
      return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                          "reading " + *file + ": " + std::strerror(errno));
    }
    if (n == 0) break;
    data->resize(static_cast<size_t>(n));
    if (!writer->Write(chunk)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
    slot.Touch();
  }
  return grpc::Status::OK;
}

grpc::Status RecordingServiceImpl::DeleteRecording(grpc::ServerContext*,
                                                   const v1::DeleteRecordingRequest* req,
                                                   v1::DeleteRecordingResponse*) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.recorder) return NoRecorder();
  if (Status s = ctx_.recorder->Delete(req->id()); !s.ok()) return ToGrpc(s.error());
  return grpc::Status::OK;
}

// ---------------------------------------------------------------------------------------------
// Commands

namespace {

const std::set<std::string_view>& RecordedMethods() {
  static const std::set<std::string_view> methods = {
      "/rheo.v1.SceneService/AddToScene",     "/rheo.v1.SceneService/RemoveFromScene",
      "/rheo.v1.SceneService/SetParameters",  "/rheo.v1.SceneService/Control",
      "/rheo.v1.DeviceService/Calibrate",     "/rheo.v1.DeviceService/EmergencyStop",
      "/rheo.v1.DeviceService/SimulatedHand", "/rheo.v1.DeviceService/AcquireLease",
      "/rheo.v1.DeviceService/RenewLease",    "/rheo.v1.DeviceService/ReleaseLease",
      "/rheo.v1.DeviceService/RevokeLease",
  };
  return methods;
}

// Puts `request` into the CommandEvent's oneof member of its type, its lease id left out (a
// recording may be exported by any viewer). False when the type has no member.
bool SetRequest(const pb::Message& request, v1::CommandEvent* event) {
  const pb::OneofDescriptor* oneof = v1::CommandEvent::descriptor()->FindOneofByName("request");
  for (int i = 0; oneof && i < oneof->field_count(); ++i) {
    const pb::FieldDescriptor* f = oneof->field(i);
    if (f->message_type() != request.GetDescriptor()) continue;
    pb::Message* copy = event->GetReflection()->MutableMessage(event, f);
    copy->CopyFrom(request);
    if (const pb::FieldDescriptor* lease = copy->GetDescriptor()->FindFieldByName("lease_id");
        lease && lease->type() == pb::FieldDescriptor::TYPE_STRING)
      copy->GetReflection()->ClearField(copy, lease);
    return true;
  }
  return false;
}

class RecordingInterceptor final : public grpc::experimental::Interceptor {
 public:
  RecordingInterceptor(grpc::experimental::ServerRpcInfo* info, Recorder* recorder)
      : info_(info), recorder_(recorder) {}

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    using grpc::experimental::InterceptionHookPoints;
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_MESSAGE) && !taken_) {
      taken_ = true;
      const auto* m = static_cast<const pb::Message*>(methods->GetRecvMessage());
      if (m && recorder_->recording()) {
        received_ns_ = Recorder::UnixNowNs();
        if (SetRequest(*m, &event_)) recording_ = true;
      }
    }
    if (recording_ &&
        methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS)) {
      const grpc::Status s = methods->GetSendStatus();
      event_.set_method(info_->method() ? info_->method() : "");
      event_.set_caller(CallerOf(info_->server_context()).token_name);
      *event_.mutable_received() =
          google::protobuf::util::TimeUtil::NanosecondsToTimestamp(received_ns_);
      *event_.mutable_finished() =
          google::protobuf::util::TimeUtil::NanosecondsToTimestamp(Recorder::UnixNowNs());
      event_.set_code(static_cast<int32_t>(s.error_code()));
      event_.set_message(s.error_message().substr(0, 1000));
      recorder_->Post(std::move(event_), received_ns_);
      recording_ = false;
    }
    methods->Proceed();
  }

 private:
  grpc::experimental::ServerRpcInfo* info_;
  Recorder* recorder_;
  v1::CommandEvent event_;
  int64_t received_ns_ = 0;
  bool taken_ = false;
  bool recording_ = false;
};

}  // namespace

grpc::experimental::Interceptor* RecordingInterceptorFactory::CreateServerInterceptor(
    grpc::experimental::ServerRpcInfo* info) {
  if (!recorder_ || !info->method() || !RecordedMethods().count(info->method())) return nullptr;
  return new RecordingInterceptor(info, recorder_);
}

grpc::Status RefuseWhilePlayingBack(const DaemonContext& ctx, const char* what) {
  if (!ctx.player) return grpc::Status::OK;
  return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                      std::string("rheod is playing back ") +
                          std::filesystem::path(ctx.player->state().file).filename().string() +
                          " (--replay): the scene follows the recording, so " + what +
                          " is not taken; pause, seek or change the speed with ControlPlayback "
                          "(rheoctl record playback), or run rheod without --replay");
}

grpc::Status StepPlayback(const DaemonContext& ctx) {
  if (!ctx.player->state().paused)
    return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                        "step shows the next frame of a paused playback; pause it first");
  ctx.player->StepFrame();
  return grpc::Status::OK;
}

std::shared_ptr<SceneEntry> EntryFromSceneEvent(const v1::SceneEvent& ev) {
  auto e = std::make_shared<SceneEntry>();
  const v1::SceneObject& so = ev.object();
  e->instance_id = so.instance_id();
  e->object_id = so.object_id();
  e->preset = so.preset();
  e->integrator = so.integrator() == v1::INTEGRATOR_IMPLICIT ? sim::Integrator::kImplicitEuler
                                                             : sim::Integrator::kSymplecticEuler;
  if (auto preset = sim::FindPreset(so.preset().empty() ? "soft-jelly" : so.preset()); preset.ok())
    e->params = preset->params;
  // Recorded values the daemon took; a set it would not take now still lists as recorded.
  (void)ApplyParameterList(e->params, so.parameters());
  e->position = Vec3(so.position().x(), so.position().y(), so.position().z());
  e->vertex_count = ev.mesh().vertex_count();
  e->triangles.assign(ev.mesh().triangles().begin(), ev.mesh().triangles().end());
  e->cost.ns = so.predicted_tick_us() * 1e3;
  return e;
}

namespace {
void FillPlayback(const PlaybackState& st, v1::Playback* out) {
  out->set_file(st.file);
  out->set_duration_s(st.duration_s);
  out->set_position_s(st.position_s);
  out->set_paused(st.paused);
  out->set_ended(st.ended);
  out->set_speed(st.speed);
  out->set_tick(st.tick);
  out->set_frames(st.frames);
  out->set_frames_shown(st.frames_shown);
}

grpc::Status NotPlayingBack() {
  return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                      "this rheod plays back no recording (start it with --replay FILE)");
}
}  // namespace

grpc::Status RecordingServiceImpl::GetPlayback(grpc::ServerContext*,
                                               const v1::GetPlaybackRequest* req,
                                               v1::Playback* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.player) return NotPlayingBack();
  FillPlayback(ctx_.player->state(), out);
  return grpc::Status::OK;
}

grpc::Status RecordingServiceImpl::ControlPlayback(grpc::ServerContext*,
                                                   const v1::ControlPlaybackRequest* req,
                                                   v1::Playback* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (!ctx_.player) return NotPlayingBack();
  RecordingPlayer& p = *ctx_.player;
  if (req->has_speed())
    if (Status s = p.SetSpeed(req->speed()); !s.ok()) return ToGrpc(s.error());
  if (req->has_seek_s()) {
    if (!std::isfinite(req->seek_s()))
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "seek_s must be a finite time [s]");
    p.Seek(req->seek_s());
  }
  if (req->has_paused()) p.SetPaused(req->paused());
  if (req->step())
    if (grpc::Status s = StepPlayback(ctx_); !s.ok()) return s;
  FillPlayback(p.state(), out);
  return grpc::Status::OK;
}

}  // namespace rheo::daemon
