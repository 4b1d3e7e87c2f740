#include "sim/params.h"

#include <array>
#include <charconv>
#include <cmath>
#include <string>

#include "common/format.h"

namespace rheo::sim {
namespace {

using P = Parameters;

constexpr std::array<ParameterInfo, 28> kTable = {{
    {"density", &P::density, 1.0, 1e5, "kg/m^3", "material density (lumped masses)"},
    {"k_v", &P::k_v, 0.0, 1e7, "N/m", "Voigt spring elasticity per edge (eq. 2)"},
    {"c_v", &P::c_v, 1e-6, 1e6, "N s/m", "Voigt damper viscosity per edge (eq. 2)"},
    {"voigt_ratio", &P::voigt_ratio, 0.05, 0.95, "-", "rest length share of the Voigt part"},
    {"damper_a", &P::damper_a, 1e-6, 1e8, "N s/m", "A of the nonlinear damper (eq. 3)"},
    {"damper_b", &P::damper_b, 0.0, 1e3, "1/N", "B of the nonlinear damper (eq. 3)"},
    {"f_min", &P::f_min, 0.0, 1e6, "N", "force below which c_d = c_max (eq. 3)"},
    {"f_max", &P::f_max, 0.0, 1e6, "N", "force above which c_d = c_min (eq. 3)"},
    {"volume_k", &P::volume_k, 0.0, 1e16, "N/m^5", "K of the global volume condition (eq. 4)"},
    {"volume_c", &P::volume_c, 0.0, 1e14, "N s/m^5", "C of the global volume condition (eq. 4)"},
    {"area_k", &P::area_k, 0.0, 1e6, "N", "k of the surface area springs (eq. 5)"},
    {"tet_k", &P::tet_k, 0.0, 1e6, "N", "k of the tetrahedron volume springs (eq. 6)"},
    {"gravity", &P::gravity, 0.0, 100.0, "m/s^2", "gravitational acceleration along -y"},
    {"floor_enabled", &P::floor_enabled, 0.0, 1.0, "-", "1 = floor plane present"},
    {"floor_height", &P::floor_height, -1e3, 1e3, "m", "floor plane y"},
    {"friction", &P::friction, 0.0, 10.0, "-", "Coulomb friction coefficient with the floor"},
    {"max_substeps", &P::max_substeps, 1.0, 10000.0, "-", "cap on explicit substeps per tick"},
    {"implicit_damping", &P::implicit_damping, 0.0, 1.0, "-",
     "1 = edge damper diagonal implicit in symplectic Euler"},
    {"implicit_substeps", &P::implicit_substeps, 1.0, 1000.0, "-",
     "substeps per tick of the implicit integrator"},
    {"implicit_order", &P::implicit_order, 1.0, 2.0, "-",
     "1 = backward Euler, 2 = BDF2 for the implicit integrator"},
    {"cg_tolerance", &P::cg_tolerance, 1e-14, 1.0, "-", "relative CG residual to stop at"},
    {"cg_max_iterations", &P::cg_max_iterations, 1.0, 10000.0, "-", "CG iteration cap"},
    {"cg_iteration_budget", &P::cg_iteration_budget, 0.0, 100.0, "-",
     "CG iterations a substep at most, as a multiple of their running mean (0: no budget)"},
    {"cg_preconditioner", &P::cg_preconditioner, 0.0, 1.0, "-",
     "0 = Jacobi, 1 = 3x3 block Jacobi for the implicit integrator's CG"},
    {"jacobian_lag", &P::jacobian_lag, 1.0, 16.0, "-",
     "substeps the implicit CG's assembled blocks are kept for (the residual is always fresh)"},
    {"max_speed", &P::max_speed, 1e-3, 1e5, "m/s", "node speed treated as an explosion"},
    {"sleep_speed", &P::sleep_speed, 0.0, 1.0, "m/s", "speed under which nodes are at rest"},
    {"sleep_time", &P::sleep_time, 0.0, 1e6, "s", "rest time before sleeping (0: never)"},
}};

std::string RangeText(const ParameterInfo& info) {
  return Format("[%g, %g] %s", info.min, info.max, info.unit);
}

const ParameterInfo* Find(std::string_view name) {
  for (const auto& info : kTable) {
    if (name == info.name) return &info;
  }
  return nullptr;
}

std::string KnownNames() {
  std::string s;
  for (size_t i = 0; i < kTable.size(); ++i) {
    if (!s.empty()) s += ", ";
    s += kTable[i].name;
  }
  return s;
}

Status CheckOne(const ParameterInfo& info, double value) {
  if (!std::isfinite(value) || value < info.min || value > info.max) {
    return InvalidArgument("parameter '" + std::string(info.name) + "' = " + Num(value) +
                           " is out of range " + RangeText(info));
  }
  return Status::Ok();
}

Status CheckCross(const Parameters& p) {
  if (p.f_min > p.f_max) {
    return InvalidArgument("parameter 'f_min' (" + Num(p.f_min) + " N) must not exceed 'f_max' (" +
                           Num(p.f_max) + " N)");
  }
  return Status::Ok();
}

Parameters SoftJelly() {
  Parameters p;
  p.k_v = 60.0;
  p.c_v = 0.2;
  p.damper_a = 2e4;
  p.damper_b = 3.0;
  p.f_min = 0.3;
  p.f_max = 1.5;
  p.volume_k = 3e8;
  p.volume_c = 0.0;
  p.area_k = 0.02;
  p.tet_k = 0.02;
  return p;
}

Parameters HardJelly() {
  Parameters p;
  p.k_v = 400.0;
  p.c_v = 0.5;
  p.damper_a = 1e5;
  p.damper_b = 2.0;
  p.f_min = 1.0;
  p.f_max = 4.0;
  p.volume_k = 1e9;
  p.area_k = 0.1;
  p.tet_k = 0.1;
  return p;
}

Parameters Clay() {
  Parameters p;
  p.density = 1800.0;
  p.k_v = 80.0;
  p.c_v = 0.6;
  p.damper_a = 47438.0;
  p.damper_b = 15.0;
  p.f_min = 0.15;
  p.f_max = 0.6;
  p.volume_k = 5e8;
  p.area_k = 0.01;
  p.tet_k = 0.05;
  p.friction = 0.9;
  return p;
}

Parameters Organ() {
  Parameters p;
  p.density = 1050.0;
  p.k_v = 150.0;
  p.c_v = 0.4;
  p.damper_a = 3e4;
  p.damper_b = 2.0;
  p.f_min = 0.5;
  p.f_max = 3.0;
  p.volume_k = 5e8;
  p.volume_c = 0.0;
  p.area_k = 0.05;
  p.tet_k = 0.05;
  p.friction = 0.3;
  return p;
}

const std::array<Preset, 4>& PresetArray() {
  static const std::array<Preset, 4> presets = {{
      {"soft-jelly", "wobbly, elastic, creeps only under strong force", SoftJelly(),
       Integrator::kSymplecticEuler},
      {"hard-jelly", "stiff elastic gel", HardJelly(), Integrator::kImplicitEuler},
      {"clay", "low yield force: keeps dents (plastic)", Clay(), Integrator::kSymplecticEuler},
      {"organ", "soft tissue: viscoelastic, slightly plastic under large force", Organ(),
       Integrator::kSymplecticEuler},
  }};
  return presets;
}

}  // namespace

Result<Integrator> ParseIntegrator(std::string_view name) {
  if (name == "symplectic-euler") return Integrator::kSymplecticEuler;
  if (name == "implicit-euler") return Integrator::kImplicitEuler;
  return InvalidArgument("unknown integrator '" + std::string(name) +
                         "'; known: symplectic-euler, implicit-euler");
}

const char* IntegratorName(Integrator integrator) {
  return integrator == Integrator::kSymplecticEuler ? "symplectic-euler" : "implicit-euler";
}

std::span<const ParameterInfo> ParameterTable() {
  return kTable;
}

Status SetParameterByName(Parameters& params, std::string_view name, double value) {
  const ParameterInfo* info = Find(name);
  if (info == nullptr) {
    return InvalidArgument("unknown parameter '" + std::string(name) + "'; known: " + KnownNames());
  }
  if (Status s = CheckOne(*info, value); !s.ok()) return s;
  Parameters next = params;
  next.*(info->field) = value;
  if (Status s = CheckCross(next); !s.ok()) return s;
  params = next;
  return Status::Ok();
}

Result<double> GetParameterByName(const Parameters& params, std::string_view name) {
  const ParameterInfo* info = Find(name);
  if (info == nullptr) {
    return InvalidArgument("unknown parameter '" + std::string(name) + "'; known: " + KnownNames());
  }
  return params.*(info->field);
}

Status ValidateParameters(const Parameters& params) {
  for (const auto& info : ParameterTable()) {
    if (Status s = CheckOne(info, params.*(info.field)); !s.ok()) return s;
  }
  return CheckCross(params);
}

std::span<const Preset> Presets() {
  return PresetArray();
}

Result<Preset> FindPreset(std::string_view name) {
  for (const auto& p : PresetArray()) {
    if (name == p.name) return p;
  }
  return InvalidArgument("unknown preset '" + std::string(name) +
                         "'; known: soft-jelly, hard-jelly, clay, organ");
}

bool ParseSetting(std::string_view text, std::string* name, double* value) {
  const size_t eq = text.find('=');
  if (eq == std::string_view::npos || eq == 0) return false;
  const char* first = text.data() + eq + 1;
  const char* last = text.data() + text.size();
  double v = 0.0;
  const auto [end, ec] = std::from_chars(first, last, v);
  if (ec != std::errc() || end != last || first == last) return false;
  *name = std::string(text.substr(0, eq));
  *value = v;
  return true;
}

}  // namespace rheo::sim
