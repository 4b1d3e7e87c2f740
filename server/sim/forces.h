// Force terms (forces.cc) and their linearisation: the implicit system's products and edge blocks
// (jacobian.cc). Internal to rheo_sim.
#pragma once

#include <span>

#include "sim/model.h"
#include "sim/params.h"
#include "sim/state.h"

// Hot loops are compiled for the x86-64 baseline, x86-64-v3 (AVX2, FMA) and x86-64-v4 (AVX-512:
// 10 % less time per 5k-tet tick than v3 on the Zen 4 development machine); the loader picks the
// best one the CPU runs (GCC function multi-versioning). Off under sanitizers and elsewhere.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(RHEO_SIM_NO_CLONES) && !defined(__SANITIZE_ADDRESS__) &&  \
    !defined(__SANITIZE_THREAD__)
#define RHEO_SIM_KERNEL \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define RHEO_SIM_KERNEL
#endif

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

/// state.f = every force at (state.x, state.v); updates state.tension. With a_step > 0, advances
/// every Voigt ratio over a_step holding the current l, dl/dt. For each term on in `linearise` (a
/// subset of `terms`; all off for the explicit integrator), fills its blocks of the implicit system
/// for step h; with linearise.edges, the edges' share of the diagonal is added to state.diag (the
/// caller sets it to the masses first). With `shape_forces` (n entries), also writes the shape
/// springs' (eqs. 5-6) share of state.f there.
void ComputeForces(const Model& model, const Parameters& params, const ActiveTerms& terms,
                   State& state, double h, double a_step, const ActiveTerms& linearise,
                   Vec3* shape_forces = nullptr);

/// out = h^2 K a + h D b with D, K the positive semi-definite damping and stiffness
/// approximations stored by ComputeForces for the terms on in `terms` (a = b for the system's
/// product; apart, the right-hand side's stiffness term and the warm start's residual share one
/// pass).
void ApplyJacobian(const Model& model, const ActiveTerms& terms, const State& state,
                   std::span<const Vec3> a, std::span<const Vec3> b, std::span<Vec3> out);

/// Edge k's 3x3 block of the system, K_e + D_e = (axial_k - lateral + axial_c) e e^T + lateral I
/// (row-major), from what ComputeForces stored with linearise.edges.
inline void EdgeSystemBlock(const State& s, size_t k, double g[9]) {
  const double e[3] = {s.edge_ex[k], s.edge_ey[k], s.edge_ez[k]};
  const double axial = s.edge_axial_k[k] - s.edge_lateral[k] + s.edge_axial_c[k];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) g[3 * r + c] = axial * e[r] * e[c];
    g[4 * r] += s.edge_lateral[k];
  }
}

/// Edges per group in state.edge_block: a group holds its edges' 3x3 blocks component by
/// component (9 rows of kEdgeBlock floats), so that the product vectorises across edges.
inline constexpr int kEdgeBlock = 16;

/// Fills state.edge_block for the product of the system of the terms on in `terms` (edges,
/// global volume aside): each edge's block K_e + D_e, plus the Gauss-Newton blocks of the area and
/// volume springs that ComputeForces stored (eqs. 5-6), each added to the edges joining its nodes.
/// A spring's block sigma w w^T acts on differences across node pairs (its w sum to zero), so the
/// product becomes one pass over the edges. Needs model.edge_tet_start (model.h).
void AssembleEdgeBlocks(const Model& model, const ActiveTerms& terms, State& state);

/// out = ApplyJacobian(terms, a, b) from the blocks AssembleEdgeBlocks stored (up to rounding):
/// G a, plus for b != a the edges' damping blocks times (b - a) (G = K + D; the shape springs
/// have no damping part).
void ApplyAssembled(const Model& model, const ActiveTerms& terms, const State& state,
                    std::span<const Vec3> a, std::span<const Vec3> b, std::span<Vec3> out);

/// Volume enclosed by the boundary faces [m^3].
double EnclosedVolume(const Model& model, std::span<const Vec3> x);

}  // namespace rheo::sim::internal
