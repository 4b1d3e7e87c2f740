// Run-time parameters of a rheological object: the constants of eqs. 2-6 of the paper plus the
// scene terms (gravity, floor) and the numerics. Every constant has a name and a validated range.
#pragma once

#include <span>
#include <string>
#include <string_view>

#include "common/status.h"

namespace rheo::sim {

/// Time integration schemes.
enum class Integrator {
  /// Semi-implicit (symplectic) Euler with as many substeps per tick as the explicit stability
  /// bound asks for (capped by `max_substeps`); the edge dampers' diagonal is implicit unless
  /// `implicit_damping` is 0. Cheapest per substep; the default for soft objects.
  kSymplecticEuler,
  /// Linearised backward Euler (one Newton step per substep), solved matrix-free by conjugate
  /// gradients warm-started from the previous tick. Unconditionally stable for the linearised
  /// system, so stiff presets run with one substep per tick.
  kImplicitEuler,
};

/// "symplectic-euler" | "implicit-euler".
Result<Integrator> ParseIntegrator(std::string_view name);
const char* IntegratorName(Integrator integrator);

/// All constants. The per-element constants are per element, as in the paper: every edge has its
/// own three-element model with these k_v, c_v, A, B, f_min, f_max.
struct Parameters {
  // Mass.
  double density = 1000.0;  // material density [kg/m^3]; lumped masses = density * volume share
  // Three-element model (eq. 2), per edge.
  double k_v = 100.0;        // Voigt spring elasticity [N/m]
  double c_v = 0.3;          // Voigt damper viscosity [N s/m]
  double voigt_ratio = 0.5;  // rest value of a: Voigt natural length L_k = ratio * rest length [-]
  // Force-dependent nonlinear damper (eq. 3): c_d = A exp(-B |f|) clamped to [c_min, c_max].
  double damper_a = 50.0;  // A [N s/m]
  double damper_b = 2.0;   // B [1/N]; 0 makes c_d = A constant (a linear damper)
  double f_min = 0.5;      // below this |f| the damper viscosity is c_max = A exp(-B f_min) [N]
  double f_max = 2.0;      // above this |f| the damper viscosity is c_min = A exp(-B f_max) [N]
  // Global volume condition (eq. 4): p = -K (V - V_init) - C dV/dt on every surface face.
  double volume_k = 1e8;  // K [N/m^5] (pressure per unit volume change)
  double volume_c = 0.0;  // C [N s/m^5]
  // Shape maintenance (eqs. 5, 6).
  double area_k = 0.05;  // k of eq. 5, per surface triangle [N]
  double tet_k = 0.05;   // k of eq. 6, per tetrahedron [N]
  // Scene.
  double gravity = 9.81;       // gravitational acceleration along -y [m/s^2]
  double floor_enabled = 1.0;  // 1: floor plane y = floor_height; 0: no floor [-]
  double floor_height = 0.0;   // [m]
  double friction = 0.6;       // Coulomb friction coefficient with the floor [-]
  // Numerics.
  double max_substeps = 64;        // cap on substeps per tick [-]
  double implicit_damping = 0.0;   // 1: symplectic Euler treats the edge dampers' diagonal
                                   // implicitly, lifting the damping step bound [-]
  double implicit_substeps = 1;    // substeps per tick of the implicit integrator, at least one
                                   // per 5 ms of the tick [-]
  double implicit_order = 2;       // 1: backward Euler; 2: BDF2 (second order) [-]
  double cg_tolerance = 5e-3;      // relative residual at which CG stops [-] (sim_bench cg)
  double cg_max_iterations = 60;   // [-]
  double cg_iteration_budget = 2;  // a substep's CG stops after this many times the running mean
                                   // of its iterations (at least 8): the impact's solves, 3-5x
                                   // the mean, made the slowest ticks; 0: cg_max_iterations only
                                   // (sim_bench budget) [-]
  double cg_preconditioner = 0;    // 0: Jacobi (the system's diagonal); 1: 3x3 block Jacobi (each
                                   // node's block: 20 % fewer CG iterations, no faster overall on
                                   // the sketched bean, bench/sim/results/sketched.txt) [-]
  double jacobian_lag = 1;         // substeps the implicit system's assembled edge blocks are
                                   // kept for (1: rebuilt every substep); the residual is always
                                   // the current one, so only the CG's operator lags: 2 saves
                                   // 7-13 % of a 21.6k-tet tick, at up to 1.7x the error of the
                                   // step at the impact (sim_bench budget) [-]
  double max_speed = 100.0;        // a node faster than this is an explosion [m/s]
  double sleep_speed = 1e-4;       // below this for sleep_time every node is at rest [m/s]
  double sleep_time = 0.5;         // [s]; 0 disables sleeping
};

/// Name, range and unit of one parameter (the run-time settable table).
struct ParameterInfo {
  const char* name;
  double Parameters::*field;
  double min;  // inclusive
  double max;  // inclusive
  const char* unit;
  const char* description;
};

/// Every settable parameter, in a fixed order.
std::span<const ParameterInfo> ParameterTable();

/// Sets `name` to `value` after checking the range (and f_min <= f_max). INVALID_ARGUMENT names the
/// parameter and its range; an unknown name lists the known ones.
Status SetParameterByName(Parameters& params, std::string_view name, double value);
Result<double> GetParameterByName(const Parameters& params, std::string_view name);

/// A `name=number` setting (the command lines' --set): false when `text` is not one (no name,
/// or anything but a whole number after the '='). The name is not checked here.
bool ParseSetting(std::string_view text, std::string* name, double* value);

/// Checks every field (used when a whole Parameters struct is handed in).
Status ValidateParameters(const Parameters& params);

/// Preset material and its recommended integrator. Values are documented in presets.cc and
/// docs: they are tuned for objects around 10 cm across meshed with 1k-20k tetrahedra (edges
/// 3-10 mm), because the paper's constants are per element.
struct Preset {
  const char* name;
  const char* description;
  Parameters params;
  Integrator integrator;
};

/// "soft-jelly", "hard-jelly", "clay", "organ".
std::span<const Preset> Presets();
Result<Preset> FindPreset(std::string_view name);

}  // namespace rheo::sim
