// The implicit system's products (ApplyJacobian, and ApplyAssembled over the blocks that
// AssembleEdgeBlocks stores), from what ComputeForces (forces.cc) stored with `linearise`.
#include <algorithm>
#include <cstdint>

#include "sim/forces.h"

namespace rheo::sim::internal {

namespace {

// One edge block of the implicit system times the differences across the edge:
// y = (K_e) da + (D_e) db, K_e = (axial_k - lateral) e e^T + lateral I, D_e = axial_c e e^T.
// eb = e . db (the caller may know it equals e . da).
inline void EdgeBlockProduct(double ex, double ey, double ez, double axial_k, double axial_c,
                             double lateral, const double da[3], double eb, double y[3]) {
  const double ea = ex * da[0] + ey * da[1] + ez * da[2];
  const double g = (axial_k - lateral) * ea + axial_c * eb;
  y[0] = g * ex + lateral * da[0];
  y[1] = g * ey + lateral * da[1];
  y[2] = g * ez + lateral * da[2];
}

// out[node] += (x, y, z): a node's sum over its run of edges.
inline void AddToNode(double* out, int32_t node, double x, double y, double z) {
  out[3 * node] += x;
  out[3 * node + 1] += y;
  out[3 * node + 2] += z;
}

// out += K_e a + D_e b over the edges, K_e = (axial_k - lateral) e e^T + lateral I and
// D_e = axial_c e e^T for d = a_i - a_j (and b_i - b_j): y to node i, -y to node j. A plain
// scalar loop (little arithmetic per edge: the blocked form of the force kernels was slower
// here). Edges are sorted by their first node, so node i's sum stays in registers for its whole
// run of edges and only node j is read and written per edge; with Vec3 stores to both ends, every
// edge waited on the store of the one before (store forwarding).
template <bool kSame>
[[gnu::always_inline]] inline void EdgeJacobianT(const Model& m, const State& s, const double* Pa,
                                                 const double* Pb, double* out) {
  const size_t ne = m.edges.size();
  const int32_t* E = m.edges.data()->data();
  const double* EX = s.edge_ex.data();
  const double* EY = s.edge_ey.data();
  const double* EZ = s.edge_ez.data();
  const double* AK = s.edge_axial_k.data();
  const double* AC = s.edge_axial_c.data();
  const double* AL = s.edge_lateral.data();
  int32_t cur = -1;
  double ax = 0.0, ay = 0.0, az = 0.0, bx = 0.0, by = 0.0, bz = 0.0;
  double sx = 0.0, sy = 0.0, sz = 0.0;
  for (size_t k = 0; k < ne; ++k) {
    const int32_t i = E[2 * k], j = E[2 * k + 1];
    if (i != cur) {
      if (cur >= 0) AddToNode(out, cur, sx, sy, sz);
      cur = i;
      ax = Pa[3 * i];
      ay = Pa[3 * i + 1];
      az = Pa[3 * i + 2];
      if constexpr (!kSame) {
        bx = Pb[3 * i];
        by = Pb[3 * i + 1];
        bz = Pb[3 * i + 2];
      }
      sx = sy = sz = 0.0;
    }
    const double ex = EX[k], ey = EY[k], ez = EZ[k];
    const double da[3] = {ax - Pa[3 * j], ay - Pa[3 * j + 1], az - Pa[3 * j + 2]};
    const double eb =
        kSame ? ex * da[0] + ey * da[1] + ez * da[2]
              : ex * (bx - Pb[3 * j]) + ey * (by - Pb[3 * j + 1]) + ez * (bz - Pb[3 * j + 2]);
    double y[3];
    EdgeBlockProduct(ex, ey, ez, AK[k], AC[k], AL[k], da, eb, y);
    sx += y[0];
    sy += y[1];
    sz += y[2];
    out[3 * j] -= y[0];
    out[3 * j + 1] -= y[1];
    out[3 * j + 2] -= y[2];
  }
  if (cur >= 0) AddToNode(out, cur, sx, sy, sz);
}

// out += sum over tets of sigma (w . a) w (eq. 6's Gauss-Newton blocks). A plain loop, as for
// the edges: the blocked form (gather, vector pass, scatter) was slower (80 us against 60 us for
// the whole product at 5k tets).
RHEO_SIM_KERNEL void TetJacobian(const Model& m, const State& s, const double* a, double* out) {
  const size_t nt = m.tets.size();
  const int32_t* Tt = m.tets.data()->data();
  const float* TW = s.tet_w.data();
  const double* TC = s.tet_coef.data();
  for (size_t k = 0; k < nt; ++k) {
    const double coef = TC[k];
    if (coef == 0.0) continue;
    int32_t node[4];
    double w[12];
    double dot = 0.0;
    for (int q = 0; q < 4; ++q) {
      node[q] = Tt[4 * k + q];
      for (int c = 0; c < 3; ++c) {
        w[3 * q + c] = TW[12 * k + 3 * q + c];
        dot += w[3 * q + c] * a[3 * node[q] + c];
      }
    }
    const double g = coef * dot;
    for (int q = 0; q < 4; ++q) {
      for (int c = 0; c < 3; ++c) out[3 * node[q] + c] += g * w[3 * q + c];
    }
  }
}

RHEO_SIM_KERNEL void EdgeJacobian(const Model& m, const State& s, const double* a, const double* b,
                                  double* out) {
  if (a == b)
    EdgeJacobianT<true>(m, s, a, b, out);
  else
    EdgeJacobianT<false>(m, s, a, b, out);
}

// out += the edge blocks' product: y = G (a_i - a_j) to node i, -G^T (a_i - a_j) to node j. In
// blocks of kEdgeBlock edges: a scalar gather of the differences, the 3x3 products vectorised
// across the block (the blocks are stored that way, component-major), a scalar scatter with node
// i's sum kept in registers over its run of edges (as in EdgeJacobianT).
// kDamp: the warm start's product K a + D b from G = K + D, i.e. G d less the edge's damping
// D_e = axial_c e e^T of (a - b) across it, in the same pass and vectorised with it (a separate
// scalar pass over the edges cost 60 % of the product).
template <bool kDamp>
[[gnu::always_inline]] inline void EdgeBlockJacobianT(const Model& m, const State& s,
                                                      const double* a, const double* b,
                                                      double* out) {
  const size_t ne = m.edges.size();
  const int32_t* E = m.edges.data()->data();
  const float* G = s.edge_block.data();
  // d (and dk) are zeroed once: the lanes past the last edge read them (their blocks are zero,
  // and so are their directions and dampers: State pads those to whole groups).
  alignas(64) double d[3][kEdgeBlock] = {}, y[3][kEdgeBlock], z[3][kEdgeBlock];
  alignas(64) double dk[3][kEdgeBlock] = {};
  const double* EX = s.edge_ex.data();
  const double* EY = s.edge_ey.data();
  const double* EZ = s.edge_ez.data();
  const double* AC = s.edge_axial_c.data();
  int32_t cur = -1;
  double sx = 0.0, sy = 0.0, sz = 0.0;
  for (size_t k0 = 0; k0 < ne; k0 += kEdgeBlock) {
    const int nb = static_cast<int>(std::min<size_t>(kEdgeBlock, ne - k0));
    int32_t gi = -1;
    double ai[3] = {}, ki[3] = {};
    for (int l = 0; l < nb; ++l) {
      const int32_t i = E[2 * (k0 + l)], j = E[2 * (k0 + l) + 1];
      if (i != gi) {
        gi = i;
        for (int c = 0; c < 3; ++c) ai[c] = a[3 * i + c];
        if constexpr (kDamp)
          for (int c = 0; c < 3; ++c) ki[c] = ai[c] - b[3 * i + c];
      }
      for (int c = 0; c < 3; ++c) d[c][l] = ai[c] - a[3 * j + c];
      if constexpr (kDamp)
        for (int c = 0; c < 3; ++c) dk[c][l] = ki[c] - (a[3 * j + c] - b[3 * j + c]);
    }
    const float* g = G + 9 * k0;  // this block's 9 rows of kEdgeBlock
#pragma omp simd
    for (int l = 0; l < kEdgeBlock; ++l) {
      double gl[9];
      for (int c = 0; c < 9; ++c) gl[c] = g[c * kEdgeBlock + l];
      double damp[3] = {};
      if constexpr (kDamp) {
        const size_t k = k0 + l;
        const double w = AC[k] * (EX[k] * dk[0][l] + EY[k] * dk[1][l] + EZ[k] * dk[2][l]);
        damp[0] = w * EX[k];
        damp[1] = w * EY[k];
        damp[2] = w * EZ[k];
      }
      for (int r = 0; r < 3; ++r) {
        y[r][l] = gl[3 * r] * d[0][l] + gl[3 * r + 1] * d[1][l] + gl[3 * r + 2] * d[2][l] - damp[r];
        z[r][l] = gl[r] * d[0][l] + gl[3 + r] * d[1][l] + gl[6 + r] * d[2][l] - damp[r];
      }
    }
    for (int l = 0; l < nb; ++l) {
      const int32_t i = E[2 * (k0 + l)], j = E[2 * (k0 + l) + 1];
      if (i != cur) {
        if (cur >= 0) AddToNode(out, cur, sx, sy, sz);
        cur = i;
        sx = sy = sz = 0.0;
      }
      sx += y[0][l];
      sy += y[1][l];
      sz += y[2][l];
      out[3 * j] -= z[0][l];
      out[3 * j + 1] -= z[1][l];
      out[3 * j + 2] -= z[2][l];
    }
  }
  if (cur >= 0) AddToNode(out, cur, sx, sy, sz);
}

RHEO_SIM_KERNEL void EdgeBlockJacobian(const Model& m, const State& s, const double* a,
                                       const double* b, double* out) {
  if (b == a)
    EdgeBlockJacobianT<false>(m, s, a, a, out);
  else
    EdgeBlockJacobianT<true>(m, s, a, b, out);
}

// out += the rank-one global volume term's product.
void GlobalVolumeJacobian(const Model& m, const State& s, std::span<const Vec3> a,
                          std::span<const Vec3> b, std::span<Vec3> out) {
  const int32_t n = m.num_nodes;
  double dot_a = 0.0, dot_b = 0.0;
  for (int32_t i = 0; i < n; ++i) {
    dot_a += s.vol_grad[i].dot(a[i]);
    dot_b += s.vol_grad[i].dot(b[i]);
  }
  const double c = s.global_k * dot_a + s.global_c * dot_b;
  for (int32_t i = 0; i < n; ++i) out[i] += c * s.vol_grad[i];
}

// g -= coef w_q w_r^T for list entry `entry` (model.h) of an element whose corner directions are
// w (3 per corner), in single precision (the blocks are stored in it).
template <typename W>
inline void SubtractPairBlock(int32_t entry, float coef, const W* w, float g[9]) {
  const W* wq = w + 3 * ((entry >> 2) & 3);
  const W* wr = w + 3 * (entry & 3);
  const float r0 = static_cast<float>(wr[0]), r1 = static_cast<float>(wr[1]),
              r2 = static_cast<float>(wr[2]);
  for (int r = 0; r < 3; ++r) {
    const float cr = coef * static_cast<float>(wq[r]);
    g[3 * r] -= cr * r0;
    g[3 * r + 1] -= cr * r1;
    g[3 * r + 2] -= cr * r2;
  }
}

}  // namespace

// Each edge's block is gathered from its elements and written once (a scatter from the elements
// read and wrote every block about five times).
RHEO_SIM_KERNEL void AssembleEdgeBlocks(const Model& m, const ActiveTerms& terms, State& s) {
  const size_t ne = m.edges.size();
  float* G = s.edge_block.data();
  const int32_t* ts = m.edge_tet_start.data();
  const int32_t* tl = m.edge_tet.data();
  const int32_t* fs = m.edge_face_start.data();
  const int32_t* fl = m.edge_face.data();
  for (size_t k = 0; k < ne; ++k) {
    float g[9] = {};
    if (terms.edges) {
      double ge[9];
      EdgeSystemBlock(s, k, ge);
      for (int c = 0; c < 9; ++c) g[c] = static_cast<float>(ge[c]);
    }
    if (terms.tet_volume) {
      for (int32_t q = ts[k]; q < ts[k + 1]; ++q) {
        const int32_t t = tl[q] >> 4;
        const double coef = s.tet_coef[t];
        if (coef != 0.0) SubtractPairBlock(tl[q], static_cast<float>(coef), &s.tet_w[12 * t], g);
      }
    }
    if (terms.area) {
      for (int32_t q = fs[k]; q < fs[k + 1]; ++q) {
        const int32_t f = fl[q] >> 4;
        const double coef = s.shape_coef[f];
        if (coef != 0.0)
          SubtractPairBlock(fl[q], static_cast<float>(coef), s.shape_dir[3 * f].data(), g);
      }
    }
    float* gk = G + 9 * (k - k % kEdgeBlock) + k % kEdgeBlock;
    for (int c = 0; c < 9; ++c) gk[c * kEdgeBlock] = g[c];
  }
}

void ApplyAssembled(const Model& m, const ActiveTerms& terms, const State& s,
                    std::span<const Vec3> a, std::span<const Vec3> b, std::span<Vec3> out) {
  const int32_t n = m.num_nodes;
  for (int32_t i = 0; i < n; ++i) out[i].setZero();
  // Without the edges in the system the blocks hold no damping.
  const double* bb = terms.edges ? b.data()->data() : a.data()->data();
  EdgeBlockJacobian(m, s, a.data()->data(), bb, out.data()->data());
  if (terms.global_volume) GlobalVolumeJacobian(m, s, a, b, out);
}

void ApplyJacobian(const Model& m, const ActiveTerms& terms, const State& s,
                   std::span<const Vec3> a, std::span<const Vec3> b, std::span<Vec3> out) {
  const int32_t n = m.num_nodes;
  for (int32_t i = 0; i < n; ++i) out[i].setZero();
  if (terms.edges) EdgeJacobian(m, s, a.data()->data(), b.data()->data(), out.data()->data());
  if (terms.global_volume) GlobalVolumeJacobian(m, s, a, b, out);
  // Eqs. 5-6 (Gauss-Newton blocks) have no damping part.
  if (terms.area) {
    const size_t nf = m.faces.size();
    for (size_t k = 0; k < nf; ++k) {
      const auto& fc = m.faces[k];
      const Vec3* w = &s.shape_dir[3 * k];
      const double dot = w[0].dot(a[fc[0]]) + w[1].dot(a[fc[1]]) + w[2].dot(a[fc[2]]);
      const double c = s.shape_coef[k] * dot;
      out[fc[0]] += c * w[0];
      out[fc[1]] += c * w[1];
      out[fc[2]] += c * w[2];
    }
  }
  if (terms.tet_volume) TetJacobian(m, s, a.data()->data(), out.data()->data());
}

}  // namespace rheo::sim::internal
