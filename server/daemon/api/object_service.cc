// ObjectService: sketches become stored solids on the worker pool, with progress and cancel.
#include <algorithm>
#include <optional>
#include <thread>

#include "common/tet_mesh_io.h"
#include "daemon/api/convert.h"
#include "daemon/api/grpc_status.h"
#include "daemon/api/limits.h"
#include "daemon/api/object_builder.h"
#include "daemon/api/services.h"
#include "mesh/mesh.h"

namespace rheo::daemon {
namespace {

std::chrono::steady_clock::time_point SteadyDeadline(const grpc::ServerContext& ctx,
                                                     std::chrono::seconds cap) {
  auto now_sys = std::chrono::system_clock::now();
  auto now = std::chrono::steady_clock::now();
  auto limit = now + cap;
  auto d = ctx.deadline();
  if (d >= now_sys + cap) return limit;
  return now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(d - now_sys);
}

// The store's errors with the id quoted short and escaped.
grpc::Status StoreError(const Error& e, const std::string& id) {
  if (e.code == ErrorCode::kNotFound)
    return ToGrpc(NotFound("no object with id " + QuoteForMessage(id)));
  return ToGrpc(e);
}

grpc::Status ObjectFromMeta(const StoredObject& o, v1::Object* out) {
  if (!out->ParseFromString(o.meta))
    return grpc::Status(grpc::StatusCode::DATA_LOSS, "stored object " + o.id + " is unreadable");
  return grpc::Status::OK;
}

// The next event of a job its handler watches: false with `stop` set when the client went away
// or the daemon is shutting down (the job is cancelled), false without when none came within
// `poll`; `done` turns true with the last event.
bool NextJobEvent(grpc::ServerContext& context, const DaemonContext& ctx, Job<JobEvent>& job,
                  std::chrono::milliseconds poll, JobEvent& ev, bool& done,
                  std::optional<grpc::Status>& stop) {
  if (context.IsCancelled()) {
    job.Cancel();
    stop = grpc::Status(grpc::StatusCode::CANCELLED, "client cancelled " + job.id());
    return false;
  }
  if (ctx.shutting_down->load()) {
    job.Cancel();
    stop = grpc::Status(grpc::StatusCode::UNAVAILABLE,
                        "rheod is shutting down; " + job.id() + " was cancelled");
    return false;
  }
  return job.Pop(ev, poll, done);
}

}  // namespace

grpc::Status ObjectServiceImpl::CreateObject(grpc::ServerContext* context,
                                             const v1::CreateObjectRequest* request,
                                             grpc::ServerWriter<v1::CreateObjectProgress>* writer) {
  if (grpc::Status s = CheckRequest(*request); !s.ok()) return s;
  if (Status s = ValidateCreateRequest(*request); !s.ok()) return ToGrpc(s.error());
  if (ctx_.shutting_down->load())
    return grpc::Status(grpc::StatusCode::UNAVAILABLE, "shutting down");
  // A request id makes a retry safe: one build per id at a time, and an id whose object is
  // stored answers with it.
  const std::string& request_id = request->request_id();
  struct InFlight {
    ObjectServiceImpl* self;
    std::string id;
    ~InFlight() {
      if (id.empty()) return;
      std::lock_guard<std::mutex> lock(self->requests_mutex_);
      self->requests_in_flight_.erase(id);
    }
  } in_flight{this, ""};
  if (!request_id.empty()) {
    const auto give_up = SteadyDeadline(*context, ctx_.job_timeout);
    for (;;) {
      {
        std::lock_guard<std::mutex> lock(requests_mutex_);
        if (requests_in_flight_.insert(request_id).second) break;
      }
      // The first attempt is still building (its client may have been cut off): wait for it.
      if (context->IsCancelled() || std::chrono::steady_clock::now() > give_up)
        return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED,
                            "a CreateObject with request_id " + QuoteForMessage(request_id) +
                                " is still building; retry later with the same id");
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    in_flight.id = request_id;
    auto earlier = ctx_.store->FindByRequestId(request_id);
    if (earlier.ok()) return Replay(*earlier, *request, writer);
    if (earlier.error().code != ErrorCode::kNotFound) return ToGrpc(earlier.error());
  }
  Quotas::Stream slot;
  if (grpc::Status s = HoldStream(ctx_, context, "CreateObject", &slot); !s.ok()) return s;
  Quotas::Job job_slot;
  if (ctx_.quotas)
    if (grpc::Status s = ctx_.quotas->StartJob(CallerOf(context).token_name, &job_slot); !s.ok())
      return s;
  Store* store = ctx_.store;
  const BuildLimits limits = ctx_.build_limits;
  auto job = ctx_.jobs->Submit(
      SteadyDeadline(*context, ctx_.job_timeout),
      [request = *request, limits, store](Job<JobEvent>& job) {
        auto built = BuildObject(
            request, limits,
            [&](const v1::CreateObjectProgress& p) {
              job.Push(JobEvent::Progress(p));
              return job.ShouldStop();
            },
            job.token());
        if (!built.ok()) {
          job.Push(JobEvent::Failed(built.error()));
          return;
        }
        v1::CreateObjectProgress p;
        p.set_stage("store");
        p.set_fraction(0.97);
        job.Push(JobEvent::Progress(p));
        if (auto stop = job.ShouldStop()) {
          job.Push(JobEvent::Failed(*stop));
          return;
        }
        built->request_id = request.request_id();
        if (Status s = store->Put(*built); !s.ok()) {
          job.Push(JobEvent::Failed(s.error()));
          return;
        }
        p.set_stage("done");
        p.set_fraction(1.0);
        if (!p.mutable_object()->ParseFromString(built->meta)) {
          job.Push(JobEvent::Failed(Internal("object metadata did not serialize")));
          return;
        }
        job.Push(JobEvent{p, std::nullopt, std::make_shared<TetMesh>(std::move(built->mesh))});
      });
  if (!job.ok()) return ToGrpc(job.error());
  const std::string job_id = (*job)->id();
  // Whose job it is (CancelJob lets only them, or an admin, cancel it), until this call ends.
  {
    std::lock_guard<std::mutex> lock(requests_mutex_);
    job_owners_[job_id] = CallerOf(context).token_name;
  }
  struct Disown {
    ObjectServiceImpl* self;
    std::string id;
    ~Disown() {
      std::lock_guard<std::mutex> lock(self->requests_mutex_);
      self->job_owners_.erase(id);
    }
  } disown{this, job_id};

  v1::CreateObjectProgress queued;
  queued.set_job_id(job_id);
  queued.set_stage("queued");
  writer->Write(queued);
  JobEvent ev;
  bool done = false;
  bool sent_object = false;
  std::optional<grpc::Status> stop;
  while (!done) {
    slot.Touch();  // the build is the server's time, not the client's idleness
    if (!NextJobEvent(*context, ctx_, **job, std::chrono::milliseconds(50), ev, done, stop)) {
      if (stop) return *stop;
      continue;
    }
    if (ev.error) {
      Error e = *ev.error;
      e.message = job_id + ": " + e.message;
      return ToGrpc(e);
    }
    ev.progress.set_job_id(job_id);
    if (ev.progress.has_object() && request->add_to_scene()) {
      v1::AddToSceneRequest add;
      add.set_object_id(ev.progress.object().id());
      if (grpc::Status s =
              AddObjectToScene(ctx_, add, ev.mesh.get(), ev.progress.mutable_scene_object());
          !s.ok())
        return grpc::Status(s.error_code(),
                            "object " + add.object_id() +
                                " was stored but not added to the scene: " + s.error_message());
    }
    sent_object = sent_object || ev.progress.has_object();
    if (!writer->Write(ev.progress)) {
      (*job)->Cancel();
      return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
    }
    slot.Touch();
  }
  if (!sent_object)
    return grpc::Status(grpc::StatusCode::INTERNAL, job_id + " ended without a result");
  return grpc::Status::OK;
}

grpc::Status ObjectServiceImpl::Replay(const StoredObject& stored,
                                       const v1::CreateObjectRequest& request,
                                       grpc::ServerWriter<v1::CreateObjectProgress>* writer) {
  v1::CreateObjectProgress done;
  done.set_stage("done");
  done.set_fraction(1.0);
  done.set_replayed(true);
  if (grpc::Status s = ObjectFromMeta(stored, done.mutable_object()); !s.ok()) return s;
  if (request.add_to_scene()) {
    // In the scene already (the first attempt got that far): that instance; else add it now.
    bool found = false;
    std::unique_lock<std::mutex> mutation(ctx_.scene->mutation_mutex());  // FillSceneObject
    for (const auto& e : ctx_.scene->All())
      if (e->object_id == stored.id) {
        FillSceneObject(*e, false, false, done.mutable_scene_object());
        found = true;
        break;
      }
    mutation.unlock();  // AddObjectToScene takes it
    if (!found) {
      v1::AddToSceneRequest add;
      add.set_object_id(stored.id);
      if (grpc::Status s = AddObjectToScene(ctx_, add, nullptr, done.mutable_scene_object());
          !s.ok())
        return grpc::Status(
            s.error_code(),
            "object " + stored.id + " was stored but not added to the scene: " + s.error_message());
    }
  }
  writer->Write(done);
  return grpc::Status::OK;
}

grpc::Status ObjectServiceImpl::CancelJob(grpc::ServerContext* context,
                                          const v1::CancelJobRequest* request,
                                          v1::CancelJobResponse* out) {
  if (grpc::Status s = CheckRequest(*request); !s.ok()) return s;
  if (request->job_id().empty()) return ToGrpc(InvalidArgument("job_id is empty"));
  const Caller caller = CallerOf(context);
  {
    std::lock_guard<std::mutex> lock(requests_mutex_);
    auto it = job_owners_.find(request->job_id());
    if (it != job_owners_.end() && it->second != caller.token_name &&
        !caller.at_least(Role::kAdmin))
      return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                          request->job_id() + " belongs to token " + QuoteForMessage(it->second) +
                              "; only its owner or an admin may cancel it");
  }
  out->set_cancelled(ctx_.jobs->Cancel(request->job_id()));
  return grpc::Status::OK;
}

// The sketch stage on the worker pool, like CreateObject: the same limits, the client's deadline
// as the job's, and the job cancelled as soon as the client goes away.
grpc::Status ObjectServiceImpl::ExtractContour(grpc::ServerContext* context,
                                               const v1::ExtractContourRequest* request,
                                               v1::ContourReport* out) {
  if (grpc::Status s = CheckRequest(*request); !s.ok()) return s;
  v1::CreateObjectRequest check;
  *check.mutable_sketch() = request->sketch();
  *check.mutable_contour_options() = request->options();
  if (Status s = ValidateCreateRequest(check); !s.ok()) return ToGrpc(s.error());
  if (ctx_.shutting_down->load())
    return grpc::Status(grpc::StatusCode::UNAVAILABLE, "shutting down");
  auto job = ctx_.jobs->Submit(
      SteadyDeadline(*context, ctx_.job_timeout), [request = *request](Job<JobEvent>& job) {
        auto r = daemon::ExtractContour(request.sketch(), request.options(), job.token());
        if (!r.ok()) {
          job.Push(JobEvent::Failed(r.error()));
          return;
        }
        v1::CreateObjectProgress p;
        p.set_stage("done");
        *p.mutable_contour() = std::move(r).value();
        job.Push(JobEvent::Progress(std::move(p)));
      });
  if (!job.ok()) return ToGrpc(job.error());
  const std::string job_id = (*job)->id();
  JobEvent ev;
  bool done = false;
  std::optional<grpc::Status> stop;
  while (!done) {
    if (!NextJobEvent(*context, ctx_, **job, std::chrono::milliseconds(20), ev, done, stop)) {
      if (stop) return *stop;
      continue;
    }
    if (ev.error) {
      Error e = *ev.error;
      e.message = "contour extraction (" + job_id + "): " + e.message;
      return ToGrpc(e);
    }
    if (ev.progress.has_contour()) {
      *out = std::move(*ev.progress.mutable_contour());
      return grpc::Status::OK;
    }
  }
  return grpc::Status(grpc::StatusCode::INTERNAL, job_id + " ended without a contour");
}

grpc::Status ObjectServiceImpl::ListObjects(grpc::ServerContext*,
                                            const v1::ListObjectsRequest* request,
                                            v1::ListObjectsResponse* out) {
  if (grpc::Status s = CheckRequest(*request); !s.ok()) return s;
  uint32_t n = request->page_size() == 0 ? 100 : std::min<uint32_t>(request->page_size(), 1000);
  std::string next;
  auto page = ctx_.store->List(n, request->page_token(), &next);
  if (!page.ok()) return ToGrpc(page.error());
  for (const auto& o : *page)
    if (grpc::Status s = ObjectFromMeta(o, out->add_objects()); !s.ok()) return s;
  out->set_next_page_token(next);
  return grpc::Status::OK;
}

grpc::Status ObjectServiceImpl::GetObject(grpc::ServerContext*, const v1::GetObjectRequest* request,
                                          v1::Object* out) {
  if (grpc::Status s = CheckRequest(*request); !s.ok()) return s;
  auto o = ctx_.store->Get(request->id(), /*with_mesh=*/false);
  if (!o.ok()) return StoreError(o.error(), request->id());
  return ObjectFromMeta(*o, out);
}

grpc::Status ObjectServiceImpl::DeleteObject(grpc::ServerContext*,
                                             const v1::DeleteObjectRequest* request,
                                             v1::DeleteObjectResponse*) {
  if (grpc::Status s = CheckRequest(*request); !s.ok()) return s;
  if (Status s = ctx_.store->Delete(request->id()); !s.ok())
    return StoreError(s.error(), request->id());
  return grpc::Status::OK;
}

grpc::Status ObjectServiceImpl::ExportObject(grpc::ServerContext* context,
                                             const v1::ExportObjectRequest* request,
                                             grpc::ServerWriter<v1::ExportChunk>* writer) {
  if (grpc::Status s = CheckRequest(*request); !s.ok()) return s;
  Quotas::Stream slot;
  if (grpc::Status s = HoldStream(ctx_, context, "ExportObject", &slot); !s.ok()) return s;
  auto o = ctx_.store->Get(request->id(), /*with_mesh=*/true);
  if (!o.ok()) return StoreError(o.error(), request->id());
  std::string data, type;
  switch (request->format()) {
    case v1::EXPORT_FORMAT_VTU: data = WriteVtu(o->mesh), type = "model/vnd.vtu+xml"; break;
    case v1::EXPORT_FORMAT_OBJ: data = mesh::SurfaceToObj(o->mesh), type = "model/obj"; break;
    case v1::EXPORT_FORMAT_PLY: data = mesh::SurfaceToPly(o->mesh), type = "model/ply"; break;
    case v1::EXPORT_FORMAT_STL: data = mesh::SurfaceToStl(o->mesh), type = "model/stl"; break;
    case v1::EXPORT_FORMAT_SVG: data = o->triangulation_svg, type = "image/svg+xml"; break;
    case v1::EXPORT_FORMAT_SKETCH:
      data = o->sketch;
      type = o->sketch_kind == "strokes" ? "application/json" : "application/octet-stream";
      break;
    case v1::EXPORT_FORMAT_BACKGROUND:
      if (o->background.empty())
        return ToGrpc(NotFound("object " + o->id + " has no background image"));
      data = o->background, type = "application/octet-stream";
      break;
    default:
      return ToGrpc(
          InvalidArgument("format must be one of VTU, OBJ, PLY, STL, SVG, SKETCH, "
                          "BACKGROUND"));
  }
  constexpr size_t kChunk = 1 << 20;
  for (size_t pos = 0; pos < data.size() || pos == 0; pos += kChunk) {
    v1::ExportChunk c;
    if (pos == 0) c.set_media_type(type);
    c.set_data(data.substr(pos, kChunk));
    if (!writer->Write(c)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
    slot.Touch();
    if (data.empty()) break;
  }
  return grpc::Status::OK;
}

}  // namespace rheo::daemon
