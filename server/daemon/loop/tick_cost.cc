#include "daemon/loop/tick_cost.h"

#include <algorithm>
#include <chrono>
#include <vector>

#include "sim/primitives.h"

namespace rheo::daemon {
namespace {

// Shortest time of one tick per (substep x element) [ns], over `ticks` ticks. The shortest, not
// the median: another process on the core only ever adds time, and the loop that the figure is
// for runs at real-time priority, ahead of such neighbours, while this runs without it.
double FastestTickNs(sim::SimObject& object, int ticks, double dt, int64_t elements,
                     int32_t* substeps_out) {
  std::vector<double> per;
  per.reserve(static_cast<size_t>(ticks));
  for (int i = 0; i < ticks; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const sim::StepResult r = object.Step(dt);
    const double ns =
        std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
    *substeps_out = std::max(r.substeps, 1);
    per.push_back(ns / (static_cast<double>(*substeps_out) * static_cast<double>(elements)));
  }
  return *std::min_element(per.begin(), per.end());
}

}  // namespace

sim::CostCoefficients MeasureTickCost() {
  constexpr double kDt = 1e-3;
  constexpr int kTicks = 40;
  sim::CostCoefficients c;
  auto mesh = sim::MakeBoxTetMesh(7, 4, 6, Vec3(0.06, 0.035, 0.05));
  auto preset = sim::FindPreset("soft-jelly");
  if (!mesh.ok() || !preset.ok()) return c;
  sim::Parameters p = preset->params;
  p.sleep_time = 0.0;  // never asleep: every tick does its work
  p.max_substeps = 10000;
  auto run = [&](sim::Integrator integrator, const sim::Parameters& params) -> double {
    auto object = sim::SimObject::Create(*mesh, params, integrator);
    if (!object.ok()) return 0.0;
    const int64_t elements = sim::ElementCount((*object)->model());
    int32_t substeps = 1;
    (void)FastestTickNs(**object, 5, kDt, elements, &substeps);  // warm the caches
    return FastestTickNs(**object, kTicks, kDt, elements, &substeps);
  };
  c.explicit_ns = run(sim::Integrator::kSymplecticEuler, p);
  // The implicit integrator with a tolerance it never reaches, so every substep does exactly
  // cg_max_iterations iterations: the difference between two counts is the iterations' cost.
  sim::Parameters q = p;
  q.cg_tolerance = 1e-14;
  constexpr int kFew = 1, kMany = 9;
  q.cg_max_iterations = kFew;
  const double few = run(sim::Integrator::kImplicitEuler, q);
  q.cg_max_iterations = kMany;
  const double many = run(sim::Integrator::kImplicitEuler, q);
  c.cg_ns = std::max(0.0, (many - few) / (kMany - kFew));
  c.implicit_ns = std::max(0.1 * few, few - kFew * c.cg_ns);
  // The same block with its shape springs stiff enough that every tetrahedron joins the linear
  // system: what is over the soft block's time is the system tetrahedra's share.
  sim::Parameters stiff = q;
  stiff.tet_k *= 1e3;
  int32_t system_tets = 0;
  int64_t elements = 0;
  {
    auto object = sim::SimObject::Create(*mesh, stiff, sim::Integrator::kImplicitEuler);
    if (!object.ok()) return c;
    auto prepared = (*object)->Prepare(stiff, sim::Integrator::kImplicitEuler, kDt);
    if (!prepared.ok()) return c;
    system_tets = prepared->implicit_tets;
    elements = sim::ElementCount((*object)->model());
  }
  if (system_tets <= 0) return c;
  stiff.cg_max_iterations = kFew;
  const double stiff_few = run(sim::Integrator::kImplicitEuler, stiff);
  stiff.cg_max_iterations = kMany;
  const double stiff_many = run(sim::Integrator::kImplicitEuler, stiff);
  const double per_tet = static_cast<double>(elements) / system_tets;  // per element -> per tet
  const double stiff_cg = std::max(0.0, (stiff_many - stiff_few) / (kMany - kFew));
  c.system_cg_ns = std::max(0.0, (stiff_cg - c.cg_ns) * per_tet);
  c.system_ns = std::max(0.0, (stiff_few - kFew * stiff_cg - c.implicit_ns) * per_tet);
  return c;
}

}  // namespace rheo::daemon
