// sim_bench cg: the implicit integrator's CG tolerance vs error and cost.
#include <cmath>
#include <cstdio>

#include "bench.h"

namespace sim_bench {

// The implicit integrator's CG tolerance against the error it costs (the default's justification).
int CgSweep() {
  const double t_end = 0.5, dt = 1e-3;
  std::printf("# implicit (BDF2), tick 1 ms: CG tolerance vs error (as in precision) and cost\n");
  std::printf("%-6s %10s %12s %10s %10s\n", "scene", "cg_tol", "error", "cpu_s/s", "CG it/tick");
  for (const Scene& sc : Scenes()) {
    const RunResult ref = RunScene(sc, kMethods[0], 1e-5, t_end);
    const double size =
        (**SimObject::Create(sc.mesh, sc.params, Integrator::kSymplecticEuler)).model().size;
    for (double tol : {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 1e-4, 1e-5, 1e-6}) {
      const RunResult r = RunScene(sc, kMethods[3], dt, t_end, tol);
      std::printf("%-6s %10.0e %12.3e %10.4f %10.1f\n", sc.name, tol, RmsError(r.x, ref.x, size),
                  r.cpu / t_end, double(r.iterations) / std::llround(t_end / dt));
    }
  }
  return 0;
}

}  // namespace sim_bench
