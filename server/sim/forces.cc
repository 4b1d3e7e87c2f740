#include "sim/forces.h"

#include <algorithm>
#include <cmath>

#include "sim/element.h"

namespace rheo::sim::internal {

ActiveTerms DecideTerms(const Model& model, const Parameters& p) {
  ActiveTerms t;
  t.edges = !model.edges.empty();
  t.nonlinear_damper = p.damper_b > 0.0 && p.f_max > p.f_min;
  t.global_volume = !model.faces.empty() && (p.volume_k > 0.0 || p.volume_c > 0.0);
  t.area = !model.faces.empty() && p.area_k > 0.0;
  t.tet_volume = !model.tets.empty() && p.tet_k > 0.0;
  t.gravity = p.gravity > 0.0;
  t.floor = p.floor_enabled > 0.5;
  return t;
}

double EnclosedVolume(const Model& model, std::span<const Vec3> x) {
  double v = 0.0;
  for (const auto& f : model.faces) v += x[f[0]].dot(x[f[1]].cross(x[f[2]]));
  return v / 6.0;
}

namespace {

void EdgeForces(const Model& m, const Parameters& p, bool nonlinear, State& s, double h,
                bool advance_a, bool linearise) {
  const bool diag_damping = !linearise && p.implicit_damping > 0.5;
  if (diag_damping) std::fill(s.damp_diag.begin(), s.damp_diag.end(), 0.0);
  const double k_v = p.k_v;
  const double c_v = p.c_v;
  const double ratio = p.voigt_ratio;
  const double c_max = DamperViscosity(p, p.f_min);
  const double c_min = DamperViscosity(p, p.f_max);
  const size_t ne = m.edges.size();
  Vec3* f = s.f.data();
  const Vec3* x = s.x.data();
  const Vec3* v = s.v.data();
  for (size_t k = 0; k < ne; ++k) {
    const int32_t i = m.edges[k][0];
    const int32_t j = m.edges[k][1];
    const Vec3 d = x[j] - x[i];
    const double l = d.norm();
    const double inv_l = l > 0.0 ? 1.0 / l : 0.0;
    const Vec3 e = d * inv_l;
    const double l_dot = e.dot(v[j] - v[i]);
    // Eq. 3 with the force of the previous substep; exp() only inside (f_min, f_max).
    double c_d = c_max;
    if (nonlinear) {
      const double f_abs = std::abs(s.tension[k]);
      c_d = f_abs <= p.f_min   ? c_max
            : f_abs >= p.f_max ? c_min
                               : p.damper_a * std::exp(-p.damper_b * f_abs);
    }
    const double rest_voigt = ratio * m.edge_rest_length[k];
    const double a = s.a[k];
    const double tension = ThreeElementTension(k_v, c_v, c_d, a, l, rest_voigt, l_dot);
    f[i] += tension * e;
    f[j] -= tension * e;
    s.tension[k] = tension;
    if (diag_damping) {
      const double c_eff = c_d / (c_v + c_d) * c_v;
      s.damp_diag[i] += c_eff;
      s.damp_diag[j] += c_eff;
    }
    if (linearise) {
      const double share = c_d / (c_v + c_d);
      s.edge_dir[k] = e;
      s.edge_axial_k[k] = h * h * share * k_v * std::max(a, 0.0);
      s.edge_axial_c[k] = h * share * c_v;
      s.edge_lateral[k] = h * h * std::max(tension, 0.0) * inv_l;
    }
    if (advance_a && l > 0.0) {
      s.a[k] = AdvanceVoigtRatio(k_v, c_v, c_d, a, l, rest_voigt, l_dot, h);
    }
  }
}

void GlobalVolumeForces(const Model& m, const Parameters& p, State& s, double h, bool linearise) {
  const int32_t n = m.num_nodes;
  std::fill(s.vol_grad.begin(), s.vol_grad.end(), Vec3::Zero());
  double vol = 0.0;
  for (const auto& fc : m.faces) {
    const Vec3& a = s.x[fc[0]];
    const Vec3& b = s.x[fc[1]];
    const Vec3& c = s.x[fc[2]];
    vol += a.dot(b.cross(c));
    // Eq. 4: each vertex takes a third of S_k n_k, i.e. (b - a) x (c - a) / 6.
    const Vec3 g = (b - a).cross(c - a) / 6.0;
    s.vol_grad[fc[0]] += g;
    s.vol_grad[fc[1]] += g;
    s.vol_grad[fc[2]] += g;
  }
  vol /= 6.0;
  double vol_dot = 0.0;
  for (int32_t i = 0; i < n; ++i) vol_dot += s.vol_grad[i].dot(s.v[i]);
  // Eq. 4 with C taken as a dissipating viscosity (the paper prints +C dV/dt).
  const double pressure = -p.volume_k * (vol - m.rest_volume) - p.volume_c * vol_dot;
  for (int32_t i = 0; i < n; ++i) s.f[i] += pressure * s.vol_grad[i];
  if (linearise) {
    s.global_k = h * h * p.volume_k;
    s.global_c = h * p.volume_c;
  }
}

// Eq. 5. u_i is the unit in-plane direction, perpendicular to the edge facing i, in which moving i
// grows the area; the force is restoring, F_i = -k (S - S0)/S0 (u_i - (u_j + u_k)/2), and sums to
// zero over the face.
void AreaForces(const Model& m, const Parameters& p, State& s, double h, bool linearise) {
  const double kk = p.area_k;
  const size_t nf = m.faces.size();
  for (size_t k = 0; k < nf; ++k) {
    const auto& fc = m.faces[k];
    const Vec3& a = s.x[fc[0]];
    const Vec3& b = s.x[fc[1]];
    const Vec3& c = s.x[fc[2]];
    const Vec3 nrm = (b - a).cross(c - a);
    const double area2 = nrm.norm();
    const double s0 = m.face_rest_area[k];
    if (!(area2 > 1e-300) || !(s0 > 0.0)) continue;
    const Vec3 nh = nrm / area2;
    const Vec3 ea = c - b, eb = a - c, ec = b - a;
    const double la = ea.norm(), lb = eb.norm(), lc = ec.norm();
    const Vec3 ua = nh.cross(ea) / la;
    const Vec3 ub = nh.cross(eb) / lb;
    const Vec3 uc = nh.cross(ec) / lc;
    const Vec3 wa = ua - 0.5 * (ub + uc);
    const Vec3 wb = ub - 0.5 * (ua + uc);
    const Vec3 wc = uc - 0.5 * (ua + ub);
    const double mag = -kk * (0.5 * area2 - s0) / s0;
    s.f[fc[0]] += mag * wa;
    s.f[fc[1]] += mag * wb;
    s.f[fc[2]] += mag * wc;
    if (linearise) {
      // Gauss-Newton: dF_i/dx_j ~ -(k/S0) w_i grad_j^T, symmetrised as sigma w w^T, |grad| ~ l/2.
      const double sigma = kk / s0 * (la + lb + lc) / 6.0 / 1.5;
      s.shape_coef[k] = h * h * sigma;
      s.shape_dir[3 * k] = wa;
      s.shape_dir[3 * k + 1] = wb;
      s.shape_dir[3 * k + 2] = wc;
    }
  }
}

// Eq. 6, restoring: F_i = -k (V - V0)/|V0| (u_i - (u_j + u_k + u_l)/3), u_i the unit gradient of
// the signed volume at node i (normal to the opposite face, towards i). An inverted tet (V < 0)
// gets a large push back through its face.
template <bool kLinearise>
void TetForcesT(const Model& m, const Parameters& p, State& s, double h) {
  // Divisions are hoisted out of the loop: without -ffast-math every "/ 6.0" or "/ 3.0" on a
  // vector is three real divisions, which made this loop divide-bound.
  const double kk = p.tet_k;
  const size_t nt = m.tets.size();
  const size_t face_off = m.faces.size();
  constexpr double kSixth = 1.0 / 6.0, kThird = 1.0 / 3.0;
  Vec3* f = s.f.data();
  const Vec3* x = s.x.data();
  for (size_t k = 0; k < nt; ++k) {
    const double v0 = m.tet_rest_volume[k];
    if (!(v0 > 0.0)) continue;
    const auto& t = m.tets[k];
    const Vec3& x0 = x[t[0]];
    const Vec3 d1 = x[t[1]] - x0;
    const Vec3 d2 = x[t[2]] - x0;
    const Vec3 d3 = x[t[3]] - x0;
    // 6 x the gradients of the signed volume at each node.
    Vec3 g[4];
    g[1] = d2.cross(d3);
    g[2] = d3.cross(d1);
    g[3] = d1.cross(d2);
    g[0] = -(g[1] + g[2] + g[3]);
    const double vol = d1.dot(g[1]) * kSixth;
    Vec3 u[4];
    double gsum = 0.0;
    for (int q = 0; q < 4; ++q) {
      const double gn = g[q].norm();
      gsum += gn;
      u[q] = gn > 1e-300 ? Vec3(g[q] * (1.0 / gn)) : Vec3::Zero();
    }
    const Vec3 usum = u[0] + u[1] + u[2] + u[3];
    const double mag = -kk * (vol - v0) / v0;
    // w_q = u_q - (usum - u_q) / 3 = (4 u_q - usum) / 3.
    const double mag3 = mag * kThird;
    for (int q = 0; q < 4; ++q) {
      const Vec3 w3 = 4.0 * u[q] - usum;
      f[t[q]] += mag3 * w3;
      if constexpr (kLinearise) s.shape_dir[3 * face_off + 4 * k + q] = w3 * kThird;
    }
    if constexpr (kLinearise)
      s.shape_coef[face_off + k] = h * h * kk / v0 * (gsum * kSixth / 4.0) / (4.0 / 3.0);
  }
}

void TetForces(const Model& m, const Parameters& p, State& s, double h, bool linearise) {
  if (linearise)
    TetForcesT<true>(m, p, s, h);
  else
    TetForcesT<false>(m, p, s, h);
}

}  // namespace

void ComputeForces(const Model& m, const Parameters& p, const ActiveTerms& terms, State& s,
                   double h, bool advance_a, bool linearise) {
  const int32_t n = m.num_nodes;
  const double g = terms.gravity ? p.gravity : 0.0;
  for (int32_t i = 0; i < n; ++i) {
    s.f[i] = s.f_ext[i];
    s.f[i].y() -= m.mass[i] * g;
  }
  if (terms.edges) EdgeForces(m, p, terms.nonlinear_damper, s, h, advance_a, linearise);
  if (terms.global_volume) GlobalVolumeForces(m, p, s, h, linearise);
  if (terms.area) AreaForces(m, p, s, h, linearise);
  if (terms.tet_volume) TetForces(m, p, s, h, linearise);
}

void ApplyJacobian(const Model& m, const ActiveTerms& terms, const State& s,
                   std::span<const Vec3> pv, std::span<Vec3> out, bool stiffness_only) {
  const int32_t n = m.num_nodes;
  for (int32_t i = 0; i < n; ++i) out[i].setZero();
  if (terms.edges) {
    const size_t ne = m.edges.size();
    for (size_t k = 0; k < ne; ++k) {
      const int32_t i = m.edges[k][0];
      const int32_t j = m.edges[k][1];
      const Vec3 d = pv[i] - pv[j];
      const Vec3& e = s.edge_dir[k];
      const double axial =
          stiffness_only ? s.edge_axial_k[k] : s.edge_axial_k[k] + s.edge_axial_c[k];
      const double ed = e.dot(d);
      const Vec3 y = (axial - s.edge_lateral[k]) * ed * e + s.edge_lateral[k] * d;
      out[i] += y;
      out[j] -= y;
    }
  }
  if (terms.global_volume) {
    const double beta = stiffness_only ? s.global_k : s.global_k + s.global_c;
    double dot = 0.0;
    for (int32_t i = 0; i < n; ++i) dot += s.vol_grad[i].dot(pv[i]);
    for (int32_t i = 0; i < n; ++i) out[i] += beta * dot * s.vol_grad[i];
  }
  if (terms.area) {
    const size_t nf = m.faces.size();
    for (size_t k = 0; k < nf; ++k) {
      const auto& fc = m.faces[k];
      const Vec3* w = &s.shape_dir[3 * k];
      const double dot = w[0].dot(pv[fc[0]]) + w[1].dot(pv[fc[1]]) + w[2].dot(pv[fc[2]]);
      const double c = s.shape_coef[k] * dot;
      out[fc[0]] += c * w[0];
      out[fc[1]] += c * w[1];
      out[fc[2]] += c * w[2];
    }
  }
  if (terms.tet_volume) {
    const size_t nt = m.tets.size();
    const size_t face_off = m.faces.size();
    for (size_t k = 0; k < nt; ++k) {
      if (!(m.tet_rest_volume[k] > 0.0)) continue;
      const auto& t = m.tets[k];
      const Vec3* w = &s.shape_dir[3 * face_off + 4 * k];
      const double dot =
          w[0].dot(pv[t[0]]) + w[1].dot(pv[t[1]]) + w[2].dot(pv[t[2]]) + w[3].dot(pv[t[3]]);
      const double c = s.shape_coef[face_off + k] * dot;
      for (int q = 0; q < 4; ++q) out[t[q]] += c * w[q];
    }
  }
}

}  // namespace rheo::sim::internal
