// sim_bench budget [sample] [max_tets]: the implicit step's solver settings side by side at each
// size of a sketched sample (about 5k/20k/100k tets), drop and press, 1 s at 1 ms ticks: each
// tick's CPU time (median and tail) beside its error against a fine-tick reference, so that a
// setting that buys time with accuracy shows both.
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "bench.h"

namespace sim_bench {
namespace {

struct Variant {
  const char* name;
  double preconditioner;  // Parameters::cg_preconditioner
  double lag;             // Parameters::jacobian_lag
  double budget;          // Parameters::cg_iteration_budget
  double max_iterations;  // Parameters::cg_max_iterations
  double tolerance;       // Parameters::cg_tolerance
};

}  // namespace

int Budget(const std::string& sample, int max_tets) {
  auto meshes = MeshSampleSizes(sample, max_tets);
  if (!meshes.ok()) {
    std::fprintf(stderr, "sim_bench budget: %s\n", meshes.error().message.c_str());
    return 1;
  }
  const double t_end = 1.0, dt = 1e-3, ref_dt = 1.25e-4;
  const Parameters defaults;
  const double lag = defaults.jacobian_lag, budget = defaults.cg_iteration_budget,
               it = defaults.cg_max_iterations, tol = defaults.cg_tolerance;
  const Variant variants[] = {
      {"before", 0, 1, 0, it, tol},
      {"lag2", 0, 2, 0, it, tol},
      {"budget2", 0, 1, 2, it, tol},
      {"default", 0, lag, budget, it, tol},
      {"block", 1, lag, budget, it, tol},
      {"budget1.5", 0, lag, 1.5, it, tol},
      {"cap16", 0, lag, 0, 16, tol},
      {"tol1e-2", 0, lag, budget, it, 1e-2},
      {"block+tol1e-2", 1, lag, budget, it, 1e-2},
  };
  std::printf(
      "# samples/%s.json at about 5k/20k/100k tets, organ preset, BDF2, 1 ms ticks, %.1f s; drop = "
      "2 cm onto the floor, press = 3 N\n# ramped over 0.1 s on the nodes within 1 cm of the top. "
      "Per tick: CPU time of the step (one thread), the first tick apart, the\n# percentiles over "
      "the "
      "rest. shape_err = RMS\n# distance from the "
      "reference (BDF2 at %.3g s ticks) at the end after the best rigid fit, over the size; "
      "pos_err without the fit.\n",
      sample.c_str(), t_end, ref_dt);
  std::printf("%-6s %7s %-17s %8s %8s %8s %8s %8s %7s %6s %11s %11s %8s\n", "scene", "tets",
              "solver", "first_us", "med_us", "p99_us", "p999_us", "max_us", "cg_mean", "cg_max",
              "shape_err", "pos_err", "restores");
  for (const TetMesh& mesh : meshes->meshes) {
    Parameters p = FindPreset("organ")->params;
    p.sleep_time = 0.0;  // measured while it moves, never asleep
    for (const Scene& base :
         {Scene{"drop", mesh, p, 0.02, 0.0}, Scene{"press", mesh, p, 0.0, 3.0}}) {
      const RunResult ref = RunScene(base, kMethods[3], ref_dt, t_end);
      const double size =
          (**SimObject::Create(base.mesh, base.params, Integrator::kImplicitEuler)).model().size;
      for (const Variant& v : variants) {
        Scene sc = base;
        sc.params.cg_preconditioner = v.preconditioner;
        sc.params.jacobian_lag = v.lag;
        sc.params.cg_iteration_budget = v.budget;
        sc.params.cg_max_iterations = v.max_iterations;
        sc.params.cg_tolerance = v.tolerance;
        const RunResult r = RunScene(sc, kMethods[3], dt, t_end);
        // The first tick apart: it decides which shape springs join the system (the daemon
        // decides that off the loop, SimObject::Prepare), and its CG starts cold.
        const std::vector<double> rest(r.tick_us.begin() + 1, r.tick_us.end());
        std::printf("%-6s %7zu %-17s %8.1f %8.1f %8.1f %8.1f %8.1f %7.2f %6d %11.3e %11.3e %8lld\n",
                    sc.name, mesh.tets.size(), v.name, r.tick_us.front(), Median(rest),
                    Percentile(rest, 0.99), Percentile(rest, 0.999),
                    *std::max_element(rest.begin(), rest.end()),
                    r.substeps > 0 ? double(r.iterations) / r.substeps : 0.0, r.max_iterations,
                    ShapeError(ref.x, r.x, size), RmsError(r.x, ref.x, size),
                    static_cast<long long>(r.restores));
        std::fflush(stdout);
      }
      std::printf("# %s %zu tets: reference %lld restores, %.1f s of CPU\n", base.name,
                  mesh.tets.size(), static_cast<long long>(ref.restores), ref.cpu);
    }
  }
  std::printf(
      "# solver: before = the implicit step until 2026-12-06: Jacobi CG, tolerance 5e-3, at most "
      "60 iterations, the blocks\n# rebuilt every tick; default = now (jacobian_lag %g, "
      "cg_iteration_budget %g); block = 3x3 block Jacobi (cg_preconditioner 1);\n# lagN = the "
      "assembled blocks kept N ticks (jacobian_lag N); budgetB = at most B times the running mean "
      "of the CG\n# iterations a tick (cg_iteration_budget B); cap16 = at most 16 "
      "(cg_max_iterations); tol = cg_tolerance.\n",
      lag, budget);
  return 0;
}

}  // namespace sim_bench
