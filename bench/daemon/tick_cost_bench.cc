// tick_cost_bench: the daemon's admission cost model (sim::PredictTickCost with the coefficients
// MeasureTickCost calibrates at start-up) against measured ticks, in one run: boxes of 1k, 5k and
// 19k tetrahedra, each integrator, default and heavier settings. Prints a table of medians.
//
//   tick_cost_bench [ticks]      (default 60 measured ticks per row, after 10 warm-up ticks)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "daemon/loop/tick_cost.h"
#include "sim/cost.h"
#include "sim/primitives.h"
#include "sim/sim.h"

namespace {

using namespace rheo;

struct Row {
  const char* name;
  sim::Integrator integrator;
  std::vector<std::pair<const char*, double>> params;
};

double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  const int ticks = argc > 1 ? std::max(5, std::atoi(argv[1])) : 60;
  constexpr double kDt = 1e-3;
  // The daemon calibrates once; here the median of three calibrations, for a steadier table.
  std::vector<sim::CostCoefficients> cal;
  for (int i = 0; i < 3; ++i) cal.push_back(daemon::MeasureTickCost());
  auto median_of = [&](double sim::CostCoefficients::*f) {
    std::vector<double> v;
    for (const auto& c : cal) v.push_back(c.*f);
    return Median(v);
  };
  sim::CostCoefficients c;
  c.explicit_ns = median_of(&sim::CostCoefficients::explicit_ns);
  c.implicit_ns = median_of(&sim::CostCoefficients::implicit_ns);
  c.cg_ns = median_of(&sim::CostCoefficients::cg_ns);
  std::printf(
      "# tick cost model: %.2f ns per element and explicit substep, %.2f per implicit "
      "substep, %.2f per CG iteration (median of 3 calibrations)\n",
      c.explicit_ns, c.implicit_ns, c.cg_ns);
  std::printf(
      "# %d ticks per row, medians; 'model at measured CG' counts the iterations the "
      "solver took instead of the model's estimate\n",
      ticks);
  std::printf("%-8s %-34s %8s %9s %12s %12s %8s %14s %8s\n", "tets", "case", "substeps", "CG/sub",
              "predicted us", "measured us", "meas/pred", "model@CG us", "meas/m@CG");

  const std::vector<Row> rows = {
      {"symplectic, soft-jelly", sim::Integrator::kSymplecticEuler, {}},
      {"symplectic, k_v x10", sim::Integrator::kSymplecticEuler, {{"k_v", 1000.0}}},
      {"implicit, soft-jelly", sim::Integrator::kImplicitEuler, {}},
      {"implicit, 4 substeps", sim::Integrator::kImplicitEuler, {{"implicit_substeps", 4.0}}},
      {"implicit, cg_tolerance 1e-6", sim::Integrator::kImplicitEuler, {{"cg_tolerance", 1e-6}}},
  };
  struct Box {
    int nx, ny, nz;
  };
  for (const Box b : {Box{7, 4, 6}, Box{12, 7, 10}, Box{19, 11, 15}}) {
    auto mesh = sim::MakeBoxTetMesh(b.nx, b.ny, b.nz, Vec3(0.1, 0.06, 0.08));
    if (!mesh.ok()) {
      std::fprintf(stderr, "box: %s\n", mesh.error().message.c_str());
      return 1;
    }
    for (const Row& row : rows) {
      sim::Parameters p = sim::FindPreset("soft-jelly")->params;
      p.sleep_time = 0.0;  // awake throughout, as the model assumes
      for (auto [name, value] : row.params) (void)sim::SetParameterByName(p, name, value);
      auto object = sim::SimObject::Create(*mesh, p, row.integrator);
      if (!object.ok()) {
        std::fprintf(stderr, "object: %s\n", object.error().message.c_str());
        return 1;
      }
      auto prepared = (*object)->Prepare(p, row.integrator, kDt);
      if (!prepared.ok()) return 1;
      const sim::TickCost cost =
          sim::PredictTickCost((*object)->model(), *prepared, row.integrator, kDt, c);
      for (int i = 0; i < 10; ++i) (void)(*object)->Step(kDt);
      std::vector<double> us;
      double iterations = 0.0, substeps = 0.0;
      for (int i = 0; i < ticks; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        const sim::StepResult r = (*object)->Step(kDt);
        us.push_back(
            std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0)
                .count());
        iterations += r.solver_iterations;
        substeps += r.substeps;
      }
      const double measured = Median(us);
      const double cg_per_substep = substeps > 0 ? iterations / substeps : 0.0;
      const double at_cg = row.integrator == sim::Integrator::kImplicitEuler
                               ? cost.substeps * static_cast<double>(cost.elements) *
                                     (c.implicit_ns + cg_per_substep * c.cg_ns) * 1e-3
                               : cost.ns * 1e-3;
      std::printf("%-8zu %-34s %8d %9.2f %12.1f %12.1f %8.2f %14.1f %8.2f\n",
                  (*object)->model().tets.size(), row.name, cost.substeps, cg_per_substep,
                  cost.ns * 1e-3, measured, measured / (cost.ns * 1e-3), at_cg, measured / at_cg);
    }
  }
  return 0;
}
