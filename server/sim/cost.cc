#include "sim/cost.h"

#include <algorithm>
#include <cmath>

#include "common/format.h"

namespace rheo::sim {
namespace {

// Iterations counted at the default tolerance, and that tolerance.
constexpr double kIterationsAtDefault = 8.0;
constexpr double kDefaultTolerance = 5e-3;
// How the iterations grow with the edges across the object (CgRefinementScale): the pressed
// 5k-tet bean (a 113 mm diagonal over 6.5 mm mean edges: 17.4 across) took 12 a tick.
constexpr double kReferenceEdgesAcross = 17.4;
constexpr double kIterationsAtReference = 12.0;
constexpr double kRefinementExponent = 0.75;
// The substep those iterations were counted at, and how they grow beyond it (CgSubstepScale).
constexpr double kCountedSubstep = 1e-3;
constexpr double kSubstepExponent = 0.5;

}  // namespace

int64_t ElementCount(const Model& m) {
  return static_cast<int64_t>(m.num_nodes) + static_cast<int64_t>(m.edges.size()) +
         static_cast<int64_t>(m.faces.size()) + static_cast<int64_t>(m.tets.size());
}

int32_t EstimatedCgIterations(const Parameters& p, double refinement) {
  const double tol = std::clamp(p.cg_tolerance, 1e-300, 1.0);
  const double scale = std::log(1.0 / tol) / std::log(1.0 / kDefaultTolerance);
  const double it =
      std::ceil(kIterationsAtDefault * std::max(scale, 0.25) * std::max(refinement, 1.0));
  return static_cast<int32_t>(std::clamp(it, 1.0, std::max(1.0, p.cg_max_iterations)));
}

double CgRefinementScale(const Model& model) {
  if (model.edge_rest_length.empty() || !(model.size > 0.0)) return 1.0;
  double sum = 0.0;
  for (double l : model.edge_rest_length) sum += l;
  const double mean = sum / static_cast<double>(model.edge_rest_length.size());
  if (!(mean > 0.0)) return 1.0;
  const double across = model.size / mean;
  return std::max(1.0, kIterationsAtReference / kIterationsAtDefault *
                           std::pow(across / kReferenceEdgesAcross, kRefinementExponent));
}

double CgSubstepScale(double substep) {
  if (!(substep > kCountedSubstep)) return 1.0;
  return std::pow(substep / kCountedSubstep, kSubstepExponent);
}

double ImplicitTickNs(const TickCost& cost, double cg, const CostCoefficients& c) {
  const double n = static_cast<double>(cost.elements);
  const double t = static_cast<double>(cost.system_tets);
  return cost.substeps *
         (n * (c.implicit_ns + cg * c.cg_ns) + t * (c.system_ns + cg * c.system_cg_ns));
}

TickCost PredictTickCost(const Model& model, const PreparedParameters& prepared,
                         Integrator integrator, double dt, const CostCoefficients& c) {
  const Parameters& p = prepared.params;
  TickCost out;
  out.elements = ElementCount(model);
  const double n = static_cast<double>(out.elements);
  if (integrator == Integrator::kSymplecticEuler) {
    // As SimObject::Step does: the stability bound's substeps, capped by max_substeps.
    const double k =
        prepared.h_stable > 0.0 ? SimObject::RequiredSubsteps(prepared.h_stable, dt) : 1e9;
    out.substeps_capped = k > p.max_substeps;
    out.substeps = static_cast<int32_t>(std::min(k, std::max(1.0, p.max_substeps)));
    out.ns = out.substeps * n * c.explicit_ns;
  } else {
    out.substeps = SimObject::ImplicitSubsteps(p, dt);
    out.cg_iterations =
        EstimatedCgIterations(p, CgRefinementScale(model) * CgSubstepScale(dt / out.substeps));
    out.system_tets = prepared.implicit_tets;
    out.ns = ImplicitTickNs(out, out.cg_iterations, c);
  }
  return out;
}

std::string DescribeTickCost(const Model& model, const TickCost& cost, Integrator integrator) {
  std::string s = std::to_string(model.tets.size()) + " tetrahedra, ";
  if (integrator == Integrator::kSymplecticEuler) {
    s += "symplectic Euler, " + std::to_string(cost.substeps) +
         (cost.substeps == 1 ? " substep" : " substeps");
    if (cost.substeps_capped) s += " (capped by max_substeps: too stiff for the tick)";
  } else {
    s += "implicit, " + std::to_string(cost.substeps) +
         (cost.substeps == 1 ? " substep" : " substeps") + ", about " +
         std::to_string(cost.cg_iterations) + " CG iterations each";
    if (cost.system_tets > 0)
      s += ", " + std::to_string(cost.system_tets) + " tetrahedra in the linear system";
  }
  return s;
}

}  // namespace rheo::sim
