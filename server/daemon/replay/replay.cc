#include "daemon/replay/replay.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <optional>

#include "daemon/device/tool_contact.h"
#include "daemon/loop/engine.h"
#include "record/mcap.h"
#include "rheo/v1/frames.pb.h"
#include "rheo/v1/recording.pb.h"
#include "sim/params.h"
#include "sim/sim.h"

namespace rheo::daemon {
namespace {

Vec3 ToVec(const v1::Vec3& v) {
  return Vec3(v.x(), v.y(), v.z());
}

std::string ObjectName(uint32_t instance_id) {
  return "object #" + std::to_string(instance_id);
}

// The tool as the recording saw it, fed to the loop's own contact code.
class ReplayTool final : public TickDevice {
 public:
  void SetSample(const v1::ToolSample* s) { sample_ = s; }
  void Tick(const rt::TickInfo& info, std::span<EngineSlot> slots, ToolTelemetry* out) override {
    *out = ToolTelemetry{};
    if (!sample_ || !sample_->present()) return;
    const Vec3 position = ToVec(sample_->device_pose().position());
    const Vec3 velocity = ToVec(sample_->device_velocity());
    const ContactTick c =
        contact_.Update(slots, position, velocity, info.dt, sample_->object_loaded());
    out->present = true;
    out->in_contact = c.in_contact;
    out->contact_instance = c.instance_id;
    out->proxy = {c.proxy.x(), c.proxy.y(), c.proxy.z()};
    out->object_force = {c.object_force.x(), c.object_force.y(), c.object_force.z()};
    out->renderer_errors = c.renderer_error ? 1 : 0;
  }
  void Apply(const Command&) override {}  // the recorded pose already holds the tool origin
  void Forget(const EngineSlot& slot) override { contact_.Forget(slot); }

 private:
  const v1::ToolSample* sample_ = nullptr;
  ToolContact contact_;
};

Command::Type CommandType(v1::AppliedCommand::Type t) {
  using T = v1::AppliedCommand;
  switch (t) {
    case T::TYPE_PAUSE: return Command::Type::kPause;
    case T::TYPE_RESUME: return Command::Type::kResume;
    case T::TYPE_RESET: return Command::Type::kReset;
    case T::TYPE_STEP: return Command::Type::kStep;
    case T::TYPE_ADD_OBJECT: return Command::Type::kAddObject;
    case T::TYPE_REMOVE_OBJECT: return Command::Type::kRemoveObject;
    case T::TYPE_SET_PARAMETERS: return Command::Type::kSetParameters;
    case T::TYPE_DEVICE_CALIBRATE: return Command::Type::kDeviceCalibrate;
    case T::TYPE_DEVICE_CLEAR: return Command::Type::kDeviceClear;
    case T::TYPE_SET_TOOL_ORIGIN: return Command::Type::kSetToolOrigin;
    default: return Command::Type::kNone;
  }
}

// A preset's parameters with the recorded list over them, then the what-if values.
Result<sim::Parameters> BuildParameters(
    const std::string& preset, const google::protobuf::RepeatedPtrField<v1::Parameter>& list,
    const ReplayOptions& options, uint32_t instance_id) {
  auto p = sim::FindPreset(preset.empty() ? "soft-jelly" : preset);
  if (!p.ok()) return Error{p.error().code, ObjectName(instance_id) + ": " + p.error().message};
  sim::Parameters params = p->params;
  for (const v1::Parameter& q : list)
    if (Status s = sim::SetParameterByName(params, q.name(), q.value()); !s.ok())
      return Error{s.error().code, ObjectName(instance_id) + ": " + s.error().message};
  for (const auto& [name, value] : options.set)
    if (Status s = sim::SetParameterByName(params, name, value); !s.ok())
      return Error{s.error().code, "--set " + name + ": " + s.error().message};
  return params;
}

struct Built {
  std::unique_ptr<sim::SimObject> object;
  std::unique_ptr<ObjectContact> contact;
};

// An object as AddToScene built it: on the placed mesh, with its preset, integrator and
// parameters, and its renderer from the recorded configuration.
Result<Built> BuildObject(const v1::SceneEvent& ev, const ReplayOptions& options) {
  const v1::SceneObject& so = ev.object();
  const v1::SceneMesh& m = ev.mesh();
  const uint32_t id = so.instance_id();
  if (m.rest_positions_size() == 0 || m.rest_positions_size() % 3 != 0 ||
      m.tetrahedra_size() % 4 != 0 || m.triangles_size() % 3 != 0)
    return InvalidArgument(ObjectName(id) + " has no complete mesh in the recording");
  TetMesh mesh;
  mesh.positions.resize(m.rest_positions_size() / 3);
  for (size_t i = 0; i < mesh.positions.size(); ++i)
    mesh.positions[i] =
        Vec3(m.rest_positions(3 * i), m.rest_positions(3 * i + 1), m.rest_positions(3 * i + 2));
  const int32_t n = static_cast<int32_t>(mesh.positions.size());
  auto index = [n](uint32_t v) { return static_cast<int32_t>(std::min<uint32_t>(v, n)); };
  mesh.tets.resize(m.tetrahedra_size() / 4);
  for (size_t t = 0; t < mesh.tets.size(); ++t)
    for (int k = 0; k < 4; ++k) mesh.tets[t][k] = index(m.tetrahedra(4 * t + k));
  mesh.surface.resize(m.triangles_size() / 3);
  for (size_t t = 0; t < mesh.surface.size(); ++t)
    for (int k = 0; k < 3; ++k) mesh.surface[t][k] = index(m.triangles(3 * t + k));
  auto params = BuildParameters(so.preset(), so.parameters(), options, id);
  if (!params.ok()) return params.error();
  const sim::Integrator integrator = so.integrator() == v1::INTEGRATOR_IMPLICIT
                                         ? sim::Integrator::kImplicitEuler
                                         : sim::Integrator::kSymplecticEuler;
  auto created = sim::SimObject::Create(mesh, *params, integrator);
  if (!created.ok())
    return Error{created.error().code, ObjectName(id) + ": " + created.error().message};
  Built out;
  out.object = std::move(created).value();
  if (ev.has_contact()) {
    const v1::ContactSetup& c = ev.contact();
    haptics::RendererConfig rc;
    rc.tool_radius = c.tool_radius();
    rc.coupling_stiffness = c.coupling_stiffness();
    rc.coupling_damping = c.coupling_damping();
    rc.stability_margin = c.stability_margin();
    rc.static_friction = c.static_friction();
    rc.dynamic_friction = c.dynamic_friction();
    rc.max_step = c.max_step();
    rc.max_surface_speed = c.max_surface_speed();
    rc.rebin_faces_per_tick = c.rebin_faces_per_tick();
    rc.cell_size = c.cell_size();
    rc.device.max_force = c.device_max_force();
    rc.device.max_stiffness = c.device_max_stiffness();
    rc.device.max_force_rate = c.device_max_force_rate();
    rc.device.damping = c.device_damping();
    rc.device.tick = c.device_tick();
    auto contact = MakeRendererContact(rc, mesh.surface, out.object->positions(), ToVec(c.tool()),
                                       MinSurfaceMass(mesh.surface, out.object->model().mass));
    if (!contact.ok())
      return Error{contact.error().code,
                   ObjectName(id) + ": the renderer does not build: " + contact.error().message};
    out.contact = std::move(contact).value();
  }
  return out;
}

double MaxAbs(const Vec3& a, const Vec3& b) {
  return (a - b).cwiseAbs().maxCoeff();
}

bool SameBits(const Vec3& a, const Vec3& b) {
  return std::memcmp(a.data(), b.data(), 3 * sizeof(double)) == 0;
}

}  // namespace

Result<ReplayReport> ReplayRecording(const std::string& path, const ReplayOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  auto reader = record::McapReader::OpenFile(path);
  if (!reader.ok()) return reader.error();
  ReplayReport report;
  report.file = path;
  if (reader->truncation())
    report.caveats.push_back("the file is cut off (" + reader->truncation()->reason +
                             "): replayed up to its last complete chunk");

  int64_t period_ns = 0;
  for (const auto& [id, ch] : reader->channels())
    if (ch.topic == "/tool") {
      auto it = ch.metadata.find("period_ns");
      if (it != ch.metadata.end()) period_ns = std::atoll(it->second.c_str());
    }
  if (period_ns <= 0)
    return InvalidArgument(path +
                           " has no /tool channel with its period_ns: not a rheod recording");
  const double dt = static_cast<double>(period_ns) * 1e-9;

  // Pass 1: the events (small, and logged by wall clock after the tick that applied them).
  std::vector<v1::SceneEvent> present;
  std::map<uint64_t, v1::SceneEvent> added;         // by command_seq
  std::map<uint64_t, v1::ParameterChange> changes;  // by command_seq
  uint64_t max_vertices = 0, vertices_now = 0;
  for (auto cursor = reader->Messages();;) {
    auto m = cursor.Next();
    if (!m.ok()) return m.error();
    if (!*m) break;
    const std::string& topic = (*m)->channel->topic;
    const auto data = (*m)->data;
    if (topic == "/scene") {
      v1::SceneEvent ev;
      if (!ev.ParseFromArray(data.data(), static_cast<int>(data.size())))
        return InvalidArgument(path + ": a /scene message does not parse");
      const uint64_t nv = ev.mesh().rest_positions_size() / 3;
      if (ev.kind() == v1::SceneEvent::KIND_PRESENT) {
        vertices_now += nv;
        present.push_back(std::move(ev));
      } else if (ev.kind() == v1::SceneEvent::KIND_ADDED) {
        vertices_now += nv;
        added.emplace(ev.command_seq(), std::move(ev));
      }
      max_vertices = std::max(max_vertices, vertices_now);
    } else if (topic == "/parameters") {
      v1::ParameterChange pc;
      if (!pc.ParseFromArray(data.data(), static_cast<int>(data.size())))
        return InvalidArgument(path + ": a /parameters message does not parse");
      changes.emplace(pc.command_seq(), std::move(pc));
    }
  }

  EngineOptions eo;
  eo.loop.period_ns = period_ns;
  eo.loop.realtime_priority = false;
  eo.loop.lock_memory = false;
  eo.max_frame_vertices = static_cast<uint32_t>(std::max<uint64_t>(max_vertices, 1));
  Engine engine(eo);
  ReplayTool tool;
  engine.AttachDevice(&tool);
  std::map<uint32_t, const sim::SimObject*> objects;  // by instance id, owned by the engine
  std::map<uint32_t, sim::Integrator> integrators;

  auto submit_object = [&](const v1::SceneEvent& ev) -> Status {
    const uint32_t id = ev.object().instance_id();
    if (ev.object().multi_rate().period_ticks() > 0)
      report.caveats.push_back(ObjectName(id) +
                               " ran multi-rate (its whole on a thread of its own, synced where "
                               "the machine's timing put it): replayed single-rate");
    auto built = BuildObject(ev, options);
    if (!built.ok()) return built.error();
    Command c;
    c.type = Command::Type::kAddObject;
    c.instance_id = id;
    c.object = built->object.get();
    c.contact = built->contact.get();
    if (engine.Submit(c) == 0) return Internal("the replay's command queue is full");
    objects[id] = built->object.release();
    integrators[id] = objects[id]->integrator();
    built->contact.release();
    ++report.objects;
    return Status::Ok();
  };
  for (const v1::SceneEvent& ev : present) {
    report.caveats.push_back(ObjectName(ev.object().instance_id()) +
                             " was in the scene before the recording started: replayed from its "
                             "rest shape, not from the state it was in");
    if (Status s = submit_object(ev); !s.ok()) return s.error();
  }

  // Pass 2: /tool drives the ticks; each /frames message is compared at its tick. A frame and
  // the sample of its tick share a log time, so a frame may come just before its sample.
  std::optional<v1::Frame> pending;
  uint64_t replayed_tick = 0;
  bool have_tick = false;
  auto compare_frame = [&](const v1::Frame& f) {
    const LoopFrame& lf = engine.frame();
    ++report.frames_compared;
    bool same = true;
    for (const v1::ObjectState& os : f.objects()) {
      const FrameObject* fo = nullptr;
      for (uint32_t i = 0; i < lf.object_count; ++i)
        if (lf.objects[i].instance_id == os.instance_id()) fo = &lf.objects[i];
      if (!fo || static_cast<int>(3 * fo->vertex_count) != os.positions_size()) {
        same = false;
        report.max_position_diff_m = INFINITY;
        continue;
      }
      const float* mine = lf.positions.data() + 3u * fo->first;
      for (int k = 0; k < os.positions_size(); ++k) {
        const float theirs = os.positions(k);
        if (std::memcmp(&mine[k], &theirs, sizeof(float)) != 0) same = false;
        const double d = std::abs(static_cast<double>(mine[k]) - static_cast<double>(theirs));
        if (!(d <= report.max_position_diff_m)) {
          report.max_position_diff_m = d;
          report.max_position_tick = f.stamp().tick();
        }
      }
    }
    if (static_cast<uint32_t>(f.objects_size()) != lf.object_count) same = false;
    if (same) {
      ++report.frames_identical;
    } else if (report.first_difference_tick == 0) {
      report.first_difference_tick = f.stamp().tick();
    }
  };
  auto settle_pending = [&]() {
    if (!pending || !have_tick) return;
    if (pending->stamp().tick() == replayed_tick) {
      compare_frame(*pending);
      pending.reset();
    } else if (pending->stamp().tick() < replayed_tick) {
      pending.reset();  // its tick was dropped from /tool: nothing to compare it with
    }
  };

  v1::ToolSample sample, held;
  uint64_t dropped = 0;
  auto run_tick = [&](const v1::ToolSample& s) {
    tool.SetSample(&s);
    rt::TickInfo info;
    info.tick = s.tick();
    info.dt = dt;
    engine.TickOnce(info);
    engine.AcquireFrame();
    engine.DrainRetired();
    replayed_tick = s.tick();
    have_tick = true;
    ++report.ticks;
    if (options.on_tick) options.on_tick(s.tick());
  };
  for (auto cursor = reader->Messages();;) {
    auto m = cursor.Next();
    if (!m.ok()) {
      if (reader->truncation()) break;  // the cut chunk: everything before it is replayed
      return m.error();
    }
    if (!*m) break;
    const std::string& topic = (*m)->channel->topic;
    const auto data = (*m)->data;
    if (topic == "/frames") {
      v1::Frame f;
      if (!f.ParseFromArray(data.data(), static_cast<int>(data.size())))
        return InvalidArgument(path + ": a /frames message does not parse");
      pending = std::move(f);
      settle_pending();
      continue;
    }
    if (topic != "/tool") continue;
    if (!sample.ParseFromArray(data.data(), static_cast<int>(data.size())))
      return InvalidArgument(path + ": a /tool message does not parse");
    const uint64_t tick = sample.tick();
    if (!have_tick) {
      report.first_tick = tick;
    } else if (tick > replayed_tick + 1) {
      // Ticks the ring dropped: stepped with the tool held where it last was, no commands (any
      // the loop applied there are lost with them).
      dropped += tick - replayed_tick - 1;
      held.clear_applied();
      for (uint64_t k = replayed_tick + 1; k < tick; ++k) {
        held.set_tick(k);
        run_tick(held);
        settle_pending();
      }
    }
    // The commands the loop applied at the start of this tick, in its order.
    for (const v1::AppliedCommand& a : sample.applied()) {
      Command c;
      c.type = CommandType(a.type());
      c.instance_id = a.instance_id();
      if (c.type == Command::Type::kAddObject) {
        auto it = added.find(a.command_seq());
        if (it == added.end()) {
          report.caveats.push_back(ObjectName(a.instance_id()) +
                                   " entered the scene but its /scene event is missing (the "
                                   "recorder's queue dropped it): not replayed");
          continue;
        }
        if (Status s = submit_object(it->second); !s.ok()) return s.error();
        ++report.commands;
        continue;
      }
      if (c.type == Command::Type::kSetParameters) {
        auto it = changes.find(a.command_seq());
        auto obj = objects.find(a.instance_id());
        if (it == changes.end() || obj == objects.end()) {
          report.caveats.push_back("a parameter change of " + ObjectName(a.instance_id()) +
                                   " at tick " + std::to_string(tick) +
                                   " has no /parameters event: not replayed");
          continue;
        }
        auto params =
            BuildParameters(it->second.preset(), it->second.parameters(), options, a.instance_id());
        if (!params.ok()) return params.error();
        auto prepared = obj->second->Prepare(*params, integrators[a.instance_id()], dt);
        if (!prepared.ok())
          return Error{prepared.error().code,
                       ObjectName(a.instance_id()) + ": " + prepared.error().message};
        c.params = new sim::PreparedParameters(std::move(prepared).value());
      }
      if (c.type == Command::Type::kRemoveObject) objects.erase(a.instance_id());
      if (c.type == Command::Type::kNone) continue;
      if (engine.Submit(c) == 0) {
        delete c.params;
        return Internal("the replay's command queue is full");
      }
      ++report.commands;
    }
    run_tick(sample);
    held = sample;

    // The tool: what the replay's contact gave against what the recording says it gave.
    if (sample.present()) {
      const ToolTelemetry t = engine.tool();
      const Vec3 proxy(t.proxy[0], t.proxy[1], t.proxy[2]);
      const Vec3 force(t.object_force[0], t.object_force[1], t.object_force[2]);
      const Vec3 rproxy = ToVec(sample.proxy_position()), rforce = ToVec(sample.object_force());
      ++report.samples_compared;
      report.contact_ticks += sample.in_contact();
      const bool same =
          SameBits(proxy, rproxy) && SameBits(force, rforce) && t.in_contact == sample.in_contact();
      report.max_proxy_diff_m = std::max(report.max_proxy_diff_m, MaxAbs(proxy, rproxy));
      const double df = MaxAbs(force, rforce);
      if (df > report.max_force_diff_n) {
        report.max_force_diff_n = df;
        report.max_force_tick = tick;
      }
      if (same) {
        ++report.samples_identical;
      } else if (report.first_difference_tick == 0) {
        report.first_difference_tick = tick;
      }
    }
    settle_pending();
  }
  report.last_tick = replayed_tick;
  if (!have_tick) return InvalidArgument(path + " holds no /tool sample: nothing to replay");
  if (dropped > 0)
    report.caveats.push_back(std::to_string(dropped) +
                             " ticks are missing from /tool (the recorder's ring dropped them): "
                             "stepped with the tool held at its last pose and no commands");
  report.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

}  // namespace rheo::daemon
