// Force terms and their linearisation (internal to rheo_sim).
#pragma once

#include <span>

#include "sim/model.h"
#include "sim/params.h"
#include "sim/state.h"

namespace rheo::sim::internal {

/// Which terms are on, decided once per parameter change so that an off term costs nothing.
struct ActiveTerms {
  bool edges = false;
  bool nonlinear_damper = false;
  bool global_volume = false;
  bool area = false;
  bool tet_volume = false;
  bool gravity = false;
  bool floor = false;
};

ActiveTerms DecideTerms(const Model& model, const Parameters& params);

/// state.f = every force at (state.x, state.v); updates state.tension. With `advance_a`, advances
/// every Voigt ratio over h holding the current l, dl/dt. For each term on in `linearise` (a subset
/// of `terms`; all off for the explicit integrator), fills its blocks of the implicit system for h.
void ComputeForces(const Model& model, const Parameters& params, const ActiveTerms& terms,
                   State& state, double h, bool advance_a, const ActiveTerms& linearise);

/// out = (h D + h^2 K) p with D, K the positive semi-definite damping and stiffness
/// approximations stored by ComputeForces for the terms on in `terms`; with stiffness_only, only
/// h^2 K p.
void ApplyJacobian(const Model& model, const ActiveTerms& terms, const State& state,
                   std::span<const Vec3> p, std::span<Vec3> out, bool stiffness_only);

/// Volume enclosed by the boundary faces [m^3].
double EnclosedVolume(const Model& model, std::span<const Vec3> x);

}  // namespace rheo::sim::internal
