// sim_bench precond [max_tets]: CG preconditioners on one tick's system.
#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include "bench.h"
#include "sim/forces.h"

namespace sim_bench {
namespace {

// Preconditioners for the implicit step's CG, on the system of one tick of the refined box in
// mid-drop (BDF1, 1 ms), from the integrator's own warm start and to its own tolerance. The
// integrator uses Jacobi (the diagonal: mass, the edges' share and the volume term's); the others
// show what a better preconditioner would buy: a 3x3 block Jacobi, and two-level methods with an
// exact coarse solve on a trilinear grid (an ideal for any multigrid: the coarse operator is
// formed by probing and factorised outside the timed solve).
struct PrecondSystem {
  const Model* m = nullptr;
  internal::ActiveTerms jac;
  State s;  // the object's state, linearised for the tick
  int32_t n = 0;
  Eigen::VectorXd b, r0, u0, inv_diag;
  std::vector<Vec3> in, out;
  // out = A x (fixed rows zero), A = M + h D + h^2 K.
  void Apply(const Eigen::VectorXd& x, Eigen::VectorXd& y) {
    for (int32_t i = 0; i < n; ++i) in[i] = x.segment<3>(3 * i);
    internal::ApplyJacobian(*m, jac, s, in, in, out);
    y.resize(3 * n);
    for (int32_t i = 0; i < n; ++i)
      y.segment<3>(3 * i) = m->fixed[i] ? Vec3::Zero() : Vec3(out[i] + m->mass[i] * in[i]);
  }
};

// The system of the next tick of `obj` (BDF1, one substep of h), as ImplicitEulerSubstep sets it.
PrecondSystem MakePrecondSystem(SimObject& obj, const Parameters& p, double h) {
  PrecondSystem sys;
  const Model& m = obj.model();
  sys.m = &m;
  sys.n = m.num_nodes;
  const internal::ActiveTerms terms = internal::DecideTerms(m, p);
  sys.jac = terms;
  const ShapeTreatment shape = obj.ShapeSpringsTreatment(h);
  if (shape != ShapeTreatment::kImplicit) sys.jac.area = false;
  if (shape == ShapeTreatment::kExplicit) sys.jac.tet_volume = false;
  sys.s = obj.state();
  State& s = sys.s;
  s.tet_split = shape == ShapeTreatment::kSplit;
  const int32_t n = sys.n;
  sys.in.resize(n);
  sys.out.resize(n);
  std::vector<Vec3> a(n), u0(n);
  for (int32_t i = 0; i < n; ++i) {
    u0[i] = m.fixed[i] ? Vec3::Zero() : Vec3(2.0 * s.dv[i] - s.dv_prev[i]);
    a[i] = s.v[i] + u0[i];
    s.diag[i] = m.mass[i];
  }
  internal::ComputeForces(m, p, terms, s, h, /*a_step=*/0.0, sys.jac);
  std::vector<Vec3> q(n);
  internal::ApplyJacobian(m, sys.jac, s, a, u0, q);
  const double beta_v = sys.jac.global_volume ? (s.global_k + s.global_c) / 3.0 : 0.0;
  sys.b.resize(3 * n);
  sys.r0.resize(3 * n);
  sys.u0.resize(3 * n);
  sys.inv_diag.resize(3 * n);
  for (int32_t i = 0; i < n; ++i) {
    const Vec3 b = m.fixed[i] ? Vec3::Zero() : Vec3(h * s.f[i]);
    sys.b.segment<3>(3 * i) = b;
    sys.r0.segment<3>(3 * i) = m.fixed[i] ? Vec3::Zero() : Vec3(b - m.mass[i] * u0[i] - q[i]);
    sys.u0.segment<3>(3 * i) = u0[i];
    const double d = s.diag[i] + beta_v * s.vol_grad[i].squaredNorm();
    sys.inv_diag.segment<3>(3 * i).setConstant(m.fixed[i] ? 0.0 : 1.0 / d);
  }
  return sys;
}

// The inverse of each node's 3x3 block of A (zero on fixed nodes).
std::vector<Eigen::Matrix3d> BlockJacobi(const PrecondSystem& sys) {
  const Model& m = *sys.m;
  const State& s = sys.s;
  std::vector<Eigen::Matrix3d> blocks(sys.n, Eigen::Matrix3d::Zero());
  for (size_t k = 0; k < m.edges.size(); ++k) {
    double g[9];
    internal::EdgeSystemBlock(s, k, g);
    const Eigen::Matrix3d block = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(g);
    blocks[m.edges[k][0]] += block;
    blocks[m.edges[k][1]] += block;
  }
  if (sys.jac.tet_volume) {
    for (size_t t = 0; t < m.tets.size(); ++t) {
      for (int c = 0; c < 4; ++c) {
        const Vec3 w(s.tet_w[12 * t + 3 * c], s.tet_w[12 * t + 3 * c + 1],
                     s.tet_w[12 * t + 3 * c + 2]);
        blocks[m.tets[t][c]] += s.tet_coef[t] * w * w.transpose();
      }
    }
  }
  if (sys.jac.area) {
    for (size_t f = 0; f < m.faces.size(); ++f) {
      for (int c = 0; c < 3; ++c) {
        const Vec3& w = s.shape_dir[3 * f + c];
        blocks[m.faces[f][c]] += s.shape_coef[f] * w * w.transpose();
      }
    }
  }
  const double beta = sys.jac.global_volume ? s.global_k + s.global_c : 0.0;
  for (int32_t i = 0; i < sys.n; ++i) {
    blocks[i] +=
        m.mass[i] * Eigen::Matrix3d::Identity() + beta * s.vol_grad[i] * s.vol_grad[i].transpose();
    blocks[i] = m.fixed[i] ? Eigen::Matrix3d::Zero() : Eigen::Matrix3d(blocks[i].inverse());
  }
  return blocks;
}

// Preconditioned CG from r0 to |r| <= tol |b|: iterations, or -1 when it did not get there.
template <typename Precond>
int Pcg(PrecondSystem& sys, double tol, Precond&& precond) {
  Eigen::VectorXd r = sys.r0, z, p, q;
  precond(r, z);
  p = z;
  double rz = r.dot(z);
  const double stop = tol * sys.b.norm();
  for (int it = 0; it < 500; ++it) {
    if (r.norm() <= stop) return it;
    sys.Apply(p, q);
    const double alpha = rz / p.dot(q);
    r -= alpha * q;
    precond(r, z);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  return -1;
}

// P: trilinear interpolation from a grid of spacing `cell` over the rest shape, per coordinate,
// without the grid nodes no mesh node uses.
Eigen::SparseMatrix<double> TrilinearProlongation(const Model& m, double cell) {
  Eigen::AlignedBox3d box;
  for (const Vec3& x : m.rest_positions) box.extend(x);
  Eigen::Vector3i cells;
  for (int c = 0; c < 3; ++c)
    cells[c] = std::max(1, static_cast<int>(std::ceil(box.sizes()[c] / cell)));
  std::vector<int> column((cells + Eigen::Vector3i::Ones()).prod(), -1);
  int used = 0;
  std::vector<Eigen::Triplet<double>> entries;
  for (int32_t i = 0; i < m.num_nodes; ++i) {
    const Vec3 u = (m.rest_positions[i] - box.min()) / cell;
    int base[3];
    double frac[3];
    for (int c = 0; c < 3; ++c) {
      base[c] = std::min(static_cast<int>(u[c]), cells[c] - 1);
      frac[c] = u[c] - base[c];
    }
    for (int corner = 0; corner < 8; ++corner) {
      double w = 1.0;
      int g[3];
      for (int c = 0; c < 3; ++c) {
        const int bit = (corner >> c) & 1;
        g[c] = base[c] + bit;
        w *= bit ? frac[c] : 1.0 - frac[c];
      }
      if (w <= 0.0) continue;
      int& col = column[(g[2] * (cells[1] + 1) + g[1]) * (cells[0] + 1) + g[0]];
      if (col < 0) col = used++;
      for (int c = 0; c < 3; ++c) entries.emplace_back(3 * i + c, 3 * col + c, w);
    }
  }
  Eigen::SparseMatrix<double> p(3 * m.num_nodes, 3 * used);
  p.setFromTriplets(entries.begin(), entries.end());
  return p;
}

}  // namespace

int Preconditioners(int max_tets) {
  constexpr int kSamples = 12;
  std::printf(
      "# CG preconditioners on one tick's system (refined 10 cm box, organ, BDF1, 1 ms, "
      "mid-drop),\n# from the integrator's warm start to its tolerance (5e-3 |b|). products = "
      "fine-level Jacobian\n# products per iteration (the CG's own and the smoother's). "
      "Two-level: trilinear coarse grid\n# of 4 mean edge lengths, solved exactly; its setup "
      "(probing, factorising) is not timed.\n");
  std::printf("%8s %-34s %6s %9s %10s %12s\n", "tets", "preconditioner", "iter", "products",
              "it x prod", "solve_ms");
  std::printf("# iter = mean CG iterations per tick; solve_ms = mean CPU time of the solve\n");
  for (int target : {5000, 20000, 100000}) {
    if (target > max_tets) break;
    const TetMesh mesh = BoxWithTets(target);
    Parameters p = FindPreset("organ")->params;
    p.sleep_time = 0.0;
    p.implicit_order = 1.0;
    auto obj_or = SimObject::Create(mesh, p, Integrator::kImplicitEuler);
    if (!obj_or.ok()) return 2;
    SimObject& obj = **obj_or;
    obj.Translate(Vec3(0, 0.005, 0));
    const Model& m = obj.model();
    const int32_t n = m.num_nodes;
    double edge_sum = 0.0;
    for (double l : m.edge_rest_length) edge_sum += l;
    const Eigen::SparseMatrix<double> P = TrilinearProlongation(m, 4.0 * edge_sum / m.edges.size());
    std::printf(
        "# %zu tets, %d nodes; coarse grid %ld unknowns; %d ticks (every 5th of the "
        "fall, impact and rebound)\n",
        m.tets.size(), n, static_cast<long>(P.cols()), kSamples);
    constexpr int kRows = 4;
    const char* names[kRows] = {"Jacobi (the integrator's)", "3x3 block Jacobi",
                                "two-level additive, exact coarse",
                                "two-level V(1,1), exact coarse"};
    const int products[kRows] = {1, 1, 1, 3};
    int iterations[kRows] = {};
    double seconds[kRows] = {};
    for (int sample = 0; sample < kSamples; ++sample) {
      for (int k = 0; k < 5; ++k) obj.Step(1e-3);
      PrecondSystem sys = MakePrecondSystem(obj, p, 1e-3);
      const std::vector<Eigen::Matrix3d> block_inv = BlockJacobi(sys);
      // The Galerkin coarse operator P^T A P, by probing.
      Eigen::MatrixXd ap(3 * n, P.cols());
      Eigen::VectorXd col, acol;
      for (int k = 0; k < P.cols(); ++k) {
        col = P.col(k);
        sys.Apply(col, acol);
        ap.col(k) = acol;
      }
      const Eigen::SparseMatrix<double> coarse = (P.transpose() * ap).sparseView();
      Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> coarse_solver(coarse);
      if (coarse_solver.info() != Eigen::Success) return 3;
      constexpr double kOmega = 0.6;  // damping of the Jacobi smoother
      Eigen::VectorXd t1, t2;
      const std::function<void(const Eigen::VectorXd&, Eigen::VectorXd&)> apply[kRows] = {
          [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) { z = sys.inv_diag.cwiseProduct(r); },
          [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
            z.resize(r.size());
            for (int32_t i = 0; i < n; ++i)
              z.segment<3>(3 * i) = block_inv[i] * r.segment<3>(3 * i);
          },
          [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
            z = sys.inv_diag.cwiseProduct(r) + P * coarse_solver.solve(P.transpose() * r);
          },
          [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
            z = kOmega * sys.inv_diag.cwiseProduct(r);
            sys.Apply(z, t1);
            z += P * coarse_solver.solve(P.transpose() * (r - t1));
            sys.Apply(z, t2);
            z += kOmega * sys.inv_diag.cwiseProduct(r - t2);
          },
      };
      for (int row = 0; row < kRows; ++row) {
        const double c0 = CpuSeconds();
        const int it = Pcg(sys, p.cg_tolerance, apply[row]);
        seconds[row] += CpuSeconds() - c0;
        if (it < 0) return 4;
        iterations[row] += it;
      }
    }
    for (int row = 0; row < kRows; ++row) {
      const double it = double(iterations[row]) / kSamples;
      std::printf("%8zu %-34s %6.2f %9d %10.2f %12.2f\n", m.tets.size(), names[row], it,
                  products[row], it * products[row], 1e3 * seconds[row] / kSamples);
    }
  }
  return 0;
}

}  // namespace sim_bench
