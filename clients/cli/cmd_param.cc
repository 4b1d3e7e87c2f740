// `rheoctl param list|set`: material parameters (they take effect on the next tick).
#include <cstdint>
#include <cstdio>

#include "rheo/v1/scene.grpc.pb.h"
#include "rheoctl.h"

namespace rheoctl {
namespace {

int ParamList(const Global& g, uint32_t instance) {
  rheo::v1::ListParametersRequest req;
  req.set_instance_id(instance);
  rheo::v1::ListParametersResponse r;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::ListParameters, req, &r);
  if (!s.ok()) return Fail(s);
  for (const auto& p : r.parameters())
    std::printf("%-18s %12.6g %-10s [%g, %g]  %s\n", p.name().c_str(), p.value(), p.unit().c_str(),
                p.min(), p.max(), p.description().c_str());
  std::printf("presets:");
  for (const auto& p : r.presets()) std::printf(" %s", p.c_str());
  std::printf("\n");
  return 0;
}

int ParamSet(const Global& g, uint32_t instance, const std::string& preset,
             const std::vector<std::string>& sets) {
  rheo::v1::SetParametersRequest req;
  req.set_instance_id(instance);
  req.set_preset(preset);
  if (!ParseAssignments(sets, req.mutable_parameters())) return 3;
  rheo::v1::SetParametersResponse r;
  grpc::Status s =
      Unary<rheo::v1::SceneService>(g, &rheo::v1::SceneService::Stub::SetParameters, req, &r);
  return s.ok() ? 0 : Fail(s);
}

}  // namespace

void AddParamCommand(CLI::App& app, const Global& g) {
  struct ParamArgs {
    uint32_t instance = 0;
    std::string preset;
    std::vector<std::string> sets;
  };
  auto a = std::make_shared<ParamArgs>();
  auto* param = app.add_subcommand("param", "material parameters (take effect on the next tick)");
  param->require_subcommand(1);
  auto* param_list = param->add_subcommand("list", "parameters with units and ranges, presets");
  param_list->add_option("INSTANCE", a->instance, "scene instance (0: the default preset)");
  param_list->callback([&g, a] { g_exit_code = ParamList(g, a->instance); });
  auto* param_set = param->add_subcommand("set", "set parameters of one instance (0: all)");
  param_set->add_option("INSTANCE", a->instance)->required();
  param_set->add_option("ASSIGNMENTS", a->sets, "name=value ...");
  param_set->add_option("--preset", a->preset, "apply a preset first");
  param_set->callback([&g, a] { g_exit_code = ParamSet(g, a->instance, a->preset, a->sets); });
}

}  // namespace rheoctl
