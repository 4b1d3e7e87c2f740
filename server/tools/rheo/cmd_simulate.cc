// `rheo simulate`: runs a rheological object offline and writes one JSON line per frame.
#include <Eigen/Geometry>
#include <chrono>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "common/tet_mesh_io.h"
#include "sim/sim.h"

// common/tet_mesh_io.cc calls Vec3 differences' cross() without including <Eigen/Geometry>, so
// the instantiation it needs is emitted nowhere; provide it here (a weak, identical definition)
// until that file includes the header.
namespace {
using Vec3Diff = Eigen::CwiseBinaryOp<Eigen::internal::scalar_difference_op<double, double>,
                                      const rheo::Vec3, const rheo::Vec3>;
}  // namespace
template Eigen::MatrixBase<Vec3Diff>::cross_product_return_type<Vec3Diff>::type
Eigen::MatrixBase<Vec3Diff>::cross<Vec3Diff>(const Eigen::MatrixBase<Vec3Diff>&) const;

namespace rheo::tools {
namespace {

struct SimulateOptions {
  std::string mesh_path;
  std::string preset = "soft-jelly";
  std::vector<std::string> sets;
  std::string integrator;
  double dt = 1e-3;
  double time = 2.0;
  double drop_height = 0.0;
  double frame_interval = 0.01;
  std::string jsonl_path;
};

int RunSimulate(const SimulateOptions& o) {
  std::ifstream in(o.mesh_path);
  if (!in) {
    std::cerr << "rheo simulate: cannot open " << o.mesh_path << "\n";
    return 1;
  }
  std::stringstream text;
  text << in.rdbuf();
  Result<TetMesh> mesh = ReadVtu(text.str());
  if (!mesh.ok()) {
    std::cerr << "rheo simulate: " << o.mesh_path << ": " << mesh.error().message << "\n";
    return 1;
  }
  Result<sim::Preset> preset = sim::FindPreset(o.preset);
  if (!preset.ok()) {
    std::cerr << "rheo simulate: " << preset.error().message << "\n";
    return 1;
  }
  sim::Parameters params = preset->params;
  for (const std::string& s : o.sets) {
    const size_t eq = s.find('=');
    double value = 0.0;
    try {
      if (eq == std::string::npos) throw std::invalid_argument("no '='");
      size_t used = 0;
      value = std::stod(s.substr(eq + 1), &used);
      if (used != s.size() - eq - 1) throw std::invalid_argument("trailing text");
    } catch (const std::exception&) {
      std::cerr << "rheo simulate: --set expects name=number, got '" << s << "'\n";
      return 1;
    }
    if (Status st = sim::SetParameterByName(params, s.substr(0, eq), value); !st.ok()) {
      std::cerr << "rheo simulate: " << st.error().message << "\n";
      return 1;
    }
  }
  sim::Integrator integrator = preset->integrator;
  if (!o.integrator.empty()) {
    Result<sim::Integrator> it = sim::ParseIntegrator(o.integrator);
    if (!it.ok()) {
      std::cerr << "rheo simulate: " << it.error().message << "\n";
      return 1;
    }
    integrator = *it;
  }
  if (!(o.dt > 0.0) || !(o.time >= 0.0) || !(o.frame_interval > 0.0)) {
    std::cerr << "rheo simulate: --dt and --frame must be positive, --time non-negative\n";
    return 1;
  }
  auto obj = sim::SimObject::Create(*mesh, params, integrator);
  if (!obj.ok()) {
    std::cerr << "rheo simulate: " << obj.error().message << "\n";
    return 1;
  }
  sim::SimObject& s = **obj;
  // Drop height: lowest point of the object this far above the floor.
  double lowest = s.positions()[0].y();
  for (const Vec3& p : s.positions()) lowest = std::min(lowest, p.y());
  if (params.floor_enabled > 0.5) {
    s.Translate(Vec3(0.0, params.floor_height + o.drop_height - lowest, 0.0));
  } else if (o.drop_height != 0.0) {
    s.Translate(Vec3(0.0, o.drop_height, 0.0));
  }

  std::ofstream file;
  std::ostream* out = &std::cout;
  if (!o.jsonl_path.empty()) {
    file.open(o.jsonl_path);
    if (!file) {
      std::cerr << "rheo simulate: cannot write " << o.jsonl_path << "\n";
      return 1;
    }
    out = &file;
  }
  const int64_t steps = static_cast<int64_t>(std::llround(o.time / o.dt));
  const int64_t per_frame = std::max<int64_t>(1, std::llround(o.frame_interval / o.dt));
  double wall_sum = 0.0;
  int64_t frame_steps = 0, frame_substeps = 0, restores = 0;
  auto emit = [&](int64_t step) {
    const sim::Diagnostics d = s.ComputeDiagnostics();
    nlohmann::json j;
    j["time"] = d.time;
    j["step"] = step;
    j["volume"] = d.volume;
    j["volume_ratio"] = d.rest_volume > 0 ? d.volume / d.rest_volume : 0.0;
    j["kinetic_energy"] = d.kinetic_energy;
    j["potential_energy"] = d.potential_energy;
    j["elastic_energy"] = d.elastic_energy;
    j["lowest_point"] = d.lowest_point;
    j["max_displacement"] = d.max_displacement;
    j["steps"] = frame_steps;
    j["substeps"] = frame_substeps;
    j["wall_time_per_step_s"] = frame_steps > 0 ? wall_sum / frame_steps : 0.0;
    j["restores"] = restores;
    j["sleeping"] = s.sleeping();
    j["floor_force_y"] = d.floor_force.y();
    *out << j.dump() << "\n";
    wall_sum = 0.0;
    frame_steps = frame_substeps = restores = 0;
  };
  emit(0);
  for (int64_t k = 1; k <= steps; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    const sim::StepResult r = s.Step(o.dt);
    wall_sum += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++frame_steps;
    frame_substeps += r.substeps;
    restores += r.restored ? 1 : 0;
    if (k % per_frame == 0 || k == steps) emit(k);
  }
  std::cerr << "rheo simulate: " << steps << " steps, " << s.events().restores << " restores, "
            << s.events().capped_ticks << " capped ticks, integrator "
            << sim::IntegratorName(s.integrator()) << "\n";
  return 0;
}

}  // namespace

void AddSimulateCommand(CLI::App& app) {
  auto opts = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand("simulate", "simulate a rheological object (.vtu tetrahedra)");
  cmd->add_option("mesh", opts->mesh_path, "tetrahedral mesh (.vtu)")->required();
  cmd->add_option("--preset", opts->preset, "soft-jelly | hard-jelly | clay | organ");
  cmd->add_option("--set", opts->sets, "parameter override name=value (repeatable)");
  cmd->add_option("--integrator", opts->integrator, "symplectic-euler | implicit-euler");
  cmd->add_option("--dt", opts->dt, "tick [s]");
  cmd->add_option("--time", opts->time, "simulated time [s]");
  cmd->add_option("--drop-height", opts->drop_height, "lowest point above the floor at start [m]");
  cmd->add_option("--frame", opts->frame_interval, "time between reported frames [s]");
  cmd->add_option("--jsonl", opts->jsonl_path, "output file (default stdout)");
  cmd->callback([opts]() { g_exit_code = RunSimulate(*opts); });
}

}  // namespace rheo::tools
