// sim_bench sketched [sample] [max_tets]: a sketched object of the project's own samples, meshed
// at about 5k, 20k and 100k tetrahedra, dropped 2 cm and pressed, organ preset, the default
// implicit integrator (BDF2), 1 ms ticks; Bullet's btSoftBody on the same tetrahedra beside it.
// Per size: tick medians and tails, cost per 1k tetrahedra, CG iterations, restores.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "bench.h"

namespace sim_bench {
namespace {

struct Tick {
  std::vector<double> us;
  int64_t restores = 0, iterations = 0, substeps = 0;
  double max_iterations = 0;
};

Tick RunRheo(const Scene& sc, int ticks) {
  Parameters p = sc.params;
  kMethods[3].Apply(p);
  auto obj = SimObject::Create(sc.mesh, p, Integrator::kImplicitEuler);
  SimObject& s = **obj;
  s.Translate(Vec3(0, sc.drop, 0));
  const std::vector<int32_t> top = TopNodes(s);
  Tick t;
  for (int k = 0; k < ticks; ++k) {
    ApplyPress(s, sc, top, k, 1e-3);
    const auto t0 = std::chrono::steady_clock::now();
    const StepResult st = s.Step(1e-3);
    t.us.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    t.restores += st.restored;
    t.iterations += st.solver_iterations;
    t.substeps += st.substeps;
    t.max_iterations = std::max<double>(t.max_iterations, st.solver_iterations);
  }
  return t;
}

}  // namespace

int Sketched(const std::string& sample, int max_tets) {
  auto meshes = MeshSampleSizes(sample, max_tets);
  if (!meshes.ok()) {
    std::fprintf(stderr, "sim_bench sketched: %s\n", meshes.error().message.c_str());
    return 1;
  }
  const int ticks = 400;
  std::printf(
      "# samples/%s.json meshed at three resolutions; organ preset, BDF2, 1 ms ticks, %d ticks "
      "(0.4 s);\n# drop = 2 cm onto the floor, press = 3 N ramped over 0.1 s on the nodes within "
      "1 cm of the top. One thread.\n# Bullet: btSoftBody on the same tetrahedra, same dt, 4 "
      "position iterations, kLST 1.\n",
      sample.c_str(), ticks);
  std::printf("%-6s %-7s %7s %8s %9s %9s %9s %9s %8s %8s %8s %10s %7s %10s %7s\n", "scene",
              "solver", "tets", "res_mm", "med_us", "p99_us", "max_us", "us/1ktet", "cg_mean",
              "cg_max", "restores", "bullet_us", "ratio", "bullet2_us", "ratio2");
  for (size_t mi = 0; mi < meshes->meshes.size(); ++mi) {
    const TetMesh& mesh = meshes->meshes[mi];
    Parameters p = FindPreset("organ")->params;
    p.sleep_time = 0.0;  // measured while it moves, never asleep
    for (const Scene& base :
         {Scene{"drop", mesh, p, 0.02, 0.0}, Scene{"press", mesh, p, 0.0, 3.0}}) {
      const size_t tets = base.mesh.tets.size();
      double bullet = 0.0, bullet_bend = 0.0;
#ifdef RHEO_HAVE_BULLET
      bullet = Median(RunBullet(base, 1e-3, ticks * 1e-3, 1.0, 0).tick_us);
      bullet_bend = Median(RunBullet(base, 1e-3, ticks * 1e-3, 1.0, 2).tick_us);
#endif
      // The implicit step as it was before 2026-12-06 (blocks rebuilt every tick, no iteration
      // budget), as it is now, and with the block preconditioner, one after the other.
      struct Solver {
        const char* name;
        double preconditioner, lag, budget;
      };
      const Parameters d;
      for (const Solver& v :
           {Solver{"before", 0.0, 1.0, 0.0},
            Solver{"default", d.cg_preconditioner, d.jacobian_lag, d.cg_iteration_budget},
            Solver{"block", 1.0, d.jacobian_lag, d.cg_iteration_budget}}) {
        Scene sc = base;
        sc.params.cg_preconditioner = v.preconditioner;
        sc.params.jacobian_lag = v.lag;
        sc.params.cg_iteration_budget = v.budget;
        const Tick t = RunRheo(sc, ticks);
        const double med = Median(t.us);
        std::printf(
            "%-6s %-7s %7zu %8.2f %9.1f %9.1f %9.1f %9.1f %8.2f %8.0f %8lld %10.1f %7.2f %10.1f "
            "%7.2f\n",
            sc.name, v.name, tets, meshes->resolution[mi] * 1e3, med, Percentile(t.us, 0.99),
            *std::max_element(t.us.begin(), t.us.end()), med / (tets / 1000.0),
            t.substeps > 0 ? double(t.iterations) / t.substeps : 0.0, t.max_iterations,
            static_cast<long long>(t.restores), bullet, bullet / med, bullet_bend,
            bullet_bend / med);
        std::fflush(stdout);
      }
    }
  }
  std::printf(
      "# ratio = Bullet's median step / Rheo's median tick (> 1: Rheo faster); bullet: the "
      "tetrahedra's links only;\n# bullet2: plus bending links two apart (sim_bench bullet's "
      "setting). cg = CG iterations per substep;\n# solver: before = Jacobi CG, blocks rebuilt "
      "every tick, no iteration budget (until 2026-12-06); default = jacobian_lag %g,\n# "
      "cg_iteration_budget %g; block = the same with the 3x3 block Jacobi preconditioner "
      "(cg_preconditioner 1).\n",
      Parameters{}.jacobian_lag, Parameters{}.cg_iteration_budget);
  return 0;
}

}  // namespace sim_bench
