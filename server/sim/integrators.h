// Time integration schemes (internal to rheo_sim). Both take substeps of h, never allocate, and
// add the floor reaction of this tick into state.floor_reaction (as force averaged over `tick`).
#pragma once

#include "sim/forces.h"

namespace rheo::sim::internal {

/// v += h M^-1 f(x, v); floor projection on v; x += h v. Voigt ratios advanced exactly for the
/// frozen l, dl/dt (element.h).
void SymplecticEulerSubstep(const Model& model, const Parameters& params, const ActiveTerms& terms,
                            State& state, double h, double tick);

struct SolveStats {
  int32_t iterations = 0;
  double residual = 0.0;  // relative
};

/// Linearised backward Euler (Baraff-Witkin): (M + h D + h^2 K) dv = h f + h^2 K_f v with the
/// PSD approximations of forces.h; dv by Jacobi-preconditioned CG warm-started with the previous
/// dv; then the same floor projection and x += h v. Only the terms on in `implicit_terms` enter
/// D and K; the others act explicitly (the caller keeps h within their explicit bound).
SolveStats ImplicitEulerSubstep(const Model& model, const Parameters& params,
                                const ActiveTerms& terms, const ActiveTerms& implicit_terms,
                                State& state, double h, double tick);

}  // namespace rheo::sim::internal
