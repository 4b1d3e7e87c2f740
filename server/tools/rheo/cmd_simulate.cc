// `rheo simulate`: runs a rheological object offline and writes one JSON line per frame, with the
// shape change free of rigid motion (compression along gravity, RMS deformation); reports the
// peak compression and, after the load is taken away, the residual (plastic) deformation; can
// write the deformed object as a VTU series with a .pvd index (ParaView opens it).
#include <Eigen/Geometry>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "common/tet_mesh_io.h"
#include "sim/deformation.h"
#include "sim/params.h"
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
  double relax = 1.0;      // [s] simulated after the run without gravity, for the residual
  std::string vtu_series;  // directory for frame_NNNNNN.vtu and series.pvd; "" none
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
    std::string name;
    double value = 0.0;
    if (!sim::ParseSetting(s, &name, &value)) {
      std::cerr << "rheo simulate: --set expects name=number, got '" << s << "'\n";
      return 1;
    }
    if (Status st = sim::SetParameterByName(params, name, value); !st.ok()) {
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
  if (!(o.relax >= 0.0)) {
    std::cerr << "rheo simulate: --relax must be non-negative\n";
    return 1;
  }
  // The VTU series: one file per frame and the index ParaView reads.
  std::ofstream pvd;
  int frame_file = 0;
  if (!o.vtu_series.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.vtu_series, ec);
    pvd.open(std::filesystem::path(o.vtu_series) / "series.pvd");
    if (ec || !pvd) {
      std::cerr << "rheo simulate: cannot write the VTU series in " << o.vtu_series << "\n";
      return 1;
    }
    pvd << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n"
           "  <Collection>\n";
  }
  TetMesh deformed = *mesh;
  auto write_vtu = [&](double time) {
    if (o.vtu_series.empty()) return true;
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.vtu", frame_file++);
    const auto x = s.positions();
    deformed.positions.assign(x.begin(), x.end());
    std::ofstream f(std::filesystem::path(o.vtu_series) / name);
    f << WriteVtu(deformed);
    if (!f) {
      std::cerr << "rheo simulate: cannot write " << o.vtu_series << "/" << name << "\n";
      return false;
    }
    pvd << "    <DataSet timestep=\"" << time << "\" part=\"0\" file=\"" << name << "\"/>\n";
    return true;
  };
  const std::vector<Vec3> rest = mesh->positions;
  const Vec3 up(0.0, 1.0, 0.0);  // gravity is along -y
  double peak_compression = 0.0, peak_time = 0.0;
  const int64_t steps = static_cast<int64_t>(std::llround(o.time / o.dt));
  const int64_t per_frame = std::max<int64_t>(1, std::llround(o.frame_interval / o.dt));
  bool ok = true;
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
    const sim::ShapeChange shape = sim::MeasureShapeChange(rest, s.positions(), up);
    j["compression"] = shape.compression;
    j["deformation_rms"] = shape.rms;
    *out << j.dump() << "\n";
    if (!write_vtu(d.time)) ok = false;
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
    // The peak is looked for at every step (outside the timed step), not only at frames.
    if (const double c = sim::MeasureShapeChange(rest, s.positions(), up).compression;
        c > peak_compression) {
      peak_compression = c;
      peak_time = s.time();
    }
    if (k % per_frame == 0 || k == steps) emit(k);
    if (!ok) return 1;
  }
  const sim::ShapeChange loaded = sim::MeasureShapeChange(rest, s.positions(), up);
  std::cerr << "rheo simulate: " << steps << " steps, " << s.events().restores << " restores, "
            << s.events().capped_ticks << " capped ticks, integrator "
            << sim::IntegratorName(s.integrator()) << "\n";
  char line[256];
  std::snprintf(line, sizeof line,
                "rheo simulate: peak compression %.3f %% at %.3f s; at the end %.3f %% "
                "(RMS deformation %.3f mm)\n",
                100.0 * peak_compression, peak_time, 100.0 * loaded.compression, 1e3 * loaded.rms);
  std::cerr << line;
  if (o.relax > 0.0) {
    // Unloaded: no gravity (the tool never touched it offline), so the elastic part recovers
    // and what stays is the plastic flow of the dampers (eq. 3).
    sim::Parameters unloaded = s.parameters();
    unloaded.gravity = 0.0;
    if (Status st = s.SetParameters(unloaded); !st.ok()) {
      std::cerr << "rheo simulate: " << st.error().message << "\n";
      return 1;
    }
    const int64_t relax_steps = static_cast<int64_t>(std::llround(o.relax / o.dt));
    for (int64_t k = 1; k <= relax_steps; ++k) s.Step(o.dt);
    const sim::ShapeChange residual = sim::MeasureShapeChange(rest, s.positions(), up);
    std::snprintf(line, sizeof line,
                  "rheo simulate: residual (plastic) deformation after %.2f s unloaded: "
                  "compression %.3f %%, RMS %.3f mm, largest %.3f mm\n",
                  o.relax, 100.0 * residual.compression, 1e3 * residual.rms, 1e3 * residual.max);
    std::cerr << line;
    nlohmann::json summary;
    summary["peak_compression"] = peak_compression;
    summary["peak_compression_time"] = peak_time;
    summary["final_compression"] = loaded.compression;
    summary["final_deformation_rms"] = loaded.rms;
    summary["residual_compression"] = residual.compression;
    summary["residual_deformation_rms"] = residual.rms;
    summary["residual_deformation_max"] = residual.max;
    summary["relax_s"] = o.relax;
    *out << nlohmann::json{{"summary", summary}}.dump() << "\n";
  }
  if (pvd.is_open()) {
    pvd << "  </Collection>\n</VTKFile>\n";
    if (!pvd) {
      std::cerr << "rheo simulate: cannot finish " << o.vtu_series << "/series.pvd\n";
      return 1;
    }
    std::cerr << "rheo simulate: wrote " << frame_file << " frames to " << o.vtu_series
              << "/series.pvd\n";
  }
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
  cmd->add_option("--relax", opts->relax,
                  "then this long without gravity, for the residual (plastic) deformation [s]; 0: "
                  "skip (the last line is then a frame, not the summary)");
  cmd->add_option("--vtu-series", opts->vtu_series,
                  "write each frame's deformed object to DIR/frame_NNNNNN.vtu and the index "
                  "DIR/series.pvd (ParaView)");
  cmd->callback([opts]() { g_exit_code = RunSimulate(*opts); });
}

}  // namespace rheo::tools
