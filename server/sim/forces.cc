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

// The element kernels run in blocks: a vectorisable pass computes each element of the block from
// gathered node data into block-local arrays (no stores to shared nodes, so `omp simd` is safe),
// then a short scalar pass adds the results to the nodes. Built twice where the compiler can
// (x86-64 baseline and x86-64-v3 with AVX2/FMA), the faster one chosen when the library loads.
constexpr int kBlock = 64;

// phi(x) = (1 - exp(-x)) / x as a polynomial, accurate to 1e-16 for |x| < kPhiPolyLimit; lanes
// outside take the exact expression in the scalar pass.
constexpr double kPhiPolyLimit = 0.05;
inline double PhiPoly(double x) {
  return 1.0 -
         x * (1.0 / 2 -
              x * (1.0 / 6 -
                   x * (1.0 / 24 -
                        x * (1.0 / 120 - x * (1.0 / 720 - x * (1.0 / 5040 - x * (1.0 / 40320)))))));
}

RHEO_SIM_KERNEL void EdgeForces(const Model& m, const Parameters& p, bool nonlinear, State& s,
                                double h, double a_step, bool linearise) {
  // The edge blocks of the implicit system are always written (see below); `linearise` only
  // says whether the diagonal damping of the explicit integrator is wanted instead.
  const bool diag_damping = !linearise && p.implicit_damping > 0.5;
  if (diag_damping) std::fill(s.damp_diag.begin(), s.damp_diag.end(), 0.0);
  const double k_v = p.k_v;
  const double c_v = p.c_v;
  const double ratio = p.voigt_ratio;
  const double c_max = DamperViscosity(p, p.f_min);
  const double c_min = DamperViscosity(p, p.f_max);
  const double h2 = h * h;
  const size_t ne = m.edges.size();
  const int32_t* E = m.edges.data()->data();
  const double* RL = m.edge_rest_length.data();
  const double* X = s.x.data()->data();
  const double* V = s.v.data()->data();
  double* F = s.f.data()->data();
  double* A = s.a.data();
  double* T = s.tension.data();
  double* EX = s.edge_ex.data();
  double* EY = s.edge_ey.data();
  double* EZ = s.edge_ez.data();
  double* AK = s.edge_axial_k.data();
  double* AC = s.edge_axial_c.data();
  double* AL = s.edge_lateral.data();
  alignas(64) double dxv[3][kBlock], dvv[3][kBlock], cd[kBlock], fx[kBlock], fy[kBlock], fz[kBlock],
      c_eff[kBlock];
  alignas(64) int32_t exact[kBlock];
  for (size_t k0 = 0; k0 < ne; k0 += kBlock) {
    const int nb = static_cast<int>(std::min<size_t>(kBlock, ne - k0));
    // Gather (scalar loads: hardware gathers are slower than this on common CPUs).
    // Node i's values are loaded once per run of edges that share it (edges are sorted by i).
    int32_t gi = -1;
    double xi[3] = {}, vi[3] = {};
    for (int l = 0; l < nb; ++l) {
      const size_t k = k0 + l;
      const int32_t i = E[2 * k], j = E[2 * k + 1];
      if (i != gi) {
        gi = i;
        for (int c = 0; c < 3; ++c) {
          xi[c] = X[3 * i + c];
          vi[c] = V[3 * i + c];
        }
      }
      for (int c = 0; c < 3; ++c) {
        dxv[c][l] = X[3 * j + c] - xi[c];
        dvv[c][l] = V[3 * j + c] - vi[c];
      }
      // Eq. 3 with the force of the previous substep; exp() only inside (f_min, f_max).
      double c_d = c_max;
      if (nonlinear) {
        const double f_abs = std::abs(T[k]);
        c_d = f_abs <= p.f_min   ? c_max
              : f_abs >= p.f_max ? c_min
                                 : p.damper_a * std::exp(-p.damper_b * f_abs);
      }
      cd[l] = c_d;
    }
#pragma omp simd
    for (int l = 0; l < nb; ++l) {
      const size_t k = k0 + l;
      const double dx = dxv[0][l], dy = dxv[1][l], dz = dxv[2][l];
      const double L = std::sqrt(dx * dx + dy * dy + dz * dz);
      const double inv_l = L > 0.0 ? 1.0 / L : 0.0;
      const double ux = dx * inv_l, uy = dy * inv_l, uz = dz * inv_l;
      const double l_dot = ux * dvv[0][l] + uy * dvv[1][l] + uz * dvv[2][l];
      const double c_d = cd[l];
      const double inv_csum = 1.0 / (c_v + c_d);
      const double share = c_d * inv_csum;
      const double rest_voigt = ratio * RL[k];
      const double a = A[k];
      // Eq. 2 (element.h ThreeElementTension).
      const double tension = share * (k_v * (a * L - rest_voigt) + c_v * l_dot);
      fx[l] = tension * ux;
      fy[l] = tension * uy;
      fz[l] = tension * uz;
      T[k] = tension;
      c_eff[l] = share * c_v;
      // The implicit system's edge blocks, written whether or not they are used: a store under a
      // condition would keep this loop from vectorising.
      EX[k] = ux;
      EY[k] = uy;
      EZ[k] = uz;
      AK[k] = h2 * share * k_v * std::max(a, 0.0);
      AC[k] = h * share * c_v;
      AL[k] = h2 * std::max(tension, 0.0) * inv_l;
      // element.h AdvanceVoigtRatio, phi by its polynomial; other lanes in the pass below.
      const double inv_den = inv_l * inv_csum;
      const double alpha = (k_v * rest_voigt + c_d * l_dot) * inv_den;
      const double beta = (k_v * L + (c_v + c_d) * l_dot) * inv_den;
      const double x = beta * a_step;
      // Bitwise & (no short circuit): branches would keep the loop from vectorising.
      const bool poly = (L > 0.0) & (std::abs(x) < kPhiPolyLimit);
      exact[l] = (a_step > 0.0) & (L > 0.0) & !poly;
      A[k] = ((a_step > 0.0) & poly) ? a + (alpha - beta * a) * a_step * PhiPoly(x) : a;
    }
    // Node i's sum stays in registers over its run of edges (sorted by i; see EdgeJacobian).
    // The implicit system's Jacobi preconditioner gets trace/3 of each edge block (linearise),
    // the explicit integrator's implicit damping the effective viscosity (diag_damping).
    double* Dg = linearise ? s.diag.data() : diag_damping ? s.damp_diag.data() : nullptr;
    int32_t cur = E[2 * k0];
    double sx = 0.0, sy = 0.0, sz = 0.0, sd = 0.0;
    // Adds node cur's sums to it.
    auto flush = [&] {
      F[3 * cur] += sx;
      F[3 * cur + 1] += sy;
      F[3 * cur + 2] += sz;
      if (Dg != nullptr) Dg[cur] += sd;
    };
    for (int l = 0; l < nb; ++l) {
      const size_t k = k0 + l;
      const int32_t i = E[2 * k], j = E[2 * k + 1];
      if (i != cur) {
        flush();
        cur = i;
        sx = sy = sz = sd = 0.0;
      }
      sx += fx[l];
      sy += fy[l];
      sz += fz[l];
      F[3 * j] -= fx[l];
      F[3 * j + 1] -= fy[l];
      F[3 * j + 2] -= fz[l];
      if (Dg != nullptr) {
        const double t = linearise ? (AK[k] + AC[k] + 2.0 * AL[k]) * (1.0 / 3.0) : c_eff[l];
        sd += t;
        Dg[j] += t;
      }
      if (exact[l]) {
        const double L =
            std::sqrt(dxv[0][l] * dxv[0][l] + dxv[1][l] * dxv[1][l] + dxv[2][l] * dxv[2][l]);
        const double l_dot =
            (dxv[0][l] * dvv[0][l] + dxv[1][l] * dvv[1][l] + dxv[2][l] * dvv[2][l]) / L;
        A[k] = AdvanceVoigtRatio(k_v, c_v, cd[l], A[k], L, ratio * RL[k], l_dot, a_step);
      }
    }
    flush();
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
  vol = vol / 6.0 + s.volume_offset;
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
RHEO_SIM_KERNEL void AreaForces(const Model& m, const Parameters& p, State& s, double h,
                                bool linearise) {
  const double kk = p.area_k;
  const size_t nf = m.faces.size();
  const int32_t* Fc = m.faces.data()->data();
  const double* S0 = m.face_rest_area.data();
  const double* X = s.x.data()->data();
  double* F = s.f.data()->data();
  alignas(64) double ev[9][kBlock], w[9][kBlock], mag[kBlock], perim[kBlock];
  for (size_t k0 = 0; k0 < nf; k0 += kBlock) {
    const int nb = static_cast<int>(std::min<size_t>(kBlock, nf - k0));
    for (int l = 0; l < nb; ++l) {
      const size_t k = k0 + l;
      const int32_t ia = Fc[3 * k], ib = Fc[3 * k + 1], ic = Fc[3 * k + 2];
      for (int c = 0; c < 3; ++c) {
        ev[c][l] = X[3 * ic + c] - X[3 * ib + c];
        ev[3 + c][l] = X[3 * ia + c] - X[3 * ic + c];
        ev[6 + c][l] = X[3 * ib + c] - X[3 * ia + c];
      }
    }
#pragma omp simd
    for (int l = 0; l < nb; ++l) {
      const size_t k = k0 + l;
      double e[3][3];  // the edge facing each vertex: c - b, a - c, b - a
      for (int q = 0; q < 3; ++q) {
        for (int c = 0; c < 3; ++c) e[q][c] = ev[3 * q + c][l];
      }
      // n = (b - a) x (c - a) = e2 x (-e1).
      const double nx = -(e[2][1] * e[1][2] - e[2][2] * e[1][1]);
      const double ny = -(e[2][2] * e[1][0] - e[2][0] * e[1][2]);
      const double nz = -(e[2][0] * e[1][1] - e[2][1] * e[1][0]);
      const double area2 = std::sqrt(nx * nx + ny * ny + nz * nz);
      const double s0 = S0[k];
      const bool ok = area2 > 1e-300 && s0 > 0.0;
      // As in the tets' kernel, the unit directions are divided by no less than half their rest
      // scale (|n| >= S0, an edge >= sqrt(S0)/2), so that a collapsing face or edge keeps a
      // bounded stiffness.
      const double inv_n = ok ? 1.0 / std::max(area2, s0) : 0.0;
      const double l_floor = 0.5 * std::sqrt(s0);
      const double hx = nx * inv_n, hy = ny * inv_n, hz = nz * inv_n;
      double u[3][3];
      double lsum = 0.0;
      for (int q = 0; q < 3; ++q) {
        const double lq = std::sqrt(e[q][0] * e[q][0] + e[q][1] * e[q][1] + e[q][2] * e[q][2]);
        lsum += lq;
        const double inv_lq = 1.0 / std::max(lq, l_floor);
        u[q][0] = (hy * e[q][2] - hz * e[q][1]) * inv_lq;
        u[q][1] = (hz * e[q][0] - hx * e[q][2]) * inv_lq;
        u[q][2] = (hx * e[q][1] - hy * e[q][0]) * inv_lq;
      }
      for (int c = 0; c < 3; ++c) {
        w[c][l] = u[0][c] - 0.5 * (u[1][c] + u[2][c]);
        w[3 + c][l] = u[1][c] - 0.5 * (u[0][c] + u[2][c]);
        w[6 + c][l] = u[2][c] - 0.5 * (u[0][c] + u[1][c]);
      }
      mag[l] = ok ? -kk * (0.5 * area2 - s0) / s0 : 0.0;
      perim[l] = ok ? lsum : -1.0;
    }
    for (int l = 0; l < nb; ++l) {
      if (!(perim[l] >= 0.0)) continue;
      const size_t k = k0 + l;
      for (int q = 0; q < 3; ++q) {
        const int32_t node = Fc[3 * k + q];
        for (int c = 0; c < 3; ++c) F[3 * node + c] += mag[l] * w[3 * q + c][l];
      }
      if (linearise) {
        // Gauss-Newton: dF_i/dx_j ~ -(k/S0) w_i grad_j^T, symmetrised as sigma w w^T, |grad| ~ l/2.
        const double sigma = kk / S0[k] * perim[l] / 6.0 / 1.5;
        s.shape_coef[k] = h * h * sigma;
        for (int q = 0; q < 3; ++q)
          s.shape_dir[3 * k + q] = Vec3(w[3 * q][l], w[3 * q + 1][l], w[3 * q + 2][l]);
      }
    }
  }
}

// Eq. 6, restoring: F_i = -k (V - V0)/|V0| (u_i - (u_j + u_k + u_l)/3), u_i the unit gradient of
// the signed volume at node i (normal to the opposite face, towards i). An inverted tet (V < 0)
// gets a large push back through its face. Tets with a non-positive rest volume are skipped.
RHEO_SIM_KERNEL void TetForces(const Model& m, const Parameters& p, State& s, double h,
                               bool linearise) {
  const double kk = p.tet_k;
  const size_t nt = m.tets.size();
  constexpr double kSixth = 1.0 / 6.0, kThird = 1.0 / 3.0;
  const int32_t* Tt = m.tets.data()->data();
  const double* V0 = m.tet_rest_volume.data();
  const float* GF = m.tet_grad_floor.data();
  const double* X = s.x.data()->data();
  double* F = s.f.data()->data();
  float* TW = s.tet_w.data();
  double* TC = s.tet_coef.data();
  const bool split = s.tet_split && linearise;
  const uint8_t* TI = s.tet_implicit.data();
  double* FI = s.f_tet_implicit.data()->data();
  if (split) std::fill(s.f_tet_implicit.begin(), s.f_tet_implicit.end(), Vec3::Zero());
  // The element arithmetic is in single precision (twice the lanes): each tet's edge vectors are
  // formed in double first, so only their relative rounding (1e-7) enters the force, far below
  // the model's own error; forces are added to the nodes in double.
  using R = float;
  alignas(64) R dv[9][kBlock], w[12][kBlock], mag3[kBlock], gsum[kBlock];
  for (size_t k0 = 0; k0 < nt; k0 += kBlock) {
    const int nb = static_cast<int>(std::min<size_t>(kBlock, nt - k0));
    for (int l = 0; l < nb; ++l) {
      const size_t k = k0 + l;
      const int32_t i0 = Tt[4 * k], i1 = Tt[4 * k + 1], i2 = Tt[4 * k + 2], i3 = Tt[4 * k + 3];
      for (int c = 0; c < 3; ++c) {
        const double x0 = X[3 * i0 + c];
        dv[c][l] = static_cast<R>(X[3 * i1 + c] - x0);
        dv[3 + c][l] = static_cast<R>(X[3 * i2 + c] - x0);
        dv[6 + c][l] = static_cast<R>(X[3 * i3 + c] - x0);
      }
    }
#pragma omp simd
    for (int l = 0; l < nb; ++l) {
      const size_t k = k0 + l;
      R d1[3], d2[3], d3[3];
      for (int c = 0; c < 3; ++c) {
        d1[c] = dv[c][l];
        d2[c] = dv[3 + c][l];
        d3[c] = dv[6 + c][l];
      }
      // 6 x the gradients of the signed volume at each node.
      R g[4][3];
      g[1][0] = d2[1] * d3[2] - d2[2] * d3[1];
      g[1][1] = d2[2] * d3[0] - d2[0] * d3[2];
      g[1][2] = d2[0] * d3[1] - d2[1] * d3[0];
      g[2][0] = d3[1] * d1[2] - d3[2] * d1[1];
      g[2][1] = d3[2] * d1[0] - d3[0] * d1[2];
      g[2][2] = d3[0] * d1[1] - d3[1] * d1[0];
      g[3][0] = d1[1] * d2[2] - d1[2] * d2[1];
      g[3][1] = d1[2] * d2[0] - d1[0] * d2[2];
      g[3][2] = d1[0] * d2[1] - d1[1] * d2[0];
      for (int c = 0; c < 3; ++c) g[0][c] = -(g[1][c] + g[2][c] + g[3][c]);
      const R vol = (d1[0] * g[1][0] + d1[1] * g[1][1] + d1[2] * g[1][2]) * R(kSixth);
      R u[4][3];
      R gs = 0.0f;
      // A value, not std::max(GF[k], ...): its reference made GCC emit a masked gather, and the
      // whole pass ran scalar (112 against 58 us at 5k tets; tests/sim/kernels_vectorized.py).
      const R gf = GF[k];
      const R g_floor = gf > R(1e-30) ? gf : R(1e-30);
      for (int q = 0; q < 4; ++q) {
        const R gn = std::sqrt(g[q][0] * g[q][0] + g[q][1] * g[q][1] + g[q][2] * g[q][2]);
        gs += gn;
        // The unit gradient, but no longer than g / g_floor where a face has collapsed.
        const R inv = R(1) / std::max(gn, g_floor);
        for (int c = 0; c < 3; ++c) u[q][c] = g[q][c] * inv;
      }
      // w_q = u_q - (usum - u_q) / 3 = (4 u_q - usum) / 3; w[] holds 3 w_q.
      for (int c = 0; c < 3; ++c) {
        const R usum = u[0][c] + u[1][c] + u[2][c] + u[3][c];
        for (int q = 0; q < 4; ++q) w[3 * q + c][l] = R(4) * u[q][c] - usum;
      }
      const R v0 = static_cast<R>(V0[k]);
      mag3[l] = v0 > R(0) ? R(-kk * kThird) * (vol - v0) / v0 : R(0);
      gsum[l] = gs;
    }
    // Adds the forces of the block's tets that `take` accepts to `dst`.
    auto scatter = [&](double* dst, auto take) {
      for (int l = 0; l < nb; ++l) {
        if (!take(k0 + l)) continue;
        for (int q = 0; q < 4; ++q) {
          const int32_t node = Tt[4 * (k0 + l) + q];
          for (int c = 0; c < 3; ++c)
            dst[3 * node + c] += double(mag3[l]) * double(w[3 * q + c][l]);
        }
      }
    };
    scatter(F, [&](size_t k) { return V0[k] > 0.0; });
    // The implicit tets' forces also go apart, so that the caller can leave them out of the
    // explicit (extrapolated) share.
    if (split) scatter(FI, [&](size_t k) { return TI[k] != 0; });
    if (linearise) {
      // Gauss-Newton blocks sigma w w^T (w = the force direction of each corner), kept per
      // coordinate for the vectorised product in ApplyJacobian; 0 for skipped tets.
      for (int l = 0; l < nb; ++l) {
        for (int j = 0; j < 12; ++j) TW[12 * (k0 + l) + j] = w[j][l] * R(kThird);
      }
      for (int l = 0; l < nb; ++l) {
        const double v0 = V0[k0 + l];
        const bool in_system = v0 > 0.0 && (!split || TI[k0 + l]);
        TC[k0 + l] =
            in_system ? h * h * kk / v0 * (double(gsum[l]) * kSixth / 4.0) / (4.0 / 3.0) : 0.0;
      }
    }
  }
}

}  // namespace

void ComputeForces(const Model& m, const Parameters& p, const ActiveTerms& terms, State& s,
                   double h, double a_step, const ActiveTerms& lin, Vec3* f_explicit) {
  const int32_t n = m.num_nodes;
  const double g = terms.gravity ? p.gravity : 0.0;
  for (int32_t i = 0; i < n; ++i) {
    s.f[i] = s.f_ext[i];
    s.f[i].y() -= m.mass[i] * g;
  }
  if (s.ext_springs > 0)
    for (int32_t i = 0; i < n; ++i)
      if (s.k_ext[i] > 0.0) s.f[i] += s.k_ext[i] * (s.x_ext[i] - s.x[i]);
  if (terms.edges) EdgeForces(m, p, terms.nonlinear_damper, s, h, a_step, lin.edges);
  if (terms.global_volume) GlobalVolumeForces(m, p, s, h, lin.global_volume);
  if (f_explicit != nullptr) {
    // Keep the shape springs' part apart: this copy, less the total after them.
    std::copy(s.f.begin(), s.f.end(), f_explicit);
  }
  if (terms.area) AreaForces(m, p, s, h, lin.area);
  if (terms.tet_volume) TetForces(m, p, s, h, lin.tet_volume);
  if (f_explicit != nullptr) {
    const bool split = terms.tet_volume && lin.tet_volume && s.tet_split;
    for (int32_t i = 0; i < n; ++i) {
      f_explicit[i] = s.f[i] - f_explicit[i];
      if (split) f_explicit[i] -= s.f_tet_implicit[i];
    }
  }
}

}  // namespace rheo::sim::internal
