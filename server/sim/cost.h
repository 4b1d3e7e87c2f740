// What one tick of a rheological object costs: a model from its size, integrator, substeps and
// solver settings, counted in element passes and turned into time by coefficients the caller
// measures on its own machine (the daemon does at start-up, off the loop). Pure: no clock here.
//
//   sim::TickCost c = sim::PredictTickCost(object.model(), prepared, integrator, 1e-3, coeffs);
//   if (c.ns > budget_ns) ...  // refuse the change: it would not fit the tick
#pragma once

#include <cstdint>
#include <string>

#include "sim/model.h"
#include "sim/params.h"
#include "sim/sim.h"

namespace rheo::sim {

/// Measured cost of the work a tick does, per element (nodes + edges + faces + tetrahedra) [ns].
struct CostCoefficients {
  double explicit_ns = 0.0;  // one symplectic Euler substep
  double implicit_ns = 0.0;  // one implicit substep without its CG iterations (forces, Jacobian)
  double cg_ns = 0.0;        // one conjugate-gradient iteration of an implicit substep
  // What a tetrahedron whose shape springs are in the implicit system adds (their Jacobian
  // blocks), per such tetrahedron [ns]: to an implicit substep, and to each CG iteration.
  // Sketched meshes put 6 % (4.6k) to all (100k) of their tets there; without these terms the
  // model came out 1.6-1.75x low at 21.6k and 100k (tick_cost_bench).
  double system_ns = 0.0;
  double system_cg_ns = 0.0;
};

/// The prediction for one object.
struct TickCost {
  int32_t substeps = 0;          // per tick
  bool substeps_capped = false;  // the explicit bound asked for more than max_substeps
  int32_t cg_iterations = 0;     // per substep, as estimated (implicit only)
  int64_t elements = 0;          // nodes + edges + faces + tetrahedra
  int64_t system_tets = 0;       // tetrahedra whose shape springs are in the linear system
  double ns = 0.0;               // predicted time of one awake tick [ns]
};

/// Nodes + edges + faces + tetrahedra: what one pass over an object's elements visits.
int64_t ElementCount(const Model& model);

/// CG iterations per implicit substep the model counts on: about 8 at the default tolerance of
/// 5e-3 (the benchmarks measure 1.6-6.4 per tick from 1k to 103k tetrahedra), growing with
/// log(1/tolerance) as a Jacobi-preconditioned CG does, and with `refinement`
/// (CgRefinementScale), never above cg_max_iterations.
int32_t EstimatedCgIterations(const Parameters& params, double refinement = 1.0);

/// The factor on the default tolerance's 8 CG iterations for `model`: the CG carries the step's
/// impulse across the object about an edge per iteration, so the iterations grow with the mean
/// edges across its bounding-box diagonal. Fitted in tick_cost_bench on the pressed bean,
/// 12 x (across / 17.4)^0.75: organ took 12.0 / 17.7 / 24.1 iterations a tick at 17 / 29 / 49
/// across (4.6k / 21.6k / 101k tets); hard and soft jelly were within 15 % of organ at each
/// size, though their (h D + h^2 K) / M differ 3.5x, so the material is left out. Never below 1:
/// coarse meshes keep the 8 (about 10 across and fewer).
double CgRefinementScale(const Model& model);

/// The factor on the CG iterations for substeps longer than the 1 ms the model was fitted at:
/// sqrt(substep / 1 ms), 1 at 1 ms and below. The pressed bean's multi-rate whole took 1.1-1.6x
/// the iterations the model counts on at 1 ms in 2 ms substeps (tick_cost_bench, 4.6k and 21.6k
/// tets, three presets; against 0.6-0.8x at 1 ms), as the dampers' share h D / M of the system
/// doubles.
double CgSubstepScale(double substep);

/// The implicit integrator's time of one awake tick [ns] for `cost`'s substeps, elements and
/// system tetrahedra, at `cg_iterations` per substep (PredictTickCost's estimate, or a count
/// measured elsewhere).
double ImplicitTickNs(const TickCost& cost, double cg_iterations, const CostCoefficients& c);

/// The cost of one awake tick of `dt` [s] for an object of `model` stepped with `prepared`
/// (from SimObject::Prepare) and `integrator`.
TickCost PredictTickCost(const Model& model, const PreparedParameters& prepared,
                         Integrator integrator, double dt, const CostCoefficients& coefficients);

/// "4936 tetrahedra, implicit, 1 substep, about 8 CG iterations": what a prediction counted.
std::string DescribeTickCost(const Model& model, const TickCost& cost, Integrator integrator);

}  // namespace rheo::sim
