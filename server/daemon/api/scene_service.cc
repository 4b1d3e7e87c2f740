// SceneService: objects into and out of the loop, material parameters, run control.
#include <algorithm>

#include "common/format.h"
#include "daemon/api/convert.h"
#include "daemon/api/grpc_status.h"
#include "daemon/api/limits.h"
#include "daemon/api/recording_service.h"
#include "daemon/api/services.h"
#include "daemon/device/tool_placement.h"
#include "daemon/replay/player.h"
#include "sim/cost.h"
#include "sim/multirate.h"
#include "sim/sim.h"

namespace rheo::daemon {
namespace {

// The solver settings the 1 kHz loop takes: tighter than the simulation library's own ranges
// (which serve offline runs too), so that no single setting can starve the loop. The cost check
// below covers the combinations.
struct LoopRange {
  const char* name;
  double sim::Parameters::*field;
  double min;
  double max;
};
constexpr LoopRange kLoopRanges[] = {
    {"max_substeps", &sim::Parameters::max_substeps, 1.0, 256.0},
    {"implicit_substeps", &sim::Parameters::implicit_substeps, 1.0, 16.0},
    {"cg_max_iterations", &sim::Parameters::cg_max_iterations, 1.0, 200.0},
    {"cg_tolerance", &sim::Parameters::cg_tolerance, 1e-10, 1.0},
};

// Ticks per whole step of a multi-rate object when its whole keeps up (100 Hz at a 1 ms tick):
// the hand force within 0.27-0.44 N RMS of the full solve's at 4.6k tets
// (bench/sim/results/multirate.txt, N = 10).
constexpr int32_t kMultiRatePeriod = 10;
// Each multi-rate object's whole steps on a thread of its own.
constexpr int kMaxMultiRateObjects = 1;

double TickSeconds(const DaemonContext& ctx) {
  return static_cast<double>(ctx.engine->loop().options().period_ns) * 1e-9;
}

// Admission by cost: refuses a change whose predicted simulation time per tick, with the rest
// of the scene's, would not fit the loop's budget.
Status CheckFitsTheTick(const DaemonContext& ctx, const sim::Model& model,
                        const sim::TickCost& cost, sim::Integrator integrator, double others_ns,
                        const char* what) {
  if (cost.ns + others_ns <= ctx.sim_budget_ns) return Status::Ok();
  const double tick_ms = TickSeconds(ctx) * 1e3;
  std::string msg = std::string(what) + " would take about " + Fixed(cost.ns * 1e-6, 2) +
                    " ms of simulation in each " + Num(tick_ms) + " ms tick (" +
                    sim::DescribeTickCost(model, cost, integrator) + ")";
  if (others_ns > 0.0)
    msg += ", on top of the " + Fixed(others_ns * 1e-6, 2) + " ms the rest of the scene takes";
  msg += "; the simulation has " + Fixed(ctx.sim_budget_ns * 1e-6, 2) +
         " ms of each tick (--sim-budget). Mesh the object coarser (a larger resolution), or "
         "ask for fewer substeps, fewer CG iterations or a looser cg_tolerance";
  return ResourceExhausted(msg);
}

}  // namespace

Status ApplyParameterList(sim::Parameters& p,
                          const google::protobuf::RepeatedPtrField<v1::Parameter>& list) {
  for (const v1::Parameter& q : list)
    if (Status s = sim::SetParameterByName(p, q.name(), q.value()); !s.ok()) return s;
  if (Status s = sim::ValidateParameters(p); !s.ok()) return s;
  for (const LoopRange& r : kLoopRanges) {
    const double v = p.*r.field;
    if (!(v >= r.min && v <= r.max))
      return InvalidArgument("parameter '" + std::string(r.name) + "' = " + Num(v) +
                             " is out of the range the 1 kHz loop takes, [" + Num(r.min) + ", " +
                             Num(r.max) + "]");
  }
  return Status::Ok();
}

grpc::Status SceneServiceImpl::GetScene(grpc::ServerContext*, const v1::GetSceneRequest* req,
                                        v1::Scene* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  out->set_paused(ctx_.engine->paused());
  out->set_sim_time(ctx_.engine->sim_time());
  sim::Parameters defaults;
  out->set_gravity(defaults.gravity);
  out->set_floor_height(defaults.floor_height);
  auto entries = ctx_.scene->All();
  // Sleeping as the latest frame has it (the hub keeps one at least every 100 ms).
  std::shared_ptr<const FrameSnapshot> snap;
  if (!entries.empty())
    snap = ctx_.hub->WaitNewer(0, std::chrono::steady_clock::now() + std::chrono::seconds(1),
                               [] { return false; });
  // FillSceneObject reads a multi-rate object's counters: no object leaves the scene meanwhile.
  std::lock_guard<std::mutex> mutation(ctx_.scene->mutation_mutex());
  for (const auto& e : entries) {
    if (!ctx_.scene->Find(e->instance_id)) continue;  // removed since
    bool sleeping = false, unstable = false;
    for (uint32_t i = 0; snap && i < snap->frame.object_count; ++i)
      if (snap->frame.objects[i].instance_id == e->instance_id) {
        sleeping = snap->frame.objects[i].sleeping;
        unstable = snap->frame.objects[i].unstable;
      }
    FillSceneObject(*e, sleeping, unstable, out->add_objects());
    out->set_gravity(e->params.gravity);
    out->set_floor_height(e->params.floor_height);
  }
  return grpc::Status::OK;
}

grpc::Status SceneServiceImpl::AddToScene(grpc::ServerContext*, const v1::AddToSceneRequest* req,
                                          v1::SceneObject* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  return AddObjectToScene(ctx_, *req, /*fresh=*/nullptr, out);
}

grpc::Status AddObjectToScene(const DaemonContext& ctx_, const v1::AddToSceneRequest& request,
                              const TetMesh* fresh, v1::SceneObject* out) {
  const v1::AddToSceneRequest* req = &request;
  if (grpc::Status s = RefuseWhilePlayingBack(ctx_, "an object added"); !s.ok()) return s;
  if (req->object_id().empty()) return ToGrpc(InvalidArgument("object_id is empty"));
  const std::string preset_name = req->preset().empty() ? "soft-jelly" : req->preset();
  auto preset = sim::FindPreset(preset_name);
  if (!preset.ok()) return ToGrpc(preset.error());
  sim::Parameters params = preset->params;
  if (Status s = ApplyParameterList(params, req->overrides()); !s.ok()) return ToGrpc(s.error());
  sim::Integrator integrator = preset->integrator;
  switch (req->integrator()) {
    case v1::INTEGRATOR_SYMPLECTIC_EULER: integrator = sim::Integrator::kSymplecticEuler; break;
    case v1::INTEGRATOR_IMPLICIT: integrator = sim::Integrator::kImplicitEuler; break;
    case v1::INTEGRATOR_UNSPECIFIED: break;
    default: return ToGrpc(InvalidArgument("integrator must be SYMPLECTIC_EULER or IMPLICIT"));
  }
  // A mesh just built by CreateObject is used as it is; otherwise it comes from the store.
  Result<StoredObject> stored = StoredObject{};
  if (!fresh) {
    stored = ctx_.store->Get(req->object_id(), /*with_mesh=*/true);
    if (!stored.ok()) return ToGrpc(stored.error());
  }
  const TetMesh& mesh = fresh ? *fresh : stored->mesh;

  std::lock_guard<std::mutex> mutation(ctx_.scene->mutation_mutex());
  if (ctx_.scene->size() >= static_cast<size_t>(kMaxSceneObjects))
    return ToGrpc(ResourceExhausted("the scene holds its limit of " +
                                    std::to_string(kMaxSceneObjects) + " objects"));
  const uint64_t n = mesh.positions.size();
  if (ctx_.scene->total_vertices() + n > ctx_.engine->options().max_frame_vertices)
    return ToGrpc(ResourceExhausted(
        "adding " + std::to_string(n) + " vertices would pass the scene's limit of " +
        std::to_string(ctx_.engine->options().max_frame_vertices) + " vertices"));

  // Placement: the rest shape's bounding-box centre goes to `position`; by default the object
  // stands centred over the origin, 2 cm above the floor. The object is built on the placed
  // mesh, exactly the positions the session recording keeps (SceneMesh.rest_positions), so
  // that a replay builds the same object bit for bit.
  const Vec3 target = req->has_position()
                          ? Vec3(req->position().x(), req->position().y(), req->position().z())
                          : DefaultPlacement(mesh, params.floor_height);
  if (!target.allFinite()) return ToGrpc(InvalidArgument("position has a non-finite coordinate"));
  TetMesh placed = mesh;
  const Vec3 shift = PlacementShift(mesh, target);
  for (Vec3& x : placed.positions) x += shift;
  auto created = sim::SimObject::Create(placed, params, integrator);
  if (!created.ok()) return ToGrpc(created.error());
  std::unique_ptr<sim::SimObject> object = std::move(created).value();
  // Will it fit the tick, with what the scene already runs? When the client left the
  // integrator to the daemon and the preset's would not fit (symplectic Euler on a fine or stiff
  // object needs many substeps), the implicit integrator is taken if it does.
  const double others_ns = ctx_.scene->predicted_ns();
  auto predict = [&](sim::Integrator with,
                     sim::PreparedParameters* prepared_out) -> Result<sim::TickCost> {
    auto prepared = object->Prepare(params, with, TickSeconds(ctx_));
    if (!prepared.ok()) return prepared.error();
    const sim::TickCost c =
        sim::PredictTickCost(object->model(), *prepared, with, TickSeconds(ctx_), ctx_.tick_cost);
    if (prepared_out) *prepared_out = std::move(prepared).value();
    return c;
  };
  auto cost = predict(integrator, nullptr);
  if (!cost.ok()) return ToGrpc(cost.error());
  if (req->integrator() == v1::INTEGRATOR_UNSPECIFIED &&
      integrator == sim::Integrator::kSymplecticEuler &&
      cost->ns + others_ns > ctx_.sim_budget_ns) {
    sim::PreparedParameters prepared;
    auto implicit = predict(sim::Integrator::kImplicitEuler, &prepared);
    if (implicit.ok() && implicit->ns < cost->ns) {
      integrator = sim::Integrator::kImplicitEuler;
      object->SetIntegrator(integrator);
      if (Status s = object->SetParameters(prepared); !s.ok()) return ToGrpc(s.error());
      cost = implicit;
    }
  }
  // Multi-rate: by default only when the full step does not fit the tick.
  const v1::MultiRateMode mode = req->multi_rate();
  if (mode != v1::MULTI_RATE_MODE_AUTO && mode != v1::MULTI_RATE_MODE_OFF &&
      mode != v1::MULTI_RATE_MODE_ON)
    return ToGrpc(InvalidArgument("multi_rate must be AUTO, OFF or ON"));
  const bool fits = cost->ns + others_ns <= ctx_.sim_budget_ns;
  bool multi = mode == v1::MULTI_RATE_MODE_ON || (mode == v1::MULTI_RATE_MODE_AUTO && !fits);
  if (multi && integrator == sim::Integrator::kSymplecticEuler) {
    if (req->integrator() == v1::INTEGRATOR_UNSPECIFIED) {
      sim::PreparedParameters prepared;
      auto implicit = predict(sim::Integrator::kImplicitEuler, &prepared);
      if (!implicit.ok()) return ToGrpc(implicit.error());
      integrator = sim::Integrator::kImplicitEuler;
      object->SetIntegrator(integrator);
      if (Status s = object->SetParameters(prepared); !s.ok()) return ToGrpc(s.error());
      cost = implicit;
    } else if (mode == v1::MULTI_RATE_MODE_ON) {
      return ToGrpc(InvalidArgument(
          "multi_rate ON needs the implicit integrator (an explicit whole step over many ticks "
          "costs as many substeps as the ticks it covers); ask for INTEGRATOR_IMPLICIT"));
    } else {
      multi = false;  // asked for the explicit integrator: refused by cost below
    }
  }
  if (!multi) {
    if (Status s =
            CheckFitsTheTick(ctx_, object->model(), *cost, integrator, others_ns, "this object");
        !s.ok())
      return ToGrpc(s.error());
  }

  std::vector<uint32_t> triangles;
  triangles.reserve(mesh.surface.size() * 3);
  for (const auto& f : mesh.surface)
    for (int32_t v : f) triangles.push_back(static_cast<uint32_t>(v));

  // The haptic side (off the loop): the object's renderer, and for the first object of an empty
  // scene the device's workspace placed over it.
  std::unique_ptr<ObjectContact> contact;
  Vec3 contact_tool = Vec3::Zero();
  if (ctx_.device_link) {
    auto attached = ctx_.device_link->PrepareObject(mesh.surface, triangles, object->positions(),
                                                    object->model().mass, ctx_.scene->size() == 0,
                                                    ctx_.engine->tool());
    if (!attached.ok()) return ToGrpc(attached.error());
    if (attached->sets_origin) {
      Command oc;
      oc.type = Command::Type::kSetToolOrigin;
      oc.vec = {attached->tool_origin.x(), attached->tool_origin.y(), attached->tool_origin.z()};
      if (ctx_.engine->Submit(oc) == 0) return QueueFull();
    }
    contact = std::move(attached->contact);
    contact_tool = attached->tool;
  }

  // Multi-rate: the patch around the press point is built here to predict the loop's part; the
  // whole's step is predicted for its period.
  std::unique_ptr<MultiRateObject> multirate;
  std::shared_ptr<const sim::Patch> probe;
  sim::TickCost whole_cost;
  if (multi) {
    if (ctx_.scene->multirate_count() >= kMaxMultiRateObjects)
      return ToGrpc(ResourceExhausted(
          "one object at a time runs multi-rate (its whole steps on a core of its own) and the "
          "scene has one; remove it first, or mesh this object coarser so that it fits the tick "
          "(" +
          Fixed(cost->ns * 1e-6, 2) + " ms of the " + Fixed(ctx_.sim_budget_ns * 1e-6, 2) +
          " ms budget)"));
    const double tick = TickSeconds(ctx_);
    sim::PatchOptions po;
    po.tick = tick;
    // The whole's substeps are the loop's own tick, the step every preset is tuned for, when the
    // whole keeps up with real time at it; otherwise sim::kBehindWholeSubstep (chosen below, once
    // the whole's step is predicted).
    po.whole_substep = tick;
    const Vec3 focus = PressPoint(triangles, object->positions());
    auto patch = sim::Patch::Build(*object, focus, po);
    if (!patch.ok()) return ToGrpc(patch.error());
    probe = std::make_shared<const sim::Patch>(std::move(*patch));
    auto patch_prepared = probe->object().Prepare(object->parameters(), integrator, tick);
    if (!patch_prepared.ok()) return ToGrpc(patch_prepared.error());
    *cost = sim::PredictTickCost(probe->object().model(), *patch_prepared, integrator, tick,
                                 ctx_.tick_cost);
    if (Status s = CheckFitsTheTick(ctx_, probe->object().model(), *cost, integrator, others_ns,
                                    "this object's patch (multi-rate)");
        !s.ok())
      return ToGrpc(s.error());
    // The whole's step over the period, with the substeps MultiRate gives it.
    const double period_s = kMultiRatePeriod * tick;
    auto predict_whole = [&]() -> Result<sim::TickCost> {
      const sim::Parameters wp =
          sim::MultiRate::WholeParameters(object->parameters(), kMultiRatePeriod, po);
      auto whole_prepared = object->Prepare(wp, integrator, period_s);
      if (!whole_prepared.ok()) return whole_prepared.error();
      return sim::PredictTickCost(object->model(), *whole_prepared, integrator, period_s,
                                  ctx_.tick_cost);
    };
    auto predicted = predict_whole();
    if (!predicted.ok()) return ToGrpc(predicted.error());
    if (predicted->ns > period_s * 1e9 && sim::kBehindWholeSubstep > tick) {
      po.whole_substep = sim::kBehindWholeSubstep;
      predicted = predict_whole();
      if (!predicted.ok()) return ToGrpc(predicted.error());
    }
    whole_cost = *predicted;
    auto created_mr = MultiRateObject::Create(std::move(object), kMultiRatePeriod, po, focus);
    if (!created_mr.ok()) return ToGrpc(created_mr.error());
    multirate = std::move(created_mr).value();
  }

  auto entry = std::make_shared<SceneEntry>();
  entry->instance_id = ctx_.scene->NextId();
  entry->object_id = req->object_id();
  entry->preset = preset_name;
  entry->integrator = integrator;
  entry->params = params;
  entry->vertex_count = static_cast<uint32_t>(n);
  entry->position = target;
  entry->cost = *cost;
  entry->object = multirate ? &multirate->whole() : object.get();
  entry->multirate = multirate.get();
  entry->patch_probe = probe;
  entry->multirate_period = multirate ? kMultiRatePeriod : 0;
  entry->whole_cost = whole_cost;
  entry->triangles = std::move(triangles);
  if (contact) {
    entry->has_contact = true;
    entry->contact_config = ctx_.device_link->renderer_config();
    entry->contact_tool = contact_tool;
  }
  ctx_.scene->Put(entry);

  Command c;
  c.type = Command::Type::kAddObject;
  c.instance_id = entry->instance_id;
  c.object = object.get();
  c.multirate = multirate.get();
  c.contact = contact.get();
  uint64_t seq = ctx_.engine->Submit(c);
  if (seq == 0) {
    ctx_.scene->Erase(entry->instance_id);
    return QueueFull();
  }
  object.release();  // the loop owns it now
  multirate.release();
  contact.release();
  if (!ctx_.engine->WaitApplied(seq, kApplyTimeoutNs)) return NotApplied("object");
  FillSceneObject(*entry, false, false, out);
  RecordSceneAdded(ctx_, *entry, mesh, seq);
  return grpc::Status::OK;
}

grpc::Status SceneServiceImpl::RemoveFromScene(grpc::ServerContext*,
                                               const v1::RemoveFromSceneRequest* req,
                                               v1::RemoveFromSceneResponse*) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (grpc::Status s = RefuseWhilePlayingBack(ctx_, "an object removed"); !s.ok()) return s;
  std::lock_guard<std::mutex> mutation(ctx_.scene->mutation_mutex());
  const auto entry = ctx_.scene->Find(req->instance_id());
  if (!entry)
    return ToGrpc(
        NotFound("no scene object with instance_id " + std::to_string(req->instance_id())));
  Command c;
  c.type = Command::Type::kRemoveObject;
  c.instance_id = req->instance_id();
  uint64_t seq = 0;
  if (grpc::Status s = SubmitAndWait(*ctx_.engine, c, &seq); !s.ok()) return s;
  ctx_.scene->Erase(req->instance_id());
  RecordSceneRemoved(ctx_, *entry, seq);
  return grpc::Status::OK;
}

grpc::Status SceneServiceImpl::SetParameters(grpc::ServerContext*,
                                             const v1::SetParametersRequest* req,
                                             v1::SetParametersResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (grpc::Status s = RefuseWhilePlayingBack(ctx_, "a parameter change"); !s.ok()) return s;
  std::lock_guard<std::mutex> mutation(ctx_.scene->mutation_mutex());
  std::vector<std::shared_ptr<const SceneEntry>> targets;
  if (req->instance_id() == 0) {
    targets = ctx_.scene->All();
    if (targets.empty())
      return ToGrpc(FailedPrecondition("the scene is empty; add an object first (AddToScene)"));
  } else {
    auto e = ctx_.scene->Find(req->instance_id());
    if (!e)
      return ToGrpc(
          NotFound("no scene object with instance_id " + std::to_string(req->instance_id())));
    targets.push_back(e);
  }
  // Validate and prepare everything first: nothing changes unless every target's parameters are
  // valid. What they imply (the step bound, the shape springs' split) is worked out here, not on
  // the loop: it takes passes over every element (about 4 ms for 19k tets).
  const double tick = static_cast<double>(ctx_.engine->loop().options().period_ns) * 1e-9;
  std::vector<std::shared_ptr<SceneEntry>> updated;
  std::vector<sim::PreparedParameters> prepared;
  for (const auto& e : targets) {
    auto next = std::make_shared<SceneEntry>(*e);
    if (!req->preset().empty()) {
      auto preset = sim::FindPreset(req->preset());
      if (!preset.ok()) return ToGrpc(preset.error());
      next->params = preset->params;
      next->preset = req->preset();
    }
    if (Status s = ApplyParameterList(next->params, req->parameters()); !s.ok())
      return ToGrpc(s.error());
    if (next->patch_probe) {
      // Multi-rate: the loop's part is the patch; the whole's thread recomputes what the
      // parameters imply for the whole when it takes them in, so only they travel.
      const sim::SimObject& patch = next->patch_probe->object();
      auto ready = patch.Prepare(next->params, next->integrator, tick);
      if (!ready.ok()) return ToGrpc(ready.error());
      next->cost =
          sim::PredictTickCost(patch.model(), *ready, next->integrator, tick, ctx_.tick_cost);
      sim::PreparedParameters only;
      only.params = next->params;
      prepared.push_back(std::move(only));
      updated.push_back(std::move(next));
      continue;
    }
    auto ready = next->object->Prepare(next->params, next->integrator, tick);
    if (!ready.ok()) return ToGrpc(ready.error());
    next->cost =
        sim::PredictTickCost(next->object->model(), *ready, next->integrator, tick, ctx_.tick_cost);
    prepared.push_back(std::move(ready).value());
    updated.push_back(std::move(next));
  }
  // The whole scene after the change must fit the tick.
  double after_ns = 0.0;
  for (const auto& e : ctx_.scene->All()) {
    bool changed = false;
    for (const auto& u : updated) changed = changed || u->instance_id == e->instance_id;
    if (!changed) after_ns += e->cost.ns;
  }
  for (const auto& u : updated) {
    const double others = after_ns;
    after_ns += u->cost.ns;
    const sim::Model& model =
        u->patch_probe ? u->patch_probe->object().model() : u->object->model();
    if (Status s = CheckFitsTheTick(ctx_, model, u->cost, u->integrator, others,
                                    updated.size() == 1 ? "this change" : "these changes");
        !s.ok())
      return ToGrpc(s.error());
  }
  for (size_t k = 0; k < updated.size(); ++k) {
    const auto& next = updated[k];
    Command c;
    c.type = Command::Type::kSetParameters;
    c.instance_id = next->instance_id;
    c.params = new sim::PreparedParameters(std::move(prepared[k]));
    uint64_t seq = ctx_.engine->Submit(c);
    if (seq == 0) {
      delete c.params;
      return QueueFull();
    }
    ctx_.scene->Put(next);
    if (!ctx_.engine->WaitApplied(seq, kApplyTimeoutNs)) return NotApplied("change");
    RecordParameters(ctx_, *next, seq);
  }
  FillParameters(updated.front()->params, out->mutable_parameters());
  return grpc::Status::OK;
}

grpc::Status SceneServiceImpl::ListParameters(grpc::ServerContext*,
                                              const v1::ListParametersRequest* req,
                                              v1::ListParametersResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  sim::Parameters p;
  if (req->instance_id() != 0) {
    auto e = ctx_.scene->Find(req->instance_id());
    if (!e)
      return ToGrpc(
          NotFound("no scene object with instance_id " + std::to_string(req->instance_id())));
    p = e->params;
  } else if (auto preset = sim::FindPreset("soft-jelly"); preset.ok()) {
    p = preset->params;
  }
  FillParameters(p, out->mutable_parameters());
  for (const sim::Preset& preset : sim::Presets()) out->add_presets(preset.name);
  return grpc::Status::OK;
}

grpc::Status SceneServiceImpl::Control(grpc::ServerContext*, const v1::ControlRequest* request,
                                       v1::ControlResponse* out) {
  if (grpc::Status s = CheckRequest(*request); !s.ok()) return s;
  if (ctx_.player) {
    // Played back: pause, resume and step act on the playback, reset goes to its start.
    RecordingPlayer& p = *ctx_.player;
    switch (request->command()) {
      case v1::RUN_COMMAND_PAUSE: p.SetPaused(true); break;
      case v1::RUN_COMMAND_RESUME: p.SetPaused(false); break;
      case v1::RUN_COMMAND_RESET: p.Seek(0.0); break;
      case v1::RUN_COMMAND_STEP:
        if (grpc::Status s = StepPlayback(ctx_); !s.ok()) return s;
        break;
      default:
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                            "command must be PAUSE, RESUME, RESET or STEP");
    }
    const PlaybackState st = p.state();
    out->set_paused(st.paused);
    out->set_sim_time(st.position_s);
    return grpc::Status::OK;
  }
  Command c;
  switch (request->command()) {
    case v1::RUN_COMMAND_PAUSE: c.type = Command::Type::kPause; break;
    case v1::RUN_COMMAND_RESUME: c.type = Command::Type::kResume; break;
    case v1::RUN_COMMAND_RESET: c.type = Command::Type::kReset; break;
    case v1::RUN_COMMAND_STEP:
      if (!ctx_.engine->paused())
        return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                            "STEP advances one tick of a paused scene; pause it first");
      c.type = Command::Type::kStep;
      break;
    default:
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "command must be PAUSE, RESUME, RESET or STEP");
  }
  if (grpc::Status s = SubmitAndWait(*ctx_.engine, c); !s.ok()) return s;
  out->set_paused(ctx_.engine->paused());
  out->set_sim_time(ctx_.engine->sim_time());
  return grpc::Status::OK;
}

}  // namespace rheo::daemon
