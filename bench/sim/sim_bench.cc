// sim_bench: measured, not asserted.
//   sim_bench speed [max_tets]       median wall time of one 1 ms tick vs mesh size
//   sim_bench precision [svg_path]   work-precision: CPU time per simulated second vs error
//   sim_bench bullet                 btSoftBody on the same tets and dt, vs the same reference
//   sim_bench kernels [tets]         time of each force kernel and Jacobian product
//   sim_bench cg                     implicit integrator: CG tolerance vs error and cost
//   sim_bench precond [max_tets]     CG preconditioners on one tick's system
// One thread throughout (the library has none).
#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <functional>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "sim/forces.h"
#include "sim/integrators.h"
#include "sim/primitives.h"
#include "sim/sim.h"

#ifdef RHEO_HAVE_BULLET
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>
#endif

namespace {

using rheo::TetMesh;
using rheo::Vec3;
using namespace rheo::sim;

double CpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}
double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
}

// A 10 cm x 6 cm x 8 cm box with about `tets` tetrahedra.
TetMesh BoxWithTets(int tets) {
  const double cells = tets / 6.0;
  const double s = std::cbrt(cells / (1.0 * 0.6 * 0.8));
  const int nx = std::max(1, static_cast<int>(std::lround(s)));
  const int ny = std::max(1, static_cast<int>(std::lround(0.6 * s)));
  const int nz = std::max(1, static_cast<int>(std::lround(0.8 * s)));
  return *MakeBoxTetMesh(nx, ny, nz, Vec3(0.1, 0.06, 0.08));
}

// A box of the 10:6:8 shape with about `tets` tetrahedra in cells of edge `cell` [m]: the object
// grows with the count, the element size (and so the stiffness per mass) stays.
TetMesh BoxWithCell(int tets, double cell) {
  const double s = std::cbrt(tets / 6.0 / (1.0 * 0.6 * 0.8));
  const int nx = std::max(1, static_cast<int>(std::lround(s)));
  const int ny = std::max(1, static_cast<int>(std::lround(0.6 * s)));
  const int nz = std::max(1, static_cast<int>(std::lround(0.8 * s)));
  return *MakeBoxTetMesh(nx, ny, nz, cell * Vec3(nx, ny, nz));
}

// An integrator as the benches name it: the scheme plus the implicit-damping switch.
struct Method {
  const char* name;
  Integrator integrator;
  double implicit_damping;
  double implicit_order;
  void Apply(Parameters& p) const {
    p.implicit_damping = implicit_damping;
    p.implicit_order = implicit_order;
  }
};
constexpr Method kMethods[] = {
    {"symplectic-euler", Integrator::kSymplecticEuler, 0.0, 2.0},
    {"symplectic+impl.damping", Integrator::kSymplecticEuler, 1.0, 2.0},
    {"implicit BDF1 (order 1)", Integrator::kImplicitEuler, 0.0, 1.0},
    {"implicit BDF2 (default)", Integrator::kImplicitEuler, 0.0, 2.0},
};

// ---------------------------------------------------------------------------------------------
// One row per method: the median tick of `mesh` settling on the floor.
int SpeedRows(const TetMesh& mesh, std::span<const Method> methods) {
  const size_t target = mesh.tets.size();
  {
    for (const Method& method : methods) {
      Parameters p = FindPreset("organ")->params;
      p.sleep_time = 0.0;
      method.Apply(p);
      auto obj = SimObject::Create(mesh, p, method.integrator);
      if (!obj.ok()) return 2;
      SimObject& s = **obj;
      s.Translate(Vec3(0, 0.005, 0));
      const int ticks = target >= 60000 ? 25 : target >= 15000 ? 40 : 200;
      for (int k = 0; k < 5; ++k) s.Step(1e-3);
      if (method.integrator == Integrator::kImplicitEuler)
        std::printf("# shape springs at 1 ms: %s (%d tets implicit)\n",
                    s.ShapeSpringsTreatment(1e-3) == ShapeTreatment::kExplicit ? "explicit"
                    : s.ShapeSpringsTreatment(1e-3) == ShapeTreatment::kSplit  ? "split"
                                                                               : "implicit",
                    s.shape_implicit_tets());
      // Wall time, and the thread's CPU time (which leaves out the time this thread waited
      // while other processes ran on its core).
      std::vector<double> us, cpu_us;
      int64_t sub = 0, it = 0;
      for (int k = 0; k < ticks; ++k) {
        const auto t0 = std::chrono::steady_clock::now();
        const double c0 = CpuSeconds();
        const StepResult r = s.Step(1e-3);
        cpu_us.push_back(1e6 * (CpuSeconds() - c0));
        us.push_back(
            std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0)
                .count());
        sub += r.substeps;
        it += r.solver_iterations;
      }
      const double med = Median(us);
      std::printf("%8zu %7d %8zu %-24s %5.1f %9.1f %9.1f %9.1f %10.1f %9.1f\n", mesh.tets.size(),
                  s.model().num_nodes, s.model().edges.size(), method.name, double(sub) / ticks,
                  med, Percentile(us, 0.9), med / (mesh.tets.size() / 1e3), double(it) / ticks,
                  Median(cpu_us));
    }
  }
  return 0;
}

int Speed(int max_tets) {
  std::printf("# speed: one 1 ms tick, object settling on the floor (awake), one core\n");
  const char* header = "%8s %7s %8s %-24s %5s %9s %9s %9s %10s %9s\n";
  std::printf(header, "tets", "nodes", "edges", "integrator", "subst", "median_us", "p90_us",
              "us/ktet", "CG it/tick", "cpu_us");
  // The same 10 cm box, refined: the elements get smaller and stiffer for their mass.
  for (int target : {100, 1000, 5000, 20000, 100000}) {
    if (target > max_tets) break;
    if (int rc = SpeedRows(BoxWithTets(target), kMethods); rc != 0) return rc;
  }
  // The 5k box's cells (10 cm / 12 = 8.3 mm), the box growing: the cost of the code per
  // element, with the conditioning of the system held.
  const double cell = 0.1 / 12.0;
  std::printf("# constant resolution: cells of %.1f mm, the box grows with the count\n",
              cell * 1e3);
  std::printf(header, "tets", "nodes", "edges", "integrator", "subst", "median_us", "p90_us",
              "us/ktet", "CG it/tick", "cpu_us");
  const std::span<const Method> implicit(kMethods + 2, 2);
  for (int target : {1000, 5000, 20000, 100000}) {
    if (target > max_tets) break;
    const TetMesh mesh = BoxWithCell(target, cell);
    Vec3 lo = mesh.positions[0], hi = lo;
    for (const Vec3& x : mesh.positions) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
    const Vec3 size = hi - lo;
    std::printf("# %.0f x %.0f x %.0f cm\n", size.x() * 100, size.y() * 100, size.z() * 100);
    if (int rc = SpeedRows(mesh, implicit); rc != 0) return rc;
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------
// Where the time of one tick goes: each force kernel and one Jacobian product, median of many.
int Kernels(int target) {
  const TetMesh mesh = BoxWithTets(target);
  Parameters p = FindPreset("organ")->params;
  Model m = *BuildModel(mesh, p.density);
  State s;
  InitState(m, p.voigt_ratio, s);
  for (Vec3& x : s.x) x *= 1.01;  // a little stretch so every term is loaded
  const internal::ActiveTerms all = internal::DecideTerms(m, p);
  auto time_us = [](auto&& fn) {
    std::vector<double> us;
    for (int k = 0; k < 301; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      fn();
      us.push_back(
          std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    }
    return Median(us);
  };
  auto only = [&](bool internal::ActiveTerms::*term) {
    internal::ActiveTerms t{};
    t.*term = true;
    return t;
  };
  std::printf("# kernels: %zu tets, %d nodes, %zu edges, %zu faces; median us of one call\n",
              m.tets.size(), m.num_nodes, m.edges.size(), m.faces.size());
  std::printf("%-28s %10s %10s\n", "kernel", "forces", "linearised");
  const std::pair<const char*, bool internal::ActiveTerms::*> terms[] = {
      {"edges (eq. 2-3)", &internal::ActiveTerms::edges},
      {"global volume (eq. 4)", &internal::ActiveTerms::global_volume},
      {"area (eq. 5)", &internal::ActiveTerms::area},
      {"tet volume (eq. 6)", &internal::ActiveTerms::tet_volume},
  };
  for (const auto& [name, term] : terms) {
    const internal::ActiveTerms t = only(term);
    const double f = time_us([&] { internal::ComputeForces(m, p, t, s, 1e-3, 1e-3, {}); });
    const double l = time_us([&] { internal::ComputeForces(m, p, t, s, 1e-3, 1e-3, t); });
    std::printf("%-28s %10.1f %10.1f\n", name, f, l);
  }
  const double all_f = time_us([&] { internal::ComputeForces(m, p, all, s, 1e-3, 1e-3, {}); });
  const double all_l = time_us([&] { internal::ComputeForces(m, p, all, s, 1e-3, 1e-3, all); });
  std::printf("%-28s %10.1f %10.1f\n", "all terms", all_f, all_l);
  const double jac = time_us([&] { internal::ApplyJacobian(m, all, s, s.v, s.v, s.cg_q); });
  std::printf("%-28s %10.1f\n", "Jacobian product (all)", jac);
  const double jac_e = time_us([&] {
    internal::ApplyJacobian(m, only(&internal::ActiveTerms::edges), s, s.v, s.v, s.cg_q);
  });
  std::printf("%-28s %10.1f\n", "Jacobian product (edges)", jac_e);
  // The same product with the shape springs' blocks moved onto the edges (what the implicit step
  // does when they are in the system), and the cost of moving them, once per substep.
  const double assemble = time_us([&] { internal::AssembleEdgeBlocks(m, all, s); });
  std::printf("%-28s %10.1f\n", "edge blocks assembled (all)", assemble);
  const double jac_a = time_us([&] { internal::ApplyAssembled(m, all, s, s.v, s.cg_q); });
  std::printf("%-28s %10.1f\n", "Jacobian product (assembled)", jac_a);
  return 0;
}

// ---------------------------------------------------------------------------------------------
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

// ---------------------------------------------------------------------------------------------
// Scenes for work-precision: the same mesh and parameters, 0.5 s.
struct Scene {
  const char* name;
  TetMesh mesh;
  Parameters params;
  double drop = 0.0;         // lowest point above the floor at t = 0 [m]
  double press_force = 0.0;  // total downward force on the top nodes, ramped over 0.1 s [N]
};

std::vector<Scene> Scenes() {
  std::vector<Scene> out;
  const TetMesh blob = *MakeEllipsoidTetMesh(4, Vec3(0.05, 0.035, 0.04), Vec3(0, 0.035, 0));
  Parameters p = FindPreset("organ")->params;
  p.sleep_time = 0.0;
  out.push_back({"drop", blob, p, 0.05, 0.0});
  out.push_back({"press", blob, p, 0.0, 3.0});
  return out;
}

struct RunResult {
  std::vector<Vec3> x;
  double cpu = 0.0;  // [s]
  int64_t substeps = 0;
  int64_t restores = 0;
  int64_t iterations = 0;  // CG iterations
};

RunResult RunScene(const Scene& sc, const Method& method, double dt, double t_end,
                   double cg_tol = -1.0) {
  const Integrator integ = method.integrator;
  Parameters p = sc.params;
  method.Apply(p);
  if (cg_tol > 0) p.cg_tolerance = cg_tol;
  p.max_substeps = 10000;
  auto obj = SimObject::Create(sc.mesh, p, integ);
  SimObject& s = **obj;
  s.Translate(Vec3(0, sc.drop, 0));
  std::vector<int32_t> top;
  double y_max = -1e30;
  for (const Vec3& x : s.positions()) y_max = std::max(y_max, x.y());
  for (int32_t i = 0; i < s.model().num_nodes; ++i) {
    if (s.positions()[i].y() > y_max - 0.01) top.push_back(i);
  }
  RunResult r;
  const int64_t ticks = std::llround(t_end / dt);
  const double t0 = CpuSeconds();
  for (int64_t k = 0; k < ticks; ++k) {
    if (sc.press_force > 0) {
      const double ramp = std::min(1.0, (k * dt) / 0.1);
      for (int32_t i : top) s.SetExternalForce(i, Vec3(0, -ramp * sc.press_force / top.size(), 0));
    }
    const StepResult st = s.Step(dt);
    r.substeps += st.substeps;
    r.restores += st.restored;
    r.iterations += st.solver_iterations;
  }
  r.cpu = CpuSeconds() - t0;
  r.x.assign(s.positions().begin(), s.positions().end());
  return r;
}

double RmsError(const std::vector<Vec3>& a, const std::vector<Vec3>& b, double size) {
  double sum = 0.0;
  for (size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]).squaredNorm();
  return std::sqrt(sum / a.size()) / size;
}

struct Point {
  std::string scene, integrator;
  double dt, error, cpu_per_s;
};

void WriteSvg(const std::vector<Point>& pts, const std::string& path) {
  // Log-log: x = error, y = CPU seconds per simulated second.
  const double W = 720, H = 480, L = 80, R = 200, T = 30, B = 60;
  double ex0 = 1e-6, ex1 = 1.0, ey0 = 1e-3, ey1 = 100.0;
  auto X = [&](double e) {
    return L + (std::log10(std::max(e, ex0)) - std::log10(ex0)) /
                   (std::log10(ex1) - std::log10(ex0)) * (W - L - R);
  };
  auto Y = [&](double c) {
    return H - B -
           (std::log10(std::max(c, ey0)) - std::log10(ey0)) / (std::log10(ey1) - std::log10(ey0)) *
               (H - T - B);
  };
  std::ofstream f(path);
  f << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H
    << "' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' "
       "fill='white'/>\n";
  for (int d = -6; d <= 0; ++d) {
    const double x = X(std::pow(10.0, d));
    f << "<line x1='" << x << "' y1='" << T << "' x2='" << x << "' y2='" << H - B
      << "' stroke='#ddd'/><text x='" << x - 12 << "' y='" << H - B + 18 << "'>1e" << d
      << "</text>\n";
  }
  for (int d = -3; d <= 2; ++d) {
    const double y = Y(std::pow(10.0, d));
    f << "<line x1='" << L << "' y1='" << y << "' x2='" << W - R << "' y2='" << y
      << "' stroke='#ddd'/><text x='" << L - 40 << "' y='" << y + 4 << "'>1e" << d << "</text>\n";
  }
  // Real-time budget: 1 s of CPU per simulated second; target error 1 %.
  f << "<line x1='" << L << "' y1='" << Y(1.0) << "' x2='" << W - R << "' y2='" << Y(1.0)
    << "' stroke='red' stroke-dasharray='4'/>\n";
  f << "<line x1='" << X(0.01) << "' y1='" << T << "' x2='" << X(0.01) << "' y2='" << H - B
    << "' stroke='red' stroke-dasharray='4'/>\n";
  f << "<text x='" << (L + W - R) / 2 - 100 << "' y='" << H - 20
    << "'>error: RMS node distance to reference at 0.5 s / size</text>\n";
  f << "<text x='15' y='" << T + 10 << "'>CPU s per simulated s</text>\n";
  const char* colors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};
  std::vector<std::string> series;
  for (const Point& p : pts) {
    const std::string key = p.scene + " " + p.integrator;
    if (std::find(series.begin(), series.end(), key) == series.end()) series.push_back(key);
  }
  for (size_t si = 0; si < series.size(); ++si) {
    std::string poly;
    for (const Point& p : pts) {
      if (p.scene + " " + p.integrator != series[si]) continue;
      poly += std::to_string(X(p.error)) + "," + std::to_string(Y(p.cpu_per_s)) + " ";
      f << "<circle cx='" << X(p.error) << "' cy='" << Y(p.cpu_per_s) << "' r='3' fill='"
        << colors[si % 6] << "'/>\n";
    }
    f << "<polyline points='" << poly << "' fill='none' stroke='" << colors[si % 6] << "'/>\n";
    f << "<text x='" << W - R + 10 << "' y='" << T + 20 + 18 * si << "' fill='" << colors[si % 6]
      << "'>" << series[si] << "</text>\n";
  }
  f << "</svg>\n";
}

int Precision(const std::string& svg) {
  const double t_end = 0.5;
  std::vector<Point> pts;
  std::printf(
      "# work-precision: error = RMS(x - x_ref)/size at t = 0.5 s; reference = "
      "symplectic Euler, tick 1e-5 s\n");
  std::printf("%-6s %-24s %9s %9s %12s %10s %8s\n", "scene", "integrator", "dt_s", "substep_s",
              "error", "cpu_s/s", "restores");
  for (const Scene& sc : Scenes()) {
    const RunResult ref = RunScene(sc, kMethods[0], 1e-5, t_end);
    const double size =
        (**SimObject::Create(sc.mesh, sc.params, Integrator::kSymplecticEuler)).model().size;
    for (const Method& method : kMethods) {
      for (double dt : {4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4}) {
        const RunResult r = RunScene(sc, method, dt, t_end);
        const double err = RmsError(r.x, ref.x, size);
        const double ticks = std::llround(t_end / dt);
        pts.push_back({sc.name, method.name, dt, err, r.cpu / t_end});
        std::printf("%-6s %-24s %9.2e %9.2e %12.3e %10.4f %8lld\n", sc.name, method.name, dt,
                    dt * ticks / r.substeps, err, r.cpu / t_end,
                    static_cast<long long>(r.restores));
      }
    }
  }
  // The goal: error <= 1 % within the real-time budget (at most 1 CPU second per simulated second;
  // a tick of 1 ms split into 1 ms / dt substeps gives the same run).
  std::printf(
      "# within the real-time budget (cpu_s/s <= 1): the smallest error of each integrator\n");
  for (const Scene& sc : Scenes()) {
    for (const Method& method : kMethods) {
      const Point* best = nullptr;
      for (const Point& p : pts) {
        if (p.scene == sc.name && p.integrator == method.name && p.cpu_per_s <= 1.0 &&
            (best == nullptr || p.error < best->error))
          best = &p;
      }
      if (best != nullptr) {
        std::printf("#   %-6s %-24s dt %.2e: error %.3e at %.3f cpu_s/s%s\n", sc.name, method.name,
                    best->dt, best->error, best->cpu_per_s, best->error <= 0.01 ? " (<= 1 %)" : "");
      } else {
        std::printf("#   %-6s %-24s none within the budget\n", sc.name, method.name);
      }
    }
  }
  if (!svg.empty()) {
    WriteSvg(pts, svg);
    std::printf("# plot written to %s\n", svg.c_str());
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------
// What a parameter change costs the thread that steps the object: the tick that applies it with
// SetParameters(params) (everything on that thread, as `rheo simulate` does) and with a set
// SimObject::Prepare made on another thread (as rheod does), next to a normal tick. Medians.
int ParameterChange() {
  std::printf("# parameter change (k_v), organ, implicit BDF2, 1 ms ticks; median us of 9\n");
  std::printf("%8s %12s %18s %16s %18s\n", "tets", "normal tick", "tick + direct set",
              "tick + prepared", "Prepare (off loop)");
  for (int target : {5000, 20000}) {
    const TetMesh mesh = BoxWithTets(target);
    Parameters p = FindPreset("organ")->params;
    auto obj = SimObject::Create(mesh, p, Integrator::kImplicitEuler);
    if (!obj.ok()) return 2;
    SimObject& s = **obj;
    for (int k = 0; k < 50; ++k) s.Step(1e-3);
    std::vector<double> normal, direct, prepared, prepare;
    auto us_since = [](auto t0) {
      return std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0)
          .count();
    };
    for (int r = 0; r < 9; ++r) {
      p.k_v = 150.0 + r;
      auto t0 = std::chrono::steady_clock::now();
      (void)s.SetParameters(p);
      s.Step(1e-3);
      direct.push_back(us_since(t0));
      p.k_v = 160.0 + r;
      t0 = std::chrono::steady_clock::now();
      auto pr = s.Prepare(p, Integrator::kImplicitEuler, 1e-3);
      prepare.push_back(us_since(t0));
      if (!pr.ok()) return 2;
      t0 = std::chrono::steady_clock::now();
      (void)s.SetParameters(*pr);
      s.Step(1e-3);
      prepared.push_back(us_since(t0));
      t0 = std::chrono::steady_clock::now();
      s.Step(1e-3);
      normal.push_back(us_since(t0));
    }
    std::printf("%8zu %12.0f %18.0f %16.0f %18.0f\n", mesh.tets.size(), Median(normal),
                Median(direct), Median(prepared), Median(prepare));
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------
// The implicit integrator's CG tolerance against the error it costs (the default's justification).
int CgSweep() {
  const double t_end = 0.5, dt = 1e-3;
  std::printf("# implicit (BDF2), tick 1 ms: CG tolerance vs error (as in precision) and cost\n");
  std::printf("%-6s %10s %12s %10s %10s\n", "scene", "cg_tol", "error", "cpu_s/s", "CG it/tick");
  for (const Scene& sc : Scenes()) {
    const RunResult ref = RunScene(sc, kMethods[0], 1e-5, t_end);
    const double size =
        (**SimObject::Create(sc.mesh, sc.params, Integrator::kSymplecticEuler)).model().size;
    for (double tol : {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 1e-4, 1e-5, 1e-6}) {
      const RunResult r = RunScene(sc, kMethods[3], dt, t_end, tol);
      std::printf("%-6s %10.0e %12.3e %10.4f %10.1f\n", sc.name, tol, RmsError(r.x, ref.x, size),
                  r.cpu / t_end, double(r.iterations) / std::llround(t_end / dt));
    }
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------
#ifdef RHEO_HAVE_BULLET
// btSoftBody from the same tetrahedra (TetGen text, as Bullet reads it), same dt, same floor.
struct BulletRun {
  std::vector<Vec3> x;
  double cpu = 0.0;
  std::vector<double> tick_us;
};

BulletRun RunBullet(const Scene& sc, double dt, double t_end, double stiffness) {
  std::ostringstream node, ele;
  node << sc.mesh.positions.size() << " 3 0 0\n";
  for (size_t i = 0; i < sc.mesh.positions.size(); ++i) {
    const Vec3& p = sc.mesh.positions[i];
    node << i << " " << p.x() << " " << p.y() + sc.drop << " " << p.z() << "\n";
  }
  ele << sc.mesh.tets.size() << " 4 0\n";
  for (size_t i = 0; i < sc.mesh.tets.size(); ++i) {
    const auto& t = sc.mesh.tets[i];
    ele << i << " " << t[0] << " " << t[1] << " " << t[2] << " " << t[3] << "\n";
  }
  btSoftBodyRigidBodyCollisionConfiguration config;
  btCollisionDispatcher dispatcher(&config);
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btSoftRigidDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
  world.setGravity(btVector3(0, -sc.params.gravity, 0));
  btSoftBodyWorldInfo& info = world.getWorldInfo();
  info.m_gravity = btVector3(0, -sc.params.gravity, 0);
  info.m_broadphase = &broadphase;
  info.m_dispatcher = &dispatcher;
  info.air_density = 0;
  info.water_density = 0;
  info.m_sparsesdf.Initialize();
  // A thick box rather than btStaticPlaneShape: soft-rigid SDF contact needs a convex shape.
  btBoxShape plane(btVector3(2.0, 0.5, 2.0));
  plane.setMargin(0.001);
  btTransform ground_pose;
  ground_pose.setIdentity();
  ground_pose.setOrigin(btVector3(0, -0.5, 0));
  btDefaultMotionState ms(ground_pose);
  btRigidBody ground(btRigidBody::btRigidBodyConstructionInfo(0, &ms, &plane));
  ground.setFriction(sc.params.friction);
  world.addRigidBody(&ground);
  const std::string ele_s = ele.str(), node_s = node.str();
  btSoftBody* sb = btSoftBodyHelpers::CreateFromTetGenData(info, ele_s.c_str(), nullptr,
                                                           node_s.c_str(), false, true, true);
  double mass = 0.0;
  for (const auto& t : sc.mesh.tets) {
    const Vec3& p0 = sc.mesh.positions[t[0]];
    mass += std::abs((sc.mesh.positions[t[1]] - p0)
                         .dot((sc.mesh.positions[t[2]] - p0).cross(sc.mesh.positions[t[3]] - p0))) /
            6.0 * sc.params.density;
  }
  sb->m_materials[0]->m_kLST = stiffness;
  sb->m_cfg.piterations = 4;
  sb->m_cfg.kDF = sc.params.friction;
  sb->m_cfg.kDP = 0.01;
  sb->m_cfg.collisions = btSoftBody::fCollision::SDF_RS;
  sb->getCollisionShape()->setMargin(0.002);  // default 0.25 m is larger than the object
  sb->setTotalMass(mass, false);              // no faces: by node, not by area
  sb->generateBendingConstraints(2, sb->m_materials[0]);
  world.addSoftBody(sb);
  std::vector<int> top;
  double y_max = -1e30;
  for (int i = 0; i < sb->m_nodes.size(); ++i)
    y_max = std::max<double>(y_max, sb->m_nodes[i].m_x.y());
  for (int i = 0; i < sb->m_nodes.size(); ++i) {
    if (sb->m_nodes[i].m_x.y() > y_max - 0.01) top.push_back(i);
  }
  BulletRun r;
  const int64_t ticks = std::llround(t_end / dt);
  const double c0 = CpuSeconds();
  for (int64_t k = 0; k < ticks; ++k) {
    if (sc.press_force > 0) {
      const double ramp = std::min(1.0, (k * dt) / 0.1);
      for (int i : top) sb->addForce(btVector3(0, -ramp * sc.press_force / top.size(), 0), i);
    }
    const auto t0 = std::chrono::steady_clock::now();
    world.stepSimulation(dt, 0);
    r.tick_us.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  r.cpu = CpuSeconds() - c0;
  for (int i = 0; i < sb->m_nodes.size(); ++i) {
    const btVector3& p = sb->m_nodes[i].m_x;
    r.x.emplace_back(p.x(), p.y(), p.z());
  }
  world.removeSoftBody(sb);
  world.removeRigidBody(&ground);
  delete sb;
  return r;
}

int Bullet() {
  const double t_end = 0.5, dt = 1e-3;
  std::printf(
      "# Bullet btSoftBody (tetra links, same tets, same dt 1 ms, same floor) vs rheo_sim;"
      " error vs the rheo_sim reference (tick 1e-5 s) at 0.5 s / size.\n"
      "# Bullet's error includes the difference of material models, not only "
      "integration error.\n");
  std::printf("%-6s %6s %-26s %10s %12s %10s\n", "scene", "tets", "engine", "median_us", "error",
              "ratio");
  for (const Scene& sc : Scenes()) {
    const RunResult ref = RunScene(sc, kMethods[0], 1e-5, t_end);
    const double size =
        (**SimObject::Create(sc.mesh, sc.params, Integrator::kSymplecticEuler)).model().size;
    double rheo_med = 0.0;
    for (const Method& method : kMethods) {
      // Median tick time measured separately from the error run.
      Parameters p = sc.params;
      method.Apply(p);
      auto obj = SimObject::Create(sc.mesh, p, method.integrator);
      SimObject& s = **obj;
      s.Translate(Vec3(0, sc.drop, 0));
      std::vector<double> us;
      for (int k = 0; k < 500; ++k) {
        const auto t0 = std::chrono::steady_clock::now();
        s.Step(dt);
        us.push_back(
            std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0)
                .count());
      }
      const RunResult r = RunScene(sc, method, dt, t_end);
      const double med = Median(us);
      if (&method == &kMethods[0]) rheo_med = med;
      std::printf("%-6s %6zu %-26s %10.1f %12.3e %10.2f\n", sc.name, sc.mesh.tets.size(),
                  method.name, med, RmsError(r.x, ref.x, size), med / rheo_med);
    }
    for (double kl : {0.1, 0.5, 1.0}) {
      const BulletRun b = RunBullet(sc, dt, t_end, kl);
      char name[64];
      std::snprintf(name, sizeof name, "bullet kLST=%.1f", kl);
      std::printf("%-6s %6zu %-26s %10.1f %12.3e %10.2f\n", sc.name, sc.mesh.tets.size(), name,
                  Median(b.tick_us), RmsError(b.x, ref.x, size), Median(b.tick_us) / rheo_med);
    }
  }
  std::printf("# ratio = median tick time / rheo_sim symplectic-euler median tick time\n");
  return 0;
}
#endif

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "speed";
  if (mode == "speed") return Speed(argc > 2 ? std::atoi(argv[2]) : 100000);
  if (mode == "cg") return CgSweep();
  if (mode == "params") return ParameterChange();
  if (mode == "kernels") return Kernels(argc > 2 ? std::atoi(argv[2]) : 5000);
  if (mode == "precond") return Preconditioners(argc > 2 ? std::atoi(argv[2]) : 100000);
  if (mode == "precision") return Precision(argc > 2 ? argv[2] : "sim_work_precision.svg");
#ifdef RHEO_HAVE_BULLET
  if (mode == "bullet") return Bullet();
  if (mode == "bullet-check") {
    // Where Bullet's object ends up after a short drop (floor contact sanity check).
    const Scene sc = Scenes()[0];
    for (double t : {0.05, 0.1, 0.3}) {
      const BulletRun b = RunBullet(sc, 1e-3, t, 0.5);
      double lo = 1e30, hi = -1e30;
      for (const Vec3& x : b.x) {
        lo = std::min(lo, x.y());
        hi = std::max(hi, x.y());
      }
      std::printf("t=%.2f lowest %.4f highest %.4f\n", t, lo, hi);
    }
    return 0;
  }
#else
  if (mode == "bullet") {
    std::fprintf(stderr, "sim_bench: built without Bullet (libbullet-dev)\n");
    return 1;
  }
#endif
  std::fprintf(
      stderr,
      "usage: sim_bench speed [max_tets] | kernels [tets] | precond [max_tets] | precision [svg] | "
      "cg | params | bullet\n");
  return 1;
}
