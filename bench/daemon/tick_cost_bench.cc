// tick_cost_bench: the daemon's admission cost model (sim::PredictTickCost with the coefficients
// MeasureTickCost calibrates at start-up) against measured ticks, in one run: boxes of 1k, 5k and
// 19k tetrahedra, each integrator, default and heavier settings; then a sketched sample at about
// 5k, 20k and 100k tetrahedra as `rheo scene add --preset P --integrator implicit` runs it
// (organ, hard jelly, soft jelly), pressed: its full tick, and the step a multi-rate whole takes
// over 10 ticks. Prints tables of medians.
//
//   tick_cost_bench [ticks] [sample] [max_tets]
//     (default 60 measured ticks per row after 10 warm-up ticks; bean; 100000; a sample of "-"
//     or max_tets 0 skips the sketched series)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "daemon/loop/tick_cost.h"
#include "samples.h"
#include "sim/cost.h"
#include "sim/multirate.h"
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

// Steps `object` by `dt` `warmup` + `steps` times while the nodes within 1 cm of its top are
// pressed down with 3 N ramped over the first 20 ms; the median of the last `steps` step times,
// and the CG iterations per substep they took.
struct Measured {
  double median_us = 0.0, cg_per_substep = 0.0;
};
Measured Press(sim::SimObject& object, double dt, int warmup, int steps) {
  std::vector<int32_t> top;
  double y_max = -1e30;
  for (const Vec3& x : object.positions()) y_max = std::max(y_max, x.y());
  for (int32_t i = 0; i < object.model().num_nodes; ++i)
    if (object.positions()[i].y() > y_max - 0.01) top.push_back(i);
  double t = 0.0, iterations = 0.0, substeps = 0.0;
  std::vector<double> us;
  for (int k = 0; k < warmup + steps; ++k) {
    const double ramp = std::min(1.0, t / 0.02);
    for (int32_t i : top)
      object.SetExternalForce(i, Vec3(0, -ramp * 3.0 / static_cast<double>(top.size()), 0));
    const auto t0 = std::chrono::steady_clock::now();
    const sim::StepResult r = object.Step(dt);
    const double took =
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
    t += dt;
    if (k < warmup) continue;
    us.push_back(took);
    iterations += r.solver_iterations;
    substeps += r.substeps;
  }
  Measured m;
  m.median_us = Median(us);
  m.cg_per_substep = substeps > 0 ? iterations / substeps : 0.0;
  return m;
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
  c.system_ns = median_of(&sim::CostCoefficients::system_ns);
  c.system_cg_ns = median_of(&sim::CostCoefficients::system_cg_ns);
  std::printf(
      "# tick cost model: %.2f ns per element and explicit substep, %.2f per implicit "
      "substep, %.2f per CG iteration; a tet in the linear system adds %.1f per substep and %.1f "
      "per CG iteration (median of 3 calibrations)\n",
      c.explicit_ns, c.implicit_ns, c.cg_ns, c.system_ns, c.system_cg_ns);
  // The model's implicit time [us] with `cg` iterations per substep instead of its estimate.
  auto model_at = [&](const sim::TickCost& cost, double cg) {
    return sim::ImplicitTickNs(cost, cg, c) * 1e-3;
  };
  std::printf(
      "# %d ticks per row, medians; 'model at measured CG' counts the iterations the "
      "solver took instead of the model's estimate\n",
      ticks);
  std::printf("%-8s %-34s %8s %9s %9s %12s %12s %8s %14s %8s %9s\n", "tets", "case", "substeps",
              "CG/sub", "CG model", "predicted us", "measured us", "meas/pred", "model@CG us",
              "meas/m@CG", "in system");

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
                               ? model_at(cost, cg_per_substep)
                               : cost.ns * 1e-3;
      std::printf("%-8zu %-34s %8d %9.2f %9d %12.1f %12.1f %8.2f %14.1f %8.2f %9lld\n",
                  (*object)->model().tets.size(), row.name, cost.substeps, cg_per_substep,
                  cost.cg_iterations, cost.ns * 1e-3, measured, measured / (cost.ns * 1e-3), at_cg,
                  measured / at_cg, static_cast<long long>(cost.system_tets));
    }
  }

  const std::string sample = argc > 2 ? argv[2] : "bean";
  const int max_tets = argc > 3 ? std::atoi(argv[3]) : 100000;
  if (sample == "-" || max_tets <= 0) return 0;
  auto meshes = sim_bench::MeshSampleSizes(sample, max_tets);
  if (!meshes.ok()) {
    std::fprintf(stderr, "tick_cost_bench: %s\n", meshes.error().message.c_str());
    return 1;
  }
  constexpr int kPeriod = 10;  // the daemon's multi-rate period (scene_service.cc)
  const int whole_steps = std::max(5, ticks / kPeriod);
  std::printf(
      "# samples/%s.json, three presets, implicit, pressed with 3 N; 'full tick' = one 1 ms tick; "
      "'whole/%d' = the multi-rate whole's step over %d ticks (1 ms substeps, or 2 ms), %d steps\n",
      sample.c_str(), kPeriod, kPeriod, whole_steps);
  for (const char* preset : {"organ", "hard-jelly", "soft-jelly"})
    for (const TetMesh& mesh : meshes->meshes) {
      sim::Parameters p = sim::FindPreset(preset)->params;
      p.sleep_time = 0.0;
      sim::PatchOptions po;
      po.tick = kDt;
      po.whole_substep = kDt;  // as rheod sets it for a whole that keeps up
      sim::PatchOptions behind = po;
      behind.whole_substep = sim::kBehindWholeSubstep;  // ... and for one that would not
      struct Case {
        std::string name;
        sim::Parameters params;
        double dt;
        int steps;
      };
      const Case cases[] = {
          {std::string(preset) + ", full tick", p, kDt, ticks},
          {std::string(preset) + ", whole/10", sim::MultiRate::WholeParameters(p, kPeriod, po),
           kPeriod * kDt, whole_steps},
          {std::string(preset) + ", whole/10, 2 ms substeps",
           sim::MultiRate::WholeParameters(p, kPeriod, behind), kPeriod * kDt, whole_steps},
      };
      for (const Case& cs : cases) {
        auto object = sim::SimObject::Create(mesh, cs.params, sim::Integrator::kImplicitEuler);
        if (!object.ok()) {
          std::fprintf(stderr, "object: %s\n", object.error().message.c_str());
          return 1;
        }
        auto prepared = (*object)->Prepare(cs.params, sim::Integrator::kImplicitEuler, cs.dt);
        if (!prepared.ok()) return 1;
        const sim::TickCost cost = sim::PredictTickCost((*object)->model(), *prepared,
                                                        sim::Integrator::kImplicitEuler, cs.dt, c);
        const Measured m = Press(**object, cs.dt, cs.dt > kDt ? 2 : 10, cs.steps);
        const double at_cg = model_at(cost, m.cg_per_substep);
        std::printf("%-8zu %-34s %8d %9.2f %9d %12.1f %12.1f %8.2f %14.1f %8.2f %9lld\n",
                    (*object)->model().tets.size(), cs.name.c_str(), cost.substeps,
                    m.cg_per_substep, cost.cg_iterations, cost.ns * 1e-3, m.median_us,
                    m.median_us / (cost.ns * 1e-3), at_cg, m.median_us / at_cg,
                    static_cast<long long>(cost.system_tets));
      }
    }
  return 0;
}
