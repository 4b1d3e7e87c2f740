// sim_bench trace [sample] [max_tets] [scene] [name=value...]: where a scene's ticks spend their
// time, in windows of 10 ms: the CPU per tick, the CG iterations, the tets and faces in the linear
// system, whether the CG's product ran on the assembled edge blocks, and the nodes the floor held.
// A leading preset=NAME starts from another preset than organ; name=value overrides a parameter.
#include <algorithm>
#include <cstdio>
#include <span>
#include <string>
#include <string_view>

#include "bench.h"

namespace sim_bench {

int Trace(const std::string& sample, int max_tets, const std::string& scene,
          std::span<char* const> sets) {
  if (scene != "drop" && scene != "press") {
    std::fprintf(stderr, "sim_bench trace: the scene is drop or press, not '%s'\n", scene.c_str());
    return 1;
  }
  // A leading preset=NAME picks the preset; the rest are name=value overrides over it.
  std::string preset_name = "organ";
  if (!sets.empty() && std::string_view(sets.front()).starts_with("preset=")) {
    preset_name = sets.front() + 7;
    sets = sets.subspan(1);
  }
  auto preset = FindPreset(preset_name);
  if (!preset.ok()) {
    std::fprintf(stderr, "sim_bench trace: %s\n", preset.error().message.c_str());
    return 1;
  }
  Parameters p = preset->params;
  p.sleep_time = 0.0;
  kMethods[3].Apply(p);
  std::string overrides;
  for (const char* arg : sets) {
    std::string name;
    double value = 0.0;
    if (!ParseSetting(arg, &name, &value)) {
      std::fprintf(stderr, "sim_bench trace: '%s' is not name=number (preset=NAME comes first)\n",
                   arg);
      return 1;
    }
    if (rheo::Status st = SetParameterByName(p, name, value); !st.ok()) {
      std::fprintf(stderr, "sim_bench trace: %s\n", st.error().message.c_str());
      return 1;
    }
    overrides += std::string(" ") + arg;
  }
  auto meshes = MeshSampleSizes(sample, max_tets);
  if (!meshes.ok()) {
    std::fprintf(stderr, "sim_bench trace: %s\n", meshes.error().message.c_str());
    return 1;
  }
  if (meshes->meshes.empty()) {
    std::fprintf(stderr,
                 "sim_bench trace: no size of %s within %d tets (the smallest is about 5k)\n",
                 sample.c_str(), max_tets);
    return 1;
  }
  const double dt = 1e-3, t_end = 0.3;
  const int window = 10;
  std::printf(
      "# samples/%s.json, %s preset, implicit BDF2, 1 ms ticks, 0.3 s of the %s scene of "
      "precision-sizes;\n# per window of %d ticks: CPU per tick (mean, max), CG iterations per "
      "tick (mean, max), the tets and faces\n# in the system, the ticks whose product ran on "
      "the assembled edge blocks, and the floor's held nodes (mean).\n# overrides:%s\n",
      sample.c_str(), preset_name.c_str(), scene.c_str(), window,
      overrides.empty() ? " none" : overrides.c_str());
  for (const TetMesh& mesh : meshes->meshes) {
    const std::vector<Scene> scenes = SizeScenes(mesh, p);
    const Scene& sc = scene == "drop" ? scenes[0] : scenes[1];
    auto created = SimObject::Create(mesh, p, Integrator::kImplicitEuler);
    if (!created.ok()) {
      std::fprintf(stderr, "sim_bench trace: %s\n", created.error().message.c_str());
      return 1;
    }
    SimObject& s = **created;
    s.Translate(Vec3(0, sc.drop, 0));
    const std::vector<int32_t> top = TopNodes(s);
    std::printf("# %zu tets, %zu edges, %d nodes\n", mesh.tets.size(), s.model().edges.size(),
                s.model().num_nodes);
    std::printf("%7s %9s %9s %7s %7s %9s %9s %8s\n", "t_ms", "us_mean", "us_max", "cg_mean",
                "cg_max", "sys_elems", "assembled", "floor");
    const int64_t ticks = std::llround(t_end / dt);
    double us_sum = 0, us_max = 0, cg_sum = 0, floor_sum = 0, total_us = 0;
    int32_t cg_max = 0, assembled = 0;
    int64_t sys = 0, total_cg = 0;
    for (int64_t k = 0; k < ticks; ++k) {
      ApplyPress(s, sc, top, k, dt);
      const double c0 = CpuSeconds();
      const StepResult st = s.Step(dt);
      const double us = (CpuSeconds() - c0) * 1e6;
      us_sum += us;
      total_us += us;
      us_max = std::max(us_max, us);
      cg_sum += st.solver_iterations;
      total_cg += st.solver_iterations;
      cg_max = std::max(cg_max, st.solver_iterations);
      sys = std::max(sys, s.state().system_elements);
      assembled += s.state().edge_block_age >= 0;
      floor_sum += s.state().floor_nodes;
      if ((k + 1) % window == 0) {
        std::printf("%7lld %9.1f %9.1f %7.1f %7d %9lld %9d %8.1f\n", static_cast<long long>(k + 1),
                    us_sum / window, us_max, cg_sum / window, cg_max, static_cast<long long>(sys),
                    assembled, floor_sum / window);
        us_sum = us_max = cg_sum = floor_sum = 0;
        cg_max = assembled = 0;
        sys = 0;
      }
    }
    std::printf("# %zu tets: %.1f us and %.2f CG iterations per tick; %.3f us per 1k tets\n",
                mesh.tets.size(), total_us / ticks, double(total_cg) / ticks,
                total_us / ticks / (mesh.tets.size() / 1000.0));
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace sim_bench
