#include "sim/sim.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "sim/element.h"
#include "sim/forces.h"
#include "sim/integrators.h"

namespace rheo::sim {

// Longest substep of the implicit integrator [s].
constexpr double kMaxImplicitStep = 5e-3;

// Steps between snapshots of the last good state (a restore goes back at most this many ticks).
constexpr int32_t kSnapshotInterval = 8;

namespace {

// The symmetrically scaled Gershgorin bounds (UpdateDerived, ShapeSpringsTreatment): a pair (i, j)
// of a spring with stiffness k adds k (1/m_i + 1/sqrt(m_i m_j)) to row i of M^-1/2 K M^-1/2;
// nothing to the row of a fixed node, and no cross term to a fixed neighbour.
double GershgorinShare(double m_i, double m_j, bool fixed_i, bool fixed_j, double k) {
  if (fixed_i) return 0.0;
  return k * (1.0 / m_i + (fixed_j ? 0.0 : 1.0 / std::sqrt(m_i * m_j)));
}

// Bounds on the stiffness of one area spring (eq. 5) and one tet spring (eq. 6) between two of
// their nodes [N/m]: k over the element's smallest height, with the margins of their gradients.
double FaceSpringStiffness(const Model& m, const Parameters& p, size_t f) {
  return 1.5 * p.area_k / std::max(m.face_min_height[f], 1e-12);
}
double TetSpringStiffness(const Model& m, const Parameters& p, size_t t) {
  return (4.0 / 3.0) * p.tet_k / std::max(m.tet_min_height[t], 1e-12);
}

}  // namespace

void InitState(const Model& m, double voigt_ratio, State& s) {
  const size_t n = m.num_nodes;
  const size_t ne = m.edges.size();
  s.time = 0.0;
  s.x = m.rest_positions;
  s.v.assign(n, Vec3::Zero());
  s.a.assign(ne, voigt_ratio);
  s.tension.assign(ne, 0.0);
  s.f_ext.assign(n, Vec3::Zero());
  s.k_ext.assign(n, 0.0);
  s.x_ext.assign(n, Vec3::Zero());
  s.ext_springs = 0;
  s.floor_reaction.assign(n, Vec3::Zero());
  s.f.assign(n, Vec3::Zero());
  s.vol_grad.assign(n, Vec3::Zero());
  s.damp_diag.assign(n, 0.0);
  // Whole groups of internal::kEdgeBlock edges (forces.h): the block product reads the edge
  // directions and dampers a group at a time, zeros past the last edge.
  const size_t groups = (ne + internal::kEdgeBlock - 1) / internal::kEdgeBlock;
  for (auto* vec : {&s.edge_ex, &s.edge_ey, &s.edge_ez, &s.edge_axial_c})
    vec->assign(internal::kEdgeBlock * groups, 0.0);
  s.edge_axial_k.assign(ne, 0.0);
  s.edge_lateral.assign(ne, 0.0);
  s.edge_block.assign(m.edge_tet_start.empty() ? 0 : 9 * internal::kEdgeBlock * groups, 0.0f);
  s.shape_coef.assign(m.faces.size(), 0.0);
  s.shape_dir.assign(3 * m.faces.size(), Vec3::Zero());
  s.tet_w.assign(12 * m.tets.size(), 0.0f);
  s.tet_coef.assign(m.tets.size(), 0.0);
  s.tet_implicit.assign(m.tets.size(), 0);
  s.tet_stiffness.assign(m.tets.size(), 0.0);
  s.tet_rows.assign(4 * m.tets.size(), 0.0);
  s.f_tet_implicit.assign(n, Vec3::Zero());
  for (auto* vec : {&s.cg_r, &s.cg_z, &s.cg_p, &s.cg_q, &s.dv, &s.x_prev, &s.v_prev, &s.f_shape,
                    &s.f_shape_prev, &s.dv_prev})
    vec->assign(n, Vec3::Zero());
  s.diag.assign(n, 1.0);
  s.floor_impulse.assign(n, Vec3::Zero());
  s.floor_stick.assign(n, 0);
  for (auto* vec : {&s.inv_diag3, &s.mass3, &s.keep3, &s.sys_mass3}) vec->assign(3 * n, 0.0);
  s.pre_block.assign(6 * static_cast<size_t>(n), 0.0);
  s.good_x = s.x;
  s.good_v = s.v;
  s.good_a = s.a;
  s.good_tension = s.tension;
  s.good_time = 0.0;
  s.have_prev = false;
}

SimObject::SimObject(Model model, const Parameters& params, Integrator integrator)
    : model_(std::move(model)), params_(params), integrator_(integrator) {
  unit_mass_.resize(model_.mass.size());
  for (size_t i = 0; i < unit_mass_.size(); ++i) unit_mass_[i] = model_.mass[i] / params_.density;
  InitState(model_, params_.voigt_ratio, state_);
  UpdateDerived();
}

void SimObject::ApplyDensity(double density) {
  for (int32_t i = 0; i < model_.num_nodes; ++i) {
    model_.mass[i] = unit_mass_[i] * density;
    model_.inv_mass[i] = model_.fixed[i] ? 0.0 : 1.0 / model_.mass[i];
  }
}

void SimObject::SyncNodeArrays() {
  for (int32_t i = 0; i < model_.num_nodes; ++i) {
    for (int c = 0; c < 3; ++c) {
      state_.mass3[3 * i + c] = model_.mass[i];
      state_.keep3[3 * i + c] = model_.fixed[i] ? 0.0 : 1.0;
    }
  }
}

Result<std::unique_ptr<SimObject>> SimObject::Create(const TetMesh& mesh, const Parameters& params,
                                                     Integrator integrator) {
  if (Status s = ValidateParameters(params); !s.ok()) return s.error();
  Result<Model> model = BuildModel(mesh, params.density);
  if (!model.ok()) return model.error();
  return std::unique_ptr<SimObject>(new SimObject(std::move(*model), params, integrator));
}

Result<std::unique_ptr<SimObject>> SimObject::Create(const TetMesh& mesh, std::string_view preset) {
  Result<Preset> p = FindPreset(preset);
  if (!p.ok()) return p.error();
  return Create(mesh, p->params, p->integrator);
}

Result<std::unique_ptr<SimObject>> SimObject::Create(Model model, const Parameters& params,
                                                     Integrator integrator) {
  if (Status s = ValidateParameters(params); !s.ok()) return s.error();
  if (model.num_nodes <= 0) return InvalidArgument("model has no nodes");
  return std::unique_ptr<SimObject>(new SimObject(std::move(model), params, integrator));
}

Status SimObject::SetParameter(std::string_view name, double value) {
  const double old_density = params_.density;
  if (Status s = SetParameterByName(params_, name, value); !s.ok()) return s;
  if (params_.density != old_density) ApplyDensity(params_.density);
  // A new voigt_ratio moves the Voigt natural length from the next step on; nothing to redo.
  UpdateDerived();
  state_.edge_block_age = -1;  // the kept blocks (jacobian_lag) describe the old parameters
  Wake();
  return Status::Ok();
}

Status SimObject::SetParameters(const Parameters& params) {
  if (Status s = ValidateParameters(params); !s.ok()) return s;
  params_ = params;
  ApplyDensity(params_.density);
  UpdateDerived();
  state_.edge_block_age = -1;  // the kept blocks (jacobian_lag) describe the old parameters
  Wake();
  return Status::Ok();
}

Result<PreparedParameters> SimObject::Prepare(const Parameters& params, Integrator integrator,
                                              double dt) const {
  if (Status s = ValidateParameters(params); !s.ok()) return s.error();
  if (!(dt > 0.0) || !std::isfinite(dt)) return InvalidArgument("tick must be positive");
  const auto n = static_cast<size_t>(model_.num_nodes);
  const size_t nt = model_.tets.size();
  PreparedParameters out;
  out.params = params;
  std::vector<double> mass(n);
  for (size_t i = 0; i < n; ++i) mass[i] = unit_mass_[i] * params.density;
  std::vector<Vec3> acc(n, Vec3::Zero());
  out.h_stable = StableStep(params, mass, acc);
  if (integrator == Integrator::kImplicitEuler) {
    std::vector<double> rows(4 * nt), sorted(nt);
    out.tet_implicit.assign(nt, 0);
    out.shape_h = dt / ImplicitSubsteps(params, dt);
    out.shape = DecideShape(params, out.shape_h, mass, acc, rows, sorted, out.tet_implicit,
                            &out.implicit_tets);
  }
  return out;
}

Status SimObject::SetParameters(PreparedParameters& prepared) {
  if (Status s = ValidateParameters(prepared.params); !s.ok()) return s;
  params_ = prepared.params;
  ApplyDensity(params_.density);
  SyncNodeArrays();
  h_stable_ = prepared.h_stable;
  shape_checked_h_ = -1.0;
  if (prepared.shape_h > 0.0 && prepared.tet_implicit.size() == state_.tet_implicit.size()) {
    std::swap(state_.tet_implicit, prepared.tet_implicit);
    shape_treatment_ = prepared.shape;
    shape_implicit_tets_ = prepared.implicit_tets;
    shape_checked_h_ = prepared.shape_h;
  }
  state_.edge_block_age = -1;
  Wake();
  return Status::Ok();
}

int32_t SimObject::ImplicitSubsteps(const Parameters& p, double dt) {
  // The linearised step is stable for any h but not accurate for long ones: the springs'
  // directions change within a step. Ticks over kMaxImplicitStep are split (offline runs).
  return std::max(static_cast<int32_t>(p.implicit_substeps),
                  static_cast<int32_t>(std::ceil(dt / kMaxImplicitStep - 1e-9)));
}

void SimObject::SetIntegrator(Integrator integrator) {
  integrator_ = integrator;
  ForgetHistory();
  Wake();
}

void SimObject::UpdateDerived() {
  SyncNodeArrays();
  h_stable_ = StableStep(params_, model_.mass, state_.cg_r);
  shape_checked_h_ = -1.0;
}

double SimObject::StableStep(const Parameters& p, std::span<const double> mass,
                             std::vector<Vec3>& acc) const {
  // Explicit stability bound: Gershgorin on M^-1 K and M^-1 D, the rank-one volume term exactly.
  const Model& m = model_;
  const int32_t n = m.num_nodes;
  const internal::ActiveTerms terms = internal::DecideTerms(m, p);
  // Symmetrically scaled Gershgorin bound on M^-1/2 K M^-1/2 (x) and M^-1/2 D M^-1/2 (y): a pair
  // (i, j) with coupling k adds k (1/m_i + 1/sqrt(m_i m_j)) to row i.
  for (int32_t i = 0; i < n; ++i) acc[i].setZero();
  auto couple = [&](int32_t i, int32_t j, double k, double c) {
    const double w = GershgorinShare(mass[i], mass[j], m.fixed[i], m.fixed[j], 1.0);
    acc[i].x() += k * w;
    acc[i].y() += c * w;
  };
  if (terms.edges) {
    // 1.5: the Voigt ratio a multiplies k_v and can grow beyond its rest value.
    const double k = 1.5 * p.k_v;
    for (const auto& e : m.edges) {
      // With implicit_damping the edge dampers have no step bound (see integrators.cc).
      const double c = p.implicit_damping > 0.5 ? 0.0 : p.c_v;
      couple(e[0], e[1], k, c);
      couple(e[1], e[0], k, c);
    }
  }
  if (terms.area) {
    for (size_t f = 0; f < m.faces.size(); ++f) {
      const double kf = FaceSpringStiffness(m, p, f);
      for (int32_t i : m.faces[f]) {
        for (int32_t j : m.faces[f]) couple(i, j, kf, 0.0);
      }
    }
  }
  if (terms.tet_volume) {
    for (size_t t = 0; t < m.tets.size(); ++t) {
      const double kt = TetSpringStiffness(m, p, t);
      for (int32_t i : m.tets[t]) {
        for (int32_t j : m.tets[t]) couple(i, j, kt, 0.0);
      }
    }
  }
  double omega2 = 0.0, lambda_c = 0.0;
  for (int32_t i = 0; i < n; ++i) {
    omega2 = std::max(omega2, acc[i].x());
    lambda_c = std::max(lambda_c, acc[i].y());
  }
  if (terms.global_volume) {
    // Rest-shape volume gradient (in acc, no longer needed); a_i = sum over faces of
    // (b - a) x (c - a) / 6.
    std::vector<Vec3>& g = acc;
    for (int32_t i = 0; i < n; ++i) g[i].setZero();
    for (const auto& fc : m.faces) {
      const Vec3 gg = (m.rest_positions[fc[1]] - m.rest_positions[fc[0]])
                          .cross(m.rest_positions[fc[2]] - m.rest_positions[fc[0]]) /
                      6.0;
      for (int32_t i : fc) g[i] += gg;
    }
    double sum = 0.0;
    for (int32_t i = 0; i < n; ++i) sum += m.fixed[i] ? 0.0 : g[i].squaredNorm() / mass[i];
    omega2 += 1.5 * p.volume_k * sum;
    lambda_c += p.volume_c * sum;
  }
  const double rate = std::sqrt(omega2) + lambda_c;
  for (int32_t i = 0; i < n; ++i) acc[i].setZero();
  return rate > 0.0 ? 0.9 * 2.0 / rate : 1e30;
}

ShapeTreatment SimObject::ShapeSpringsTreatment(double h) {
  if (h == shape_checked_h_) return shape_treatment_;
  shape_treatment_ = DecideShape(params_, h, model_.mass, state_.cg_r, state_.tet_rows,
                                 state_.tet_stiffness, state_.tet_implicit, &shape_implicit_tets_);
  shape_checked_h_ = h;
  return shape_treatment_;
}

ShapeTreatment SimObject::DecideShape(const Parameters& p, double h, std::span<const double> mass,
                                      std::vector<Vec3>& acc, std::vector<double>& rows,
                                      std::vector<double>& sorted,
                                      std::vector<uint8_t>& tet_implicit,
                                      int32_t* implicit_tets_out) const {
  // In the implicit step the shape springs' forces meet the system matrix M + h D + h^2 K, not M:
  // Gershgorin on M_h^-1/2 K_shape M_h^-1/2 with M_h = M + h D_min (D_min the edge dampers at
  // their least effective viscosity, lumped per node) must stay within half the explicit limit,
  // h^2 omega^2 <= 1. When all of them together do not, the stiffest tets (small heights; a few
  // per cent on sketched meshes) join the linear system and the rest stay explicit: the largest
  // stiffness threshold that keeps the bound is found by bisection over the sorted tets.
  const Model& m = model_;
  const int32_t n = m.num_nodes;
  const size_t nt = m.tets.size();
  const internal::ActiveTerms terms = internal::DecideTerms(m, p);
  // acc: x the effective mass, y the row sum.
  for (int32_t i = 0; i < n; ++i) acc[i] = Vec3(mass[i], 0.0, 0.0);
  if (terms.edges) {
    const double c_low = DamperViscosity(p, terms.nonlinear_damper ? p.f_max : 0.0);
    const double c_eff = c_low * p.c_v / (c_low + p.c_v);
    for (const auto& e : m.edges) {
      acc[e[0]].x() += h * c_eff;
      acc[e[1]].x() += h * c_eff;
    }
  }
  // Row-sum contribution of a spring with stiffness k between i and j (to row i).
  auto coupling = [&](int32_t i, int32_t j, double k) {
    return GershgorinShare(acc[i].x(), acc[j].x(), m.fixed[i], m.fixed[j], k);
  };
  auto tet_k = [&](size_t t) { return TetSpringStiffness(m, p, t); };
  // The faces' row sums (y), and each tet's share of its four nodes' rows (rows), once; the
  // bisection below then only adds shares, so the whole decision is a few passes over the tets
  // (it still runs on the stepping thread when the substep changes or SetParameter is used).
  if (terms.area) {
    for (size_t f = 0; f < m.faces.size(); ++f) {
      const double kf = FaceSpringStiffness(m, p, f);
      for (int32_t i : m.faces[f]) {
        for (int32_t j : m.faces[f]) acc[i].y() += coupling(i, j, kf);
      }
    }
  }
  if (terms.tet_volume) {
    for (size_t t = 0; t < nt; ++t) {
      const double kt = tet_k(t);
      for (int q = 0; q < 4; ++q) {
        double r = 0.0;
        for (int32_t j : m.tets[t]) r += coupling(m.tets[t][q], j, kt);
        rows[4 * t + q] = r;
      }
    }
  }
  // h^2 omega^2 with the faces and the tets no stiffer than k_max (z: the row sums).
  auto bound = [&](double k_max) {
    for (int32_t i = 0; i < n; ++i) acc[i].z() = acc[i].y();
    if (terms.tet_volume) {
      for (size_t t = 0; t < nt; ++t) {
        if (tet_k(t) > k_max) continue;
        for (int q = 0; q < 4; ++q) acc[m.tets[t][q]].z() += rows[4 * t + q];
      }
    }
    double omega2 = 0.0;
    for (int32_t i = 0; i < n; ++i) omega2 = std::max(omega2, acc[i].z());
    return h * h * omega2;
  };
  ShapeTreatment result = ShapeTreatment::kExplicit;
  int32_t implicit_tets = 0;
  if (bound(std::numeric_limits<double>::infinity()) > 1.0) {
    if (!terms.tet_volume || bound(-1.0) > 1.0) {
      result = ShapeTreatment::kImplicit;
      implicit_tets = static_cast<int32_t>(nt);
    } else {
      for (size_t t = 0; t < nt; ++t) sorted[t] = tet_k(t);
      std::sort(sorted.begin(), sorted.end());
      size_t lo = 0, hi = nt;  // bound holds with the first lo tets explicit, not with hi
      while (hi - lo > 1) {
        const size_t mid = (lo + hi) / 2;
        (bound(sorted[mid - 1]) <= 1.0 ? lo : hi) = mid;
      }
      const double k_max = lo > 0 ? sorted[lo - 1] : -1.0;
      for (size_t t = 0; t < nt; ++t) {
        tet_implicit[t] = tet_k(t) > k_max ? 1 : 0;
        implicit_tets += tet_implicit[t];
      }
      result = ShapeTreatment::kSplit;
    }
  }
  for (int32_t i = 0; i < n; ++i) acc[i].setZero();
  *implicit_tets_out = implicit_tets;
  return result;
}

int32_t SimObject::RequiredSubsteps(double dt) const {
  return RequiredSubsteps(h_stable_, dt);
}

int32_t SimObject::RequiredSubsteps(double h_stable, double dt) {
  const double k = std::ceil(dt / h_stable);
  return static_cast<int32_t>(std::clamp(k, 1.0, 1e9));
}

void SimObject::Wake() {
  if (sleeping_) ++events_.wakes;
  sleeping_ = false;
  rest_time_ = 0.0;
}

bool SimObject::SetExternalForce(int32_t node, const Vec3& force, double stiffness) {
  if (node < 0 || node >= model_.num_nodes || !force.allFinite() || !std::isfinite(stiffness) ||
      stiffness < 0.0)
    return false;
  state_.f_ext[node] = force;
  const bool had = state_.k_ext[node] > 0.0;
  state_.k_ext[node] = stiffness;
  state_.x_ext[node] = state_.x[node];
  state_.ext_springs += (stiffness > 0.0) - had;
  if (!force.isZero(0.0)) Wake();
  return true;
}

void SimObject::ClearExternalForces() {
  for (auto& f : state_.f_ext) f.setZero();
  if (state_.ext_springs > 0)
    for (auto& k : state_.k_ext) k = 0.0;
  state_.ext_springs = 0;
  Wake();
}

bool SimObject::SetFixed(int32_t node, bool fixed) {
  if (node < 0 || node >= model_.num_nodes) return false;
  model_.fixed[node] = fixed ? 1 : 0;
  model_.inv_mass[node] = fixed ? 0.0 : 1.0 / model_.mass[node];
  state_.v[node].setZero();
  UpdateDerived();
  Wake();
  return true;
}

bool SimObject::SetNodeState(int32_t node, const Vec3& position, const Vec3& velocity) {
  if (node < 0 || node >= model_.num_nodes || !position.allFinite() || !velocity.allFinite()) {
    return false;
  }
  state_.x[node] = position;
  state_.v[node] = velocity;
  ForgetHistory();
  Wake();
  return true;
}

void SimObject::Translate(const Vec3& offset) {
  for (auto& x : state_.x) x += offset;
  placement_ += offset;
  ForgetHistory();
  for (auto& v : state_.v) v.setZero();
  SaveGood();
  Wake();
}

void SimObject::PlaceRestShape(const Vec3& offset) {
  const Model& m = model_;
  for (int32_t i = 0; i < m.num_nodes; ++i) state_.x[i] = m.rest_positions[i] + offset;
  placement_ = offset;
  for (auto& v : state_.v) v.setZero();
  for (auto& a : state_.a) a = params_.voigt_ratio;
  for (auto& t : state_.tension) t = 0.0;
  for (auto& r : state_.floor_reaction) r.setZero();
  kinetic_energy_ = 0.0;
  ForgetHistory();
}

void SimObject::Reset() {
  PlaceRestShape(Vec3::Zero());
  state_.time = 0.0;
  SaveGood();
  Wake();
}

void SimObject::ForgetHistory() {
  // The implicit integrator's memory of earlier substeps (BDF2 and the CG warm start) no longer
  // describes the state: the next substep starts afresh.
  for (auto& d : state_.dv) d.setZero();
  for (auto& d : state_.dv_prev) d.setZero();
  for (auto& j : state_.floor_impulse) j.setZero();
  for (auto& k : state_.floor_stick) k = 0;
  state_.have_prev = false;
}

void SimObject::SaveGood() {
  std::copy(state_.x.begin(), state_.x.end(), state_.good_x.begin());
  std::copy(state_.v.begin(), state_.v.end(), state_.good_v.begin());
  std::copy(state_.a.begin(), state_.a.end(), state_.good_a.begin());
  std::copy(state_.tension.begin(), state_.tension.end(), state_.good_tension.begin());
  state_.good_time = state_.time;
  steps_since_good_ = 0;
  restored_since_good_ = false;
}

void SimObject::RestoreGood() {
  std::copy(state_.good_x.begin(), state_.good_x.end(), state_.x.begin());
  // Velocities are dropped: replaying them would repeat the same blow-up.
  for (auto& v : state_.v) v.setZero();
  std::copy(state_.good_a.begin(), state_.good_a.end(), state_.a.begin());
  std::copy(state_.good_tension.begin(), state_.good_tension.end(), state_.tension.begin());
  for (auto& r : state_.floor_reaction) r.setZero();
  kinetic_energy_ = 0.0;
  ForgetHistory();
}

void SimObject::ResetShapeAtGood() {
  const Model& m = model_;
  Vec3 good_c = Vec3::Zero(), rest_c = Vec3::Zero();
  double total = 0.0;
  for (int32_t i = 0; i < m.num_nodes; ++i) {
    good_c += m.mass[i] * state_.good_x[i];
    rest_c += m.mass[i] * m.rest_positions[i];
    total += m.mass[i];
  }
  Vec3 offset = total > 0.0 ? Vec3((good_c - rest_c) / total) : Vec3::Zero();
  if (internal::DecideTerms(m, params_).floor) {
    double lowest = std::numeric_limits<double>::infinity();
    for (const Vec3& x : m.rest_positions) lowest = std::min(lowest, x.y());
    offset.y() = std::max(offset.y(), params_.floor_height - lowest);
  }
  PlaceRestShape(offset);
  SaveGood();
}

StepResult SimObject::Step(double dt) {
  StepResult r;
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    r.invalid_dt = true;
    return r;
  }
  ++events_.steps;
  if (sleeping_) {
    state_.time += dt;
    ++events_.sleeping_ticks;
    r.sleeping = true;
    return r;
  }
  const internal::ActiveTerms terms = internal::DecideTerms(model_, params_);
  for (auto& f : state_.floor_reaction) f.setZero();
  int32_t substeps;
  if (integrator_ == Integrator::kSymplecticEuler) {
    substeps = RequiredSubsteps(dt);
    if (substeps > params_.max_substeps) {
      substeps = static_cast<int32_t>(params_.max_substeps);
      r.substeps_capped = true;
      ++events_.capped_ticks;
    }
    const double h = dt / substeps;
    for (int32_t k = 0; k < substeps; ++k) {
      internal::SymplecticEulerSubstep(model_, params_, terms, state_, h, dt);
    }
  } else {
    substeps = ImplicitSubsteps(params_, dt);
    const double h = dt / substeps;
    // The shape springs (eqs. 5-6) are soft next to the edges: within their own explicit bound
    // they stay out of the linear system, which then holds the edges and the rank-one volume term
    // (and, split, the stiffest tets).
    internal::ActiveTerms implicit_terms = terms;
    const ShapeTreatment shape = ShapeSpringsTreatment(h);
    state_.tet_split = shape == ShapeTreatment::kSplit;
    if (shape != ShapeTreatment::kImplicit) implicit_terms.area = false;
    if (shape == ShapeTreatment::kExplicit) implicit_terms.tet_volume = false;
    state_.system_elements = shape == ShapeTreatment::kImplicit
                                 ? static_cast<int64_t>(model_.tets.size() + model_.faces.size())
                             : shape == ShapeTreatment::kSplit ? shape_implicit_tets_
                                                               : 0;
    for (int32_t k = 0; k < substeps; ++k) {
      const internal::SolveStats st =
          internal::ImplicitEulerSubstep(model_, params_, terms, implicit_terms, state_, h, dt);
      r.solver_iterations += st.iterations;
      r.solver_residual = st.residual;
    }
  }
  state_.time += dt;
  r.substeps = substeps;
  events_.substeps += substeps;

  // One pass: finite-ness, explosion, rest detection.
  double max_speed2 = 0.0, twice_kinetic = 0.0;
  bool finite = true;
  for (int32_t i = 0; i < model_.num_nodes; ++i) {
    finite &= state_.x[i].allFinite() && state_.v[i].allFinite();
    const double v2 = state_.v[i].squaredNorm();
    max_speed2 = std::max(max_speed2, v2);
    twice_kinetic += model_.mass[i] * v2;
  }
  kinetic_energy_ = 0.5 * twice_kinetic;
  for (double a : state_.a) finite &= std::isfinite(a);
  if (!finite || max_speed2 > params_.max_speed * params_.max_speed) {
    // A second restore from the same good state means the state itself leads to the blow-up
    // (restoring it looped, every other tick, on a crushed 8k-tet bean): start again from the
    // rest shape where the object was.
    if (restored_since_good_) {
      ResetShapeAtGood();
      ++events_.shape_resets;
    } else {
      RestoreGood();
      restored_since_good_ = true;
    }
    r.restored = true;
    ++events_.restores;
    return r;
  }
  if (++steps_since_good_ >= kSnapshotInterval) SaveGood();

  bool pushed = false;
  for (const auto& f : state_.f_ext) pushed |= !f.isZero(0.0);
  if (params_.sleep_time > 0.0 && !pushed &&
      max_speed2 < params_.sleep_speed * params_.sleep_speed) {
    rest_time_ += dt;
    if (rest_time_ >= params_.sleep_time) {
      sleeping_ = true;
      kinetic_energy_ = 0.0;
      for (auto& v : state_.v) v.setZero();
      ForgetHistory();
    }
  } else {
    rest_time_ = 0.0;
  }
  return r;
}

Diagnostics SimObject::ComputeDiagnostics() const {
  Diagnostics d;
  const Model& m = model_;
  const State& s = state_;
  d.time = s.time;
  d.rest_volume = m.rest_volume;
  d.volume = internal::EnclosedVolume(m, s.x);
  d.lowest_point = m.num_nodes > 0 ? s.x[0].y() : 0.0;
  double max_speed2 = 0.0, max_disp2 = 0.0;
  const double g = params_.gravity;
  for (int32_t i = 0; i < m.num_nodes; ++i) {
    d.finite &= s.x[i].allFinite() && s.v[i].allFinite();
    d.kinetic_energy += 0.5 * m.mass[i] * s.v[i].squaredNorm();
    d.gravity_energy += m.mass[i] * g * s.x[i].y();
    d.lowest_point = std::min(d.lowest_point, s.x[i].y());
    max_disp2 = std::max(max_disp2, (s.x[i] - m.rest_positions[i] - placement_).squaredNorm());
    max_speed2 = std::max(max_speed2, s.v[i].squaredNorm());
    d.floor_force += s.floor_reaction[i];
    d.external_force += s.f_ext[i];
  }
  for (size_t k = 0; k < m.edges.size(); ++k) {
    const double l = (s.x[m.edges[k][1]] - s.x[m.edges[k][0]]).norm();
    const double stretch = s.a[k] * l - params_.voigt_ratio * m.edge_rest_length[k];
    d.elastic_energy += 0.5 * params_.k_v * stretch * stretch;
  }
  if (!m.faces.empty()) {
    const double dv = d.volume - m.rest_volume;
    d.elastic_energy += 0.5 * params_.volume_k * dv * dv;
  }
  d.potential_energy = d.gravity_energy + d.elastic_energy;
  d.max_displacement = std::sqrt(max_disp2);
  d.max_speed = std::sqrt(max_speed2);
  return d;
}

}  // namespace rheo::sim
