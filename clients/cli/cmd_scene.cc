// `rheoctl scene show|add|remove|pause|resume|reset|step`: what is simulated, and run control.
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <utility>

#include "rheo/v1/scene.grpc.pb.h"
#include "rheoctl.h"

namespace rheoctl {
namespace {

int SceneShow(const Global& g) {
  rheo::v1::Scene scene;
  grpc::Status s = Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::GetScene,
                                                 rheo::v1::GetSceneRequest(), &scene);
  if (!s.ok()) return Fail(s);
  std::cout << ToJson(scene, true);
  return 0;
}

int SceneAdd(const Global& g, const std::string& id, const std::string& preset,
             const std::string& integrator, const std::string& multi_rate,
             const std::vector<double>& at, const std::vector<std::string>& sets) {
  rheo::v1::AddToSceneRequest req;
  req.set_object_id(id);
  req.set_preset(preset);
  if (multi_rate == "off") req.set_multi_rate(rheo::v1::MULTI_RATE_MODE_OFF);
  if (multi_rate == "on") req.set_multi_rate(rheo::v1::MULTI_RATE_MODE_ON);
  if (integrator == "explicit") req.set_integrator(rheo::v1::INTEGRATOR_SYMPLECTIC_EULER);
  if (integrator == "implicit") req.set_integrator(rheo::v1::INTEGRATOR_IMPLICIT);
  if (at.size() == 3) {
    req.mutable_position()->set_x(at[0]);
    req.mutable_position()->set_y(at[1]);
    req.mutable_position()->set_z(at[2]);
  }
  if (!ParseAssignments(sets, req.mutable_overrides())) return 3;
  rheo::v1::SceneObject o;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::AddToScene, req, &o, 30.0);
  if (!s.ok()) return Fail(s);
  std::printf("instance %u: %s as %s, %s integrator, about %.0f us a tick\n", o.instance_id(),
              o.object_id().c_str(), o.preset().c_str(),
              o.integrator() == rheo::v1::INTEGRATOR_IMPLICIT ? "implicit" : "symplectic Euler",
              o.predicted_tick_us());
  if (o.has_multi_rate()) {
    const rheo::v1::MultiRate& m = o.multi_rate();
    std::printf(
        "  multi-rate: the %u nodes nearest the tool (%u tets) every tick; the whole every %u "
        "ticks, about %.1f ms a step%s\n",
        m.patch_inner_nodes(), m.patch_tets(), m.period_ticks(), m.predicted_whole_step_ms(),
        m.predicted_whole_step_ms() > m.period_ticks() ? " (longer than its period: the whole will "
                                                         "run behind real time)"
                                                       : "");
  }
  return 0;
}

int SceneRemove(const Global& g, uint32_t instance) {
  rheo::v1::RemoveFromSceneRequest req;
  req.set_instance_id(instance);
  rheo::v1::RemoveFromSceneResponse r;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::RemoveFromScene, req, &r);
  return s.ok() ? 0 : Fail(s);
}

int SceneControl(const Global& g, rheo::v1::RunCommand cmd) {
  rheo::v1::ControlRequest req;
  req.set_command(cmd);
  rheo::v1::ControlResponse r;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::Control, req, &r);
  if (!s.ok()) return Fail(s);
  std::printf("%s at t = %.3f s\n", r.paused() ? "paused" : "running", r.sim_time());
  return 0;
}

}  // namespace

void AddSceneCommand(CLI::App& app, const Global& g) {
  struct SceneArgs {
    std::string id, preset, integrator, multi_rate = "auto";
    std::vector<double> at;
    std::vector<std::string> sets;
    uint32_t instance = 0;
  };
  auto a = std::make_shared<SceneArgs>();
  auto* scene = app.add_subcommand("scene", "what is simulated, and run control");
  scene->require_subcommand(1);
  auto* scene_show = scene->add_subcommand("show", "objects in the scene with their parameters");
  scene_show->callback([&g] { g_exit_code = SceneShow(g); });
  auto* scene_add = scene->add_subcommand("add", "add a stored object to the scene");
  scene_add->add_option("ID", a->id, "stored object id")->required();
  scene_add->add_option("--preset", a->preset, "soft-jelly, hard-jelly, clay, organ");
  scene_add
      ->add_option("--integrator", a->integrator, "explicit or implicit (default: the preset's)")
      ->check(CLI::IsMember({"explicit", "implicit"}));
  scene_add
      ->add_option("--multi-rate", a->multi_rate,
                   "auto: step the region near the tool every tick and the whole at its own "
                   "rate when the object does not fit the tick; off: refuse it then; on: always")
      ->check(CLI::IsMember({"auto", "off", "on"}));
  scene_add->add_option("--at", a->at, "centre of the rest shape: x y z [m]")->expected(3);
  scene_add->add_option("--set", a->sets, "parameter overrides name=value");
  scene_add->callback([&g, a] {
    g_exit_code = SceneAdd(g, a->id, a->preset, a->integrator, a->multi_rate, a->at, a->sets);
  });
  auto* scene_remove = scene->add_subcommand("remove", "remove an instance from the scene");
  scene_remove->add_option("INSTANCE", a->instance)->required();
  scene_remove->callback([&g, a] { g_exit_code = SceneRemove(g, a->instance); });
  const std::pair<const char*, const char*> controls[] = {
      {"pause", "stop simulated time (the loop keeps ticking)"},
      {"resume", "restart simulated time"},
      {"reset", "every object back to its rest shape, time 0"},
      {"step", "advance a paused scene by one tick"},
  };
  const rheo::v1::RunCommand commands[] = {rheo::v1::RUN_COMMAND_PAUSE,
                                           rheo::v1::RUN_COMMAND_RESUME,
                                           rheo::v1::RUN_COMMAND_RESET, rheo::v1::RUN_COMMAND_STEP};
  for (int k = 0; k < 4; ++k) {
    const rheo::v1::RunCommand cmd = commands[k];
    scene->add_subcommand(controls[k].first, controls[k].second)->callback([&g, cmd] {
      g_exit_code = SceneControl(g, cmd);
    });
  }
}

}  // namespace rheoctl
