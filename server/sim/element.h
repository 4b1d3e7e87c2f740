// One three-element model (eq. 2) with the force-dependent nonlinear damper (eq. 3): the scalar
// laws every edge of the object follows. Public so the closed-form tests can reach them.
#pragma once

#include <algorithm>
#include <cmath>

#include "sim/params.h"

namespace rheo::sim {

/// Damper viscosity c_d of eq. 3 for an element carrying force magnitude `force` [N]; returns
/// [N s/m]. c_max = A exp(-B f_min) below f_min, c_min = A exp(-B f_max) above f_max.
inline double DamperViscosity(const Parameters& p, double force) {
  const double f = std::clamp(std::abs(force), p.f_min, p.f_max);
  return p.damper_a * std::exp(-p.damper_b * f);
}

/// Tension of the element (positive pulls the ends together) [N]. Eq. 2 with da/dt substituted:
/// f = c_d ((1 - a) dl - da l) = c_d / (c_v + c_d) * (k_v (a l - L) + c_v dl).
inline double ThreeElementTension(double k_v, double c_v, double c_d, double a, double l,
                                  double rest_voigt_length, double l_dot) {
  return c_d / (c_v + c_d) * (k_v * (a * l - rest_voigt_length) + c_v * l_dot);
}

/// da/dt of eq. 2 [1/s].
inline double VoigtRatioRate(double k_v, double c_v, double c_d, double a, double l,
                             double rest_voigt_length, double l_dot) {
  return (-k_v * (a * l - rest_voigt_length) - (c_v * a - c_d * (1.0 - a)) * l_dot) /
         ((c_v + c_d) * l);
}

/// Advances a over h [s] holding l and dl/dt fixed. Eq. 2 is then linear in a,
/// da/dt = alpha - beta a, and this is its exact solution, so the update is stable for any k_v/c
/// and step, and exact for a held extension (the relaxation test).
inline double AdvanceVoigtRatio(double k_v, double c_v, double c_d, double a, double l,
                                double rest_voigt_length, double l_dot, double h) {
  const double denom = (c_v + c_d) * l;
  const double alpha = (k_v * rest_voigt_length + c_d * l_dot) / denom;
  const double beta = (k_v * l + (c_v + c_d) * l_dot) / denom;
  const double x = beta * h;
  // phi = (1 - exp(-x)) / x, written to stay accurate near x = 0.
  const double phi = std::abs(x) < 1e-3 ? 1.0 - x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0)))
                                        : -std::expm1(-x) / x;
  return a + (alpha - beta * a) * h * phi;
}

}  // namespace rheo::sim
