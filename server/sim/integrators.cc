#include "sim/integrators.h"

#include <algorithm>
#include <cmath>

namespace rheo::sim::internal {
namespace {

// Relative CG tolerance near rest (see ImplicitEulerSubstep).
constexpr double kRestCgTolerance = 1e-5;

// Parameters::cg_iteration_budget: a substep's CG iterations are capped at the budget times their
// running mean (an exponential one, this weight on the newest, starting from
// kMinBudgetIterations), and at no fewer than kMinBudgetIterations. Seeded from the object's first
// solve instead (cold, 24 iterations at 4.6k tets, 51 at 21.6k), the budget did not bind in the
// ticks after it, which were the slowest. The solve left short is still a descent on the system's
// energy from the warm start; the next substep starts from the current state's residual.
constexpr double kBudgetMeanWeight = 0.05;
constexpr int kMinBudgetIterations = 8;

// Depenetration speed cap: a node found below the floor is lifted out at most this fast [m/s].
constexpr double kMaxDepenetrationSpeed = 1.0;
// A node the floor pushed in the last substep stays held while it would end this one within this
// height above the floor [m]: resting contact is then part of the solve every substep. Released
// only when it would rise higher (or, once, when holding it pulled), the nodes at rest had
// chattered between held and projected substeps, which flattened tets against the floor (12-24
// left inverted on a 22k-tet bean) and cost 10 CG iterations per substep instead of 7.
constexpr double kFloorHoldSlop = 1e-5;

// Inelastic floor contact with Coulomb friction as a velocity projection: unconditionally stable,
// independent of the material stiffness, and the impulse gives the reaction force directly.
// `impulse` (the implicit step's, else null) holds the impulse the floor already gave each node
// inside the solve (ImplicitEulerSubstep): its normal part counts towards the friction, all of it
// towards the reaction. There a node whose tangential velocity the friction stops is marked to
// stick (State::floor_stick): the next solve holds it in all three coordinates, so that static
// friction acts inside the solve, as the normal impulse does.
// The floor's velocity jump is an impulse that no smooth history describes. With h_full > 0 (the
// implicit step) a node the floor stopped has its history (x_prev, v_prev) replaced by the
// constant-velocity one through its new state, so that the next BDF2 substep neither re-applies a
// third of the jump (the M (v0 - v_1)/3 term) nor extrapolates the pre-impact position: left
// alone, these made a 4.6k-tet bean dropped 2 cm tear at its first rebound.
void FloorProjection(const Model& m, const Parameters& p, State& s, double h, double tick,
                     const Vec3* impulse = nullptr, double h_full = 0.0) {
  const double floor = p.floor_height;
  const double mu = p.friction;
  const double inv_tick = 1.0 / tick;
  const int32_t n = m.num_nodes;
  for (int32_t i = 0; i < n; ++i) {
    if (m.fixed[i]) continue;
    Vec3& v = s.v[i];
    const double y = s.x[i].y();
    const Vec3 j = impulse != nullptr ? impulse[i] : Vec3::Zero();
    const double jn = j.y();
    double dvn = 0.0;
    if (y + h * v.y() < floor) {
      double vn = (floor - y) / h;
      if (y < floor) vn = std::min(vn, std::max(v.y(), 0.0) + kMaxDepenetrationSpeed);
      dvn = std::max(vn - v.y(), 0.0);
    }
    // The solve's impulse is negative where holding the node at the floor pulled it (it would
    // have stopped short by itself): that much adhesion for one substep, and no friction.
    const double dvn_all = dvn + std::max(jn, 0.0) * m.inv_mass[i];
    if (dvn_all <= 0.0 && jn == 0.0) continue;
    const double vt = std::hypot(v.x(), v.z());
    const double dvt = std::min(vt, mu * dvn_all);
    const double scale = vt > 0.0 ? (vt - dvt) / vt : 0.0;
    const Vec3 before = v;
    v.x() *= scale;
    v.z() *= scale;
    v.y() += dvn;
    s.floor_reaction[i] += (m.mass[i] * (v - before) + j) * inv_tick;
    if (h_full > 0.0) {
      // After Advect x1 = x + h v; the constant-velocity history has x_1 = x1 - h_full v.
      s.x_prev[i] = s.x[i] + (h - h_full) * v;
      s.v_prev[i] = v;
      if (mu > 0.0 && dvt >= vt && dvn_all > 0.0) s.floor_stick[i] = 1;
    }
  }
}

void Advect(const Model& m, State& s, double h) {
  const int32_t n = m.num_nodes;
  for (int32_t i = 0; i < n; ++i) s.x[i] += h * s.v[i];
}

// CG's passes over the nodes, on the flat arrays (3 doubles per node) so that they vectorise.
// out = keep (out + mass in), the rows of fixed nodes zero; returns in . out.
RHEO_SIM_KERNEL double FinishProduct(size_t n3, const double* keep, const double* mass,
                                     const double* in, double* out) {
  double dot = 0.0;
#pragma omp simd reduction(+ : dot)
  for (size_t k = 0; k < n3; ++k) {
    const double o = keep[k] * (out[k] + mass[k] * in[k]);
    out[k] = o;
    dot += in[k] * o;
  }
  return dot;
}

// dv += alpha p, r -= alpha q, z = D^-1 r; returns r . z and r . r. The coordinates that are not
// unknowns (D^-1 = 0: fixed, or held by the floor) are left out of r . r: there r goes on as the
// residual b - A u, which for a held coordinate is minus the floor's impulse.
RHEO_SIM_KERNEL void CgUpdate(size_t n3, double alpha, const double* p, const double* q,
                              const double* inv_diag, double* dv, double* r, double* z,
                              double* rz_out, double* r2_out) {
  double rz = 0.0, r2 = 0.0;
#pragma omp simd reduction(+ : rz, r2)
  for (size_t k = 0; k < n3; ++k) {
    dv[k] += alpha * p[k];
    const double rk = r[k] - alpha * q[k];
    r[k] = rk;
    const double zk = inv_diag[k] * rk;
    z[k] = zk;
    rz += rk * zk;
    r2 += inv_diag[k] != 0.0 ? rk * rk : 0.0;
  }
  *rz_out = rz;
  *r2_out = r2;
}

// z = p = D^-1 r; returns r . z and r . r (over the unknowns, as CgUpdate).
RHEO_SIM_KERNEL void CgStart(size_t n3, const double* r, const double* inv_diag, double* z,
                             double* p, double* rz_out, double* r2_out) {
  double rz = 0.0, r2 = 0.0;
#pragma omp simd reduction(+ : rz, r2)
  for (size_t k = 0; k < n3; ++k) {
    const double zk = inv_diag[k] * r[k];
    z[k] = zk;
    p[k] = zk;
    rz += r[k] * zk;
    r2 += inv_diag[k] != 0.0 ? r[k] * r[k] : 0.0;
  }
  *rz_out = rz;
  *r2_out = r2;
}

// z = P r at node i for the block Jacobi forms of CgUpdate and CgStart below, P each node's
// inverted 3x3 block (State::pre_block, six arrays of n: xx, yy, zz, xy, xz, yz); adds r . z to
// rz and r . r over the unknowns (`mask` nonzero) to r2, as the Jacobi forms above do. Written
// out per coordinate: with loops over c (and r as an array) the callers' loops did not vectorise.
[[gnu::always_inline]] inline void BlockPrecondition(size_t n, size_t i, const double* P,
                                                     const double* mask, double r0, double r1,
                                                     double r2i, double* z, double& rz,
                                                     double& r2) {
  const double xx = P[i], yy = P[n + i], zz = P[2 * n + i], xy = P[3 * n + i], xz = P[4 * n + i],
               yz = P[5 * n + i];
  const size_t k = 3 * i;
  const double z0 = xx * r0 + xy * r1 + xz * r2i;
  const double z1 = xy * r0 + yy * r1 + yz * r2i;
  const double z2 = xz * r0 + yz * r1 + zz * r2i;
  z[k] = z0;
  z[k + 1] = z1;
  z[k + 2] = z2;
  rz += r0 * z0 + r1 * z1 + r2i * z2;
  r2 += (mask[k] != 0.0 ? r0 * r0 : 0.0) + (mask[k + 1] != 0.0 ? r1 * r1 : 0.0) +
        (mask[k + 2] != 0.0 ? r2i * r2i : 0.0);
}

RHEO_SIM_KERNEL void CgUpdateBlock(size_t n, double alpha, const double* p, const double* q,
                                   const double* P, const double* mask, double* dv, double* r,
                                   double* z, double* rz_out, double* r2_out) {
  double rz = 0.0, r2 = 0.0;
#pragma omp simd reduction(+ : rz, r2)
  for (size_t i = 0; i < n; ++i) {
    const size_t k = 3 * i;
    dv[k] += alpha * p[k];
    dv[k + 1] += alpha * p[k + 1];
    dv[k + 2] += alpha * p[k + 2];
    const double r0 = r[k] - alpha * q[k], r1 = r[k + 1] - alpha * q[k + 1],
                 r2i = r[k + 2] - alpha * q[k + 2];
    r[k] = r0;
    r[k + 1] = r1;
    r[k + 2] = r2i;
    BlockPrecondition(n, i, P, mask, r0, r1, r2i, z, rz, r2);
  }
  *rz_out = rz;
  *r2_out = r2;
}

// As CgUpdateBlock for the first iteration: p = z = P r.
RHEO_SIM_KERNEL void CgStartBlock(size_t n, const double* r, const double* P, const double* mask,
                                  double* z, double* p, double* rz_out, double* r2_out) {
  double rz = 0.0, r2 = 0.0;
#pragma omp simd reduction(+ : rz, r2)
  for (size_t i = 0; i < n; ++i) {
    const size_t k = 3 * i;
    BlockPrecondition(n, i, P, mask, r[k], r[k + 1], r[k + 2], z, rz, r2);
    p[k] = z[k];
    p[k + 1] = z[k + 1];
    p[k + 2] = z[k + 2];
  }
  *rz_out = rz;
  *r2_out = r2;
}

// Each node's 3x3 block of the system A = M + hh D + hh^2 K (+ the tool's springs), inverted into
// State::pre_block: the masses (with the tool's springs times `spring_h2`), the edges' blocks (K_e
// + D_e to both ends), the shape springs' Gauss-Newton blocks sigma w w^T at each corner, and the
// volume term's beta g g^T. `mask` (3n) is 1 on the unknowns and 0 on the coordinates the floor
// holds; those leave the block (their rows and columns of the inverse are 0), as do fixed nodes.
// With `assembled` (AssembleEdgeBlocks has run for `jac`), the edges' and springs' share comes
// from the assembled blocks, one pass over the edges: node i's block gains G_e, node j's G_e^T
// (the product's y = G_e (a_i - a_j) to i, -G_e^T (a_i - a_j) to j), symmetrised. Gathered from
// the edges, tets and faces instead, the block preconditioner cost as much as the iterations it
// saved at 21.6k tets.
void BlockJacobi(const Model& m, const ActiveTerms& jac, State& s, double spring_h2, double beta,
                 const double* mask, bool assembled) {
  const size_t n = static_cast<size_t>(m.num_nodes);
  double* B = s.pre_block.data();
  double *xx = B, *yy = B + n, *zz = B + 2 * n, *xy = B + 3 * n, *xz = B + 4 * n, *yz = B + 5 * n;
  for (size_t i = 0; i < n; ++i) {
    xx[i] = yy[i] = zz[i] = m.mass[i] + (spring_h2 > 0.0 ? spring_h2 * s.k_ext[i] : 0.0);
    xy[i] = xz[i] = yz[i] = 0.0;
  }
  // Adds sym(a e e^T) + l I to node i's block.
  auto add = [&](size_t i, double a, double l, double ex, double ey, double ez) {
    xx[i] += a * ex * ex + l;
    yy[i] += a * ey * ey + l;
    zz[i] += a * ez * ez + l;
    xy[i] += a * ex * ey;
    xz[i] += a * ex * ez;
    yz[i] += a * ey * ez;
  };
  if (assembled) {
    const size_t ne = m.edges.size();
    const float* G = s.edge_block.data();
    for (size_t k = 0; k < ne; ++k) {
      const float* g = G + 9 * (k - k % kEdgeBlock) + k % kEdgeBlock;
      double b[9];
      for (int c = 0; c < 9; ++c) b[c] = g[c * kEdgeBlock];
      // G_e's symmetric part serves both ends (the transpose has the same one).
      for (const int32_t i : {m.edges[k][0], m.edges[k][1]}) {
        xx[i] += b[0];
        yy[i] += b[4];
        zz[i] += b[8];
        xy[i] += 0.5 * (b[1] + b[3]);
        xz[i] += 0.5 * (b[2] + b[6]);
        yz[i] += 0.5 * (b[5] + b[7]);
      }
    }
  } else if (jac.edges) {
    const size_t ne = m.edges.size();
    for (size_t k = 0; k < ne; ++k) {
      const double axial = s.edge_axial_k[k] - s.edge_lateral[k] + s.edge_axial_c[k];
      const double lat = s.edge_lateral[k];
      const double ex = s.edge_ex[k], ey = s.edge_ey[k], ez = s.edge_ez[k];
      add(static_cast<size_t>(m.edges[k][0]), axial, lat, ex, ey, ez);
      add(static_cast<size_t>(m.edges[k][1]), axial, lat, ex, ey, ez);
    }
  }
  if (jac.tet_volume && !assembled) {
    const size_t nt = m.tets.size();
    for (size_t t = 0; t < nt; ++t) {
      const double coef = s.tet_coef[t];
      if (coef == 0.0) continue;
      const float* w = &s.tet_w[12 * t];
      for (int c = 0; c < 4; ++c)
        add(static_cast<size_t>(m.tets[t][c]), coef, 0.0, w[3 * c], w[3 * c + 1], w[3 * c + 2]);
    }
  }
  if (jac.area && !assembled) {
    const size_t nf = m.faces.size();
    for (size_t f = 0; f < nf; ++f) {
      for (int c = 0; c < 3; ++c) {
        const Vec3& w = s.shape_dir[3 * f + c];
        add(static_cast<size_t>(m.faces[f][c]), s.shape_coef[f], 0.0, w.x(), w.y(), w.z());
      }
    }
  }
  for (size_t i = 0; i < n; ++i) {
    if (beta > 0.0) {
      const Vec3& g = s.vol_grad[i];
      add(i, beta, 0.0, g.x(), g.y(), g.z());
    }
    if (m.fixed[i]) {
      xx[i] = yy[i] = zz[i] = xy[i] = xz[i] = yz[i] = 0.0;
      continue;
    }
    // A held coordinate leaves the block: its row and column are cleared and its diagonal set to
    // 1 for the inversion, then to 0.
    const bool hx = mask[3 * i] == 0.0, hy = mask[3 * i + 1] == 0.0, hz = mask[3 * i + 2] == 0.0;
    double a = xx[i], b = xy[i], c = xz[i], d = yy[i], e = yz[i], f = zz[i];
    if (hx) a = 1.0, b = c = 0.0;
    if (hy) d = 1.0, b = e = 0.0;
    if (hz) f = 1.0, c = e = 0.0;
    // The symmetric inverse by cofactors.
    const double A = d * f - e * e, Bc = c * e - b * f, C = b * e - c * d;
    const double D = a * f - c * c, E = b * c - a * e, F = a * d - b * b;
    const double det = a * A + b * Bc + c * C;
    if (!(det > 1e-12 * a * d * f) || !std::isfinite(det)) {
      // Not positive definite in floating point (never seen; a safeguard): the diagonal alone.
      xx[i] = hx ? 0.0 : 1.0 / a;
      yy[i] = hy ? 0.0 : 1.0 / d;
      zz[i] = hz ? 0.0 : 1.0 / f;
      xy[i] = xz[i] = yz[i] = 0.0;
      continue;
    }
    const double inv = 1.0 / det;
    xx[i] = hx ? 0.0 : A * inv;
    yy[i] = hy ? 0.0 : D * inv;
    zz[i] = hz ? 0.0 : F * inv;
    xy[i] = Bc * inv;
    xz[i] = C * inv;
    yz[i] = E * inv;
  }
}

// p = z + beta p.
RHEO_SIM_KERNEL void CgDirection(size_t n3, double beta, const double* z, double* p) {
#pragma omp simd
  for (size_t k = 0; k < n3; ++k) p[k] = z[k] + beta * p[k];
}

}  // namespace

void SymplecticEulerSubstep(const Model& m, const Parameters& p, const ActiveTerms& terms, State& s,
                            double h, double tick) {
  ComputeForces(m, p, terms, s, h, /*a_step=*/h, /*linearise=*/ActiveTerms{});
  const int32_t n = m.num_nodes;
  if (p.implicit_damping > 0.5 && terms.edges) {
    // v += h (M + h D)^-1 f with D the diagonal of the edge damping: for a damping Laplacian,
    // h * lambda((M + h D)^-1 C) < 2 for every h, so the dampers never limit the substep; the
    // update is still first-order consistent (it differs from plain Euler by O(h^2)).
    for (int32_t i = 0; i < n; ++i) {
      if (m.fixed[i]) continue;
      s.v[i] += (h / (m.mass[i] + h * s.damp_diag[i])) * s.f[i];
    }
  } else {
    for (int32_t i = 0; i < n; ++i) s.v[i] += (h * m.inv_mass[i]) * s.f[i];
  }
  if (terms.floor) FloorProjection(m, p, s, h, tick);
  Advect(m, s, h);
}

SolveStats ImplicitEulerSubstep(const Model& m, const Parameters& p, const ActiveTerms& terms,
                                const ActiveTerms& jac, State& s, double h, double tick) {
  const int32_t n = m.num_nodes;
  // BDF2 needs the previous substep, taken with the same h; otherwise this substep is BDF1
  // (backward Euler), which also starts the history.
  const bool bdf2 = p.implicit_order > 1.5 && s.have_prev && s.prev_h == h;
  // BDF2: x1 = (4 x0 - x_1)/3 + (2h/3) v1, v1 = (4 v0 - v_1)/3 + (2h/3) M^-1 f(x1, v1); linearised
  // about (x0, v0) this is the backward Euler system with step hh = 2h/3 and, with u = v1 - v0,
  // (M + hh D + hh^2 K) u = hh f + M (v0 - v_1)/3 - hh^2 K (v0 + (x0 - x_1) / (3 hh)).
  const double hh = bdf2 ? 2.0 * h / 3.0 : h;
  // Shape springs left explicit are extrapolated to the end of the step in BDF2
  // (2 f(x0) - f(x_1), the SBDF2 scheme); taken at x0 alone they would make it first order and
  // weakly damped.
  const bool shape_explicit =
      (terms.area && !jac.area) || (terms.tet_volume && (!jac.tet_volume || s.tet_split));
  // CG is warm-started from the previous dv extrapolated linearly (dv changes smoothly from one
  // substep to the next while the object moves).
  // The system is A u = b - hh^2 K k with A = M + hh D + hh^2 K, b = hh f (+ M (v0 - v_1)/3 in
  // BDF2) and k = v0 (+ (x0 - x_1)/(3 hh) in BDF2). The residual of the warm start u0 then is
  // b - M u0 - hh^2 K (k + u0) - hh D u0: one Jacobian product with a = k + u0 (in cg_p) and
  // b = u0. (Fused into the edge force kernel, it cost 5 % more per tick at 5k and 20k tets.) The
  // diagonal starts at the masses; the edge kernel adds its share.
  const double k_scale = bdf2 ? 1.0 / (3.0 * hh) : 0.0;
  // The tool's springs (State::k_ext) are diagonal: hh^2 k_ext joins the masses in the
  // diagonal, the product and the warm start's residual.
  const bool springs = s.ext_springs > 0;
  // The floor inside the solve (the filtered CG of Baraff and Witkin, 1998): a node that would
  // cross it in this substep, or that it held in the last one and that stays within
  // kFloorHoldSlop, has its normal velocity prescribed, v1.y = (floor - y)/hh with y the base of
  // the position update, and its y coordinate leaves the unknowns (its preconditioner is 0, so no
  // search direction moves it; its row stays in the product, and the residual CG carries there
  // is minus the floor's impulse). The rest of the object then meets the impact in
  // the same solve; projected only afterwards, the nodes above a stopped one kept falling into it
  // for a substep, and a 22k-tet bean dropped 2 cm inverted its bottom layer and blew up.
  const double floor = p.floor_height;
  s.floor_nodes = 0;
  // inv_diag3 first holds 1 per unknown coordinate and 0 per held one; the preconditioner loop
  // below scales it by the inverse diagonal.
  auto held = [&](int32_t i, int c) { return s.inv_diag3[3 * i + c] == 0.0 && !m.fixed[i]; };
  for (int32_t i = 0; i < n; ++i) {
    const Vec3 last = s.dv[i];
    Vec3 dv = 2.0 * last - s.dv_prev[i];
    s.dv_prev[i] = last;
    if (m.fixed[i] || !dv.allFinite()) dv.setZero();
    const double held_before = s.floor_impulse[i].y();
    const bool stick_before = s.floor_stick[i] != 0;
    s.floor_impulse[i].setZero();
    s.floor_stick[i] = 0;
    for (int c = 0; c < 3; ++c) s.inv_diag3[3 * i + c] = 1.0;
    if (terms.floor && !m.fixed[i]) {
      const double vy = s.v[i].y();
      const double y = bdf2 ? (4.0 * s.x[i].y() - s.x_prev[i].y()) / 3.0 : s.x[i].y();
      const bool hold = held_before > 0.0 && y + hh * vy <= floor + kFloorHoldSlop;
      if (y + hh * vy < floor || hold) {
        double vn = (floor - y) / hh;
        if (y < floor) vn = std::min(vn, std::max(vy, 0.0) + kMaxDepenetrationSpeed);
        if (vn > vy || hold) {
          dv.y() = vn - vy;
          s.inv_diag3[3 * i + 1] = 0.0;
          ++s.floor_nodes;
          if (hold && stick_before) {
            // Static friction inside the solve: the sticking node's tangential velocity is 0.
            // With friction only projected after the solve, a held node moved freely along the
            // floor within each solve, and a bean standing on its rim walked 6 cm in 1 s at
            // friction 5 (1.5 cm before the nodes were held).
            dv.x() = -s.v[i].x();
            dv.z() = -s.v[i].z();
            s.inv_diag3[3 * i] = 0.0;
            s.inv_diag3[3 * i + 2] = 0.0;
            s.floor_stick[i] = 1;
          }
        }
      }
    }
    s.dv[i] = dv;
    const Vec3 k = bdf2 ? Vec3(s.v[i] + k_scale * (s.x[i] - s.x_prev[i])) : s.v[i];
    s.cg_p[i] = k + dv;
    s.diag[i] = m.mass[i];
    if (springs) {
      s.diag[i] += hh * hh * s.k_ext[i];
      for (int c = 0; c < 3; ++c) s.sys_mass3[3 * i + c] = s.diag[i];
    }
  }
  ComputeForces(m, p, terms, s, hh, /*a_step=*/h, /*linearise=*/jac,
                shape_explicit ? s.f_shape.data() : nullptr);
  if (shape_explicit) {
    for (int32_t i = 0; i < n; ++i) {
      if (bdf2 && s.have_prev_shape) s.f[i] += s.f_shape[i] - s.f_shape_prev[i];
      s.f_shape_prev[i] = s.f_shape[i];
    }
  }
  s.have_prev_shape = shape_explicit;
  // The preconditioner. Block Jacobi (cg_preconditioner 1): each node's 3x3 block of the system,
  // inverted (BlockJacobi). Jacobi (0): the diagonal of the system (mass + trace/3 of each edge
  // block; the edge kernel added the edges' share), kept as its inverse, 0 on fixed nodes (dv = 0
  // there). inv_diag3 is both ways the mask of the unknowns.
  // With shape springs in the system, their blocks can join the edges' (AssembleEdgeBlocks): one
  // pass over the edges per product instead of one over the edges and one over the elements.
  // Assembling costs about two element-wise products, so it is done when the elements in the
  // system times the CG iterations (the last substep's) reach twice the edges: at 103k tets with
  // 69k in the system and 6 iterations, CPU per tick falls by 15-20 %; a sketched 5k-tet object
  // with 15 of its tets in the system would have been 8-13 % slower.
  const bool assembled = (jac.area || jac.tet_volume) && !m.edge_tet_start.empty() &&
                         s.system_elements * std::max(s.last_cg_iterations, 1) >=
                             2 * static_cast<int64_t>(m.edges.size());
  if (assembled) {
    // The blocks may be kept for jacobian_lag substeps: CG then solves for the correction to the
    // warm start with the blocks of up to lag - 1 substeps back, while its right-hand side (the
    // warm start's residual, from ApplyJacobian) is the current one. Rebuilt whenever the step,
    // the elements in the system or the history (a restore, a teleport) changed.
    const int32_t lag = std::max(1, static_cast<int32_t>(p.jacobian_lag));
    const bool stale = s.edge_block_age < 0 || !s.have_prev || s.edge_block_hh != hh ||
                       s.edge_block_elements != s.system_elements || s.edge_block_age + 1 >= lag;
    if (stale) {
      AssembleEdgeBlocks(m, jac, s);
      s.edge_block_age = 0;
      s.edge_block_hh = hh;
      s.edge_block_elements = s.system_elements;
    } else {
      ++s.edge_block_age;
    }
  } else {
    s.edge_block_age = -1;
  }
  const bool block = p.cg_preconditioner > 0.5;
  if (block) {
    BlockJacobi(m, jac, s, springs ? hh * hh : 0.0,
                jac.global_volume ? s.global_k + s.global_c : 0.0, s.inv_diag3.data(), assembled);
  }
  const double beta_v = jac.global_volume ? (s.global_k + s.global_c) / 3.0 : 0.0;
  for (int32_t i = 0; i < n; ++i) {
    const double d = s.diag[i] + beta_v * s.vol_grad[i].squaredNorm();
    const double inv = m.fixed[i] ? 0.0 : 1.0 / d;
    for (int c = 0; c < 3; ++c) s.inv_diag3[3 * i + c] *= inv;
  }
  const size_t n3 = 3 * static_cast<size_t>(n);
  auto flat = [](std::vector<Vec3>& v) { return v.data()->data(); };
  // out = A in (rows of fixed nodes zero); returns in . out.
  const double* sys_mass = springs ? s.sys_mass3.data() : s.mass3.data();
  auto apply_a = [&](std::vector<Vec3>& in, std::vector<Vec3>& out) {
    if (assembled)
      ApplyAssembled(m, jac, s, in, in, out);
    else
      ApplyJacobian(m, jac, s, in, in, out);
    return FinishProduct(n3, s.keep3.data(), sys_mass, flat(in), flat(out));
  };
  // The warm start's product from the blocks when they are this substep's: G (k + u0) less the
  // edges' damping of k. Element by element it cost as much as assembling them (14 % of a 21.6k-tet
  // tick).
  if (assembled && s.edge_block_age == 0)
    ApplyAssembled(m, jac, s, s.cg_p, s.dv, s.cg_q);
  else
    ApplyJacobian(m, jac, s, s.cg_p, s.dv, s.cg_q);
  // The relative tolerance is taken against |b|, the impulse of the forces over the step.
  double b2 = 0.0, v_max2 = 0.0;
  for (int32_t i = 0; i < n; ++i) {
    Vec3 b = hh * s.f[i];
    if (bdf2) b += m.mass[i] * (s.v[i] - s.v_prev[i]) / 3.0;
    if (m.fixed[i]) b.setZero();
    s.cg_r[i] = m.fixed[i] ? Vec3::Zero() : Vec3(b - m.mass[i] * s.dv[i] - s.cg_q[i]);
    if (springs && !m.fixed[i]) s.cg_r[i] -= (hh * hh * s.k_ext[i]) * s.cg_p[i];
    b2 += b.squaredNorm();
    v_max2 = std::max(v_max2, s.v[i].squaredNorm());
  }
  const double rhs_norm = std::sqrt(b2);
  SolveStats stats;
  // Held nodes are solved for even where b = 0 (their prescribed changes are the right-hand side).
  if (rhs_norm > 0.0 || s.floor_nodes > 0) {
    // Near rest the solve is tightened: there the right-hand side is mostly weight held by the
    // floor, and an error relative to it, repeated every tick, keeps light nodes jittering above
    // sleep_speed (warm-started, the tighter solve costs about one iteration at rest).
    const bool near_rest = p.sleep_time > 0.0 && v_max2 < 100.0 * p.sleep_speed * p.sleep_speed;
    int max_it = static_cast<int>(p.cg_max_iterations);
    const double mean_it = s.cg_mean_iterations > 0.0 ? s.cg_mean_iterations : kMinBudgetIterations;
    if (p.cg_iteration_budget > 0.0) {
      max_it =
          std::min(max_it, std::max(kMinBudgetIterations,
                                    static_cast<int>(std::ceil(p.cg_iteration_budget * mean_it))));
    }
    double rz = 0.0, r2 = 0.0;
    if (block)
      CgStartBlock(static_cast<size_t>(n), flat(s.cg_r), s.pre_block.data(), s.inv_diag3.data(),
                   flat(s.cg_z), flat(s.cg_p), &rz, &r2);
    else
      CgStart(n3, flat(s.cg_r), s.inv_diag3.data(), flat(s.cg_z), flat(s.cg_p), &rz, &r2);
    double r_norm = std::sqrt(r2);
    // With the floor in the solve, its prescribed changes are part of the right-hand side: they
    // reach the neighbours through A (mostly h D, the edge dampers, far heavier than the node
    // masses), so the start's residual, not |b|, is the scale of the impact's substeps. Relative
    // to |b| alone they took 15-24 CG iterations instead of 3-8 on a 4.6k-tet bean.
    const double scale = s.floor_nodes > 0 ? std::max(rhs_norm, r_norm) : rhs_norm;
    const double tol =
        (near_rest ? std::min(p.cg_tolerance, kRestCgTolerance) : p.cg_tolerance) * scale;
    int it = 0;
    // Three passes over the nodes per iteration: the product (with p.q), the updates (with r.z
    // and r.r), the new direction.
    while (it < max_it && r_norm > tol) {
      const double pq = apply_a(s.cg_p, s.cg_q);
      if (!(pq > 0.0)) break;
      const double alpha = rz / pq;
      double rz_next = 0.0;
      if (block)
        CgUpdateBlock(static_cast<size_t>(n), alpha, flat(s.cg_p), flat(s.cg_q), s.pre_block.data(),
                      s.inv_diag3.data(), flat(s.dv), flat(s.cg_r), flat(s.cg_z), &rz_next, &r2);
      else
        CgUpdate(n3, alpha, flat(s.cg_p), flat(s.cg_q), s.inv_diag3.data(), flat(s.dv),
                 flat(s.cg_r), flat(s.cg_z), &rz_next, &r2);
      const double beta = rz_next / rz;
      rz = rz_next;
      CgDirection(n3, beta, flat(s.cg_z), flat(s.cg_p));
      r_norm = std::sqrt(r2);
      ++it;
    }
    stats.iterations = it;
    s.last_cg_iterations = it;
    s.cg_mean_iterations = mean_it + kBudgetMeanWeight * (it - mean_it);
    stats.residual = scale > 0.0 ? r_norm / scale : 0.0;
  } else {
    for (int32_t i = 0; i < n; ++i) s.dv[i].setZero();
  }
  if (s.floor_nodes > 0) {
    // The floor's impulse on each node it held, (A u - b) in the held coordinates: minus the
    // residual CG carried there (an extra product had cost 10 % of a contact substep).
    const double mu = p.friction;
    for (int32_t i = 0; i < n; ++i) {
      if (!held(i, 1)) continue;
      for (int c = 0; c < 3; ++c)
        if (held(i, c)) s.floor_impulse[i][c] = -s.cg_r[i][c];
      // A sticking node goes on sticking while the static friction it needed stays within the
      // cone (and the floor pushes it); otherwise it slides, with friction projected, next time.
      const Vec3& j = s.floor_impulse[i];
      if (s.floor_stick[i] != 0 && !(j.y() > 0.0 && std::hypot(j.x(), j.z()) <= mu * j.y()))
        s.floor_stick[i] = 0;
    }
  }
  // History for the next substep; for BDF2 x becomes (4 x0 - x_1)/3, from which x1 = x + hh v1.
  for (int32_t i = 0; i < n; ++i) {
    const Vec3 x0 = s.x[i];
    if (bdf2) s.x[i] = (4.0 * x0 - s.x_prev[i]) / 3.0;
    s.x_prev[i] = x0;
    s.v_prev[i] = s.v[i];
    s.v[i] += s.dv[i];
  }
  s.have_prev = true;
  s.prev_h = h;
  if (terms.floor) FloorProjection(m, p, s, hh, tick, s.floor_impulse.data(), h);
  Advect(m, s, hh);
  return stats;
}

}  // namespace rheo::sim::internal
