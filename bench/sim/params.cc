// sim_bench params: what a parameter change costs the thread that steps the object.
#include <chrono>
#include <cstdio>
#include <vector>

#include "bench.h"

namespace sim_bench {

// What a parameter change costs the thread that steps the object: the tick that applies it with
// SetParameters(params) (everything on that thread, as `rheo simulate` does) and with a set
// SimObject::Prepare made on another thread (as rheod does), next to a normal tick. Medians.
int ParameterChange() {
  std::printf("# parameter change (k_v), organ, implicit BDF2, 1 ms ticks; median us of 9\n");
  std::printf("%8s %12s %18s %16s %18s\n", "tets", "normal tick", "tick + direct set",
              "tick + prepared", "Prepare (off loop)");
  for (int target : {5000, 20000}) {
    const TetMesh mesh = BoxWithTets(target);
    Parameters p = FindPreset("organ")->params;
    auto obj = SimObject::Create(mesh, p, Integrator::kImplicitEuler);
    if (!obj.ok()) return 2;
    SimObject& s = **obj;
    for (int k = 0; k < 50; ++k) s.Step(1e-3);
    std::vector<double> normal, direct, prepared, prepare;
    auto us_since = [](auto t0) {
      return std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0)
          .count();
    };
    for (int r = 0; r < 9; ++r) {
      p.k_v = 150.0 + r;
      auto t0 = std::chrono::steady_clock::now();
      (void)s.SetParameters(p);
      s.Step(1e-3);
      direct.push_back(us_since(t0));
      p.k_v = 160.0 + r;
      t0 = std::chrono::steady_clock::now();
      auto pr = s.Prepare(p, Integrator::kImplicitEuler, 1e-3);
      prepare.push_back(us_since(t0));
      if (!pr.ok()) return 2;
      t0 = std::chrono::steady_clock::now();
      (void)s.SetParameters(*pr);
      s.Step(1e-3);
      prepared.push_back(us_since(t0));
      t0 = std::chrono::steady_clock::now();
      s.Step(1e-3);
      normal.push_back(us_since(t0));
    }
    std::printf("%8zu %12.0f %18.0f %16.0f %18.0f\n", mesh.tets.size(), Median(normal),
                Median(direct), Median(prepared), Median(prepare));
  }
  return 0;
}

}  // namespace sim_bench
