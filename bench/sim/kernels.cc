// sim_bench kernels [tets]: time of each force kernel and Jacobian product.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "bench.h"
#include "sim/forces.h"

namespace sim_bench {

// Where the time of one tick goes: each force kernel and one Jacobian product, median of many.
int Kernels(int target, const std::string& sample) {
  TetMesh mesh;
  if (sample.empty()) {
    mesh = BoxWithTets(target);
  } else {
    const int targets[] = {target};
    auto meshes = MeshSample(sample, targets);
    if (!meshes.ok()) {
      std::fprintf(stderr, "sim_bench kernels: %s\n", meshes.error().message.c_str());
      return 1;
    }
    mesh = std::move(meshes->meshes[0]);
  }
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
  double spread = 0.0;  // how far apart an edge's two nodes are in the node order
  for (const auto& e : m.edges) spread += std::abs(e[0] - e[1]);
  std::printf(
      "# kernels: %s, %zu tets, %d nodes, %zu edges, %zu faces, mean |i - j| over the edges %.0f; "
      "median us of one call\n",
      sample.empty() ? "box" : sample.c_str(), m.tets.size(), m.num_nodes, m.edges.size(),
      m.faces.size(), spread / std::max<size_t>(m.edges.size(), 1));
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
  const double jac_a = time_us([&] { internal::ApplyAssembled(m, all, s, s.v, s.v, s.cg_q); });
  std::printf("%-28s %10.1f\n", "Jacobian product (assembled)", jac_a);
  // The warm start's product K a + D b (a != b): element by element, and from the blocks.
  const double ws = time_us([&] { internal::ApplyJacobian(m, all, s, s.v, s.dv, s.cg_q); });
  std::printf("%-28s %10.1f\n", "warm start (elements)", ws);
  const double ws_a = time_us([&] { internal::ApplyAssembled(m, all, s, s.v, s.dv, s.cg_q); });
  std::printf("%-28s %10.1f\n", "warm start (assembled)", ws_a);
  return 0;
}

}  // namespace sim_bench
