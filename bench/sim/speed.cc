// sim_bench speed [max_tets]: median wall time of one 1 ms tick vs mesh size.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <span>
#include <vector>

#include "bench.h"

namespace sim_bench {
namespace {

// One row per method: the median tick of `mesh` settling on the floor.
int SpeedRows(const TetMesh& mesh, std::span<const Method> methods) {
  const size_t target = mesh.tets.size();
  {
    for (const Method& method : methods) {
      Parameters p = FindPreset("organ")->params;
      p.sleep_time = 0.0;
      method.Apply(p);
      auto obj = SimObject::Create(mesh, p, method.integrator);
      if (!obj.ok()) return 2;
      SimObject& s = **obj;
      s.Translate(Vec3(0, 0.005, 0));
      const int ticks = target >= 60000 ? 25 : target >= 15000 ? 40 : 200;
      for (int k = 0; k < 5; ++k) s.Step(1e-3);
      if (method.integrator == Integrator::kImplicitEuler)
        std::printf("# shape springs at 1 ms: %s (%d tets implicit)\n",
                    s.ShapeSpringsTreatment(1e-3) == ShapeTreatment::kExplicit ? "explicit"
                    : s.ShapeSpringsTreatment(1e-3) == ShapeTreatment::kSplit  ? "split"
                                                                               : "implicit",
                    s.shape_implicit_tets());
      // Wall time, and the thread's CPU time (which leaves out the time this thread waited
      // while other processes ran on its core).
      std::vector<double> us, cpu_us;
      int64_t sub = 0, it = 0;
      for (int k = 0; k < ticks; ++k) {
        const auto t0 = std::chrono::steady_clock::now();
        const double c0 = CpuSeconds();
        const StepResult r = s.Step(1e-3);
        cpu_us.push_back(1e6 * (CpuSeconds() - c0));
        us.push_back(
            std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0)
                .count());
        sub += r.substeps;
        it += r.solver_iterations;
      }
      const double med = Median(us);
      std::printf("%8zu %7d %8zu %-24s %5.1f %9.1f %9.1f %9.1f %10.1f %9.1f\n", mesh.tets.size(),
                  s.model().num_nodes, s.model().edges.size(), method.name, double(sub) / ticks,
                  med, Percentile(us, 0.9), med / (mesh.tets.size() / 1e3), double(it) / ticks,
                  Median(cpu_us));
    }
  }
  return 0;
}

}  // namespace

int Speed(int max_tets) {
  std::printf("# speed: one 1 ms tick, object settling on the floor (awake), one core\n");
  const char* header = "%8s %7s %8s %-24s %5s %9s %9s %9s %10s %9s\n";
  std::printf(header, "tets", "nodes", "edges", "integrator", "subst", "median_us", "p90_us",
              "us/ktet", "CG it/tick", "cpu_us");
  // The same 10 cm box, refined: the elements get smaller and stiffer for their mass.
  for (int target : {100, 1000, 5000, 20000, 100000}) {
    if (target > max_tets) break;
    if (int rc = SpeedRows(BoxWithTets(target), kMethods); rc != 0) return rc;
  }
  // The 5k box's cells (10 cm / 12 = 8.3 mm), the box growing: the cost of the code per
  // element, with the conditioning of the system held.
  const double cell = 0.1 / 12.0;
  std::printf("# constant resolution: cells of %.1f mm, the box grows with the count\n",
              cell * 1e3);
  std::printf(header, "tets", "nodes", "edges", "integrator", "subst", "median_us", "p90_us",
              "us/ktet", "CG it/tick", "cpu_us");
  const std::span<const Method> implicit(kMethods + 2, 2);
  for (int target : {1000, 5000, 20000, 100000}) {
    if (target > max_tets) break;
    const TetMesh mesh = BoxWithCell(target, cell);
    Vec3 lo = mesh.positions[0], hi = lo;
    for (const Vec3& x : mesh.positions) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
    const Vec3 size = hi - lo;
    std::printf("# %.0f x %.0f x %.0f cm\n", size.x() * 100, size.y() * 100, size.z() * 100);
    if (int rc = SpeedRows(mesh, implicit); rc != 0) return rc;
  }
  return 0;
}

}  // namespace sim_bench
