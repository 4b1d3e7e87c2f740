// Vertex smoothing of the tetrahedra: a vertex of a poor tetrahedron moves toward the centroid of
// its neighbours when that raises the smallest dihedral angle among its tetrahedra ("smart"
// Laplacian smoothing: a move that would make any of them worse is not taken, so nothing is ever
// inverted). Surface vertices stay on the inflated surface; contour vertices do not move.
#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>

#include "mesh/internal.h"

namespace rheo::mesh::internal {
namespace {

// Largest cosine of the six dihedral angles of a tetrahedron: 1 is flat, 1/3 the regular one.
// A tetrahedron of non-positive volume scores 2, worse than any valid one.
double MaxDihedralCos(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  if ((p1 - p0).dot((p2 - p0).cross(p3 - p0)) <= 0) return 2.0;
  Vec3 n[4] = {(p2 - p1).cross(p3 - p1), (p3 - p0).cross(p2 - p0), (p1 - p0).cross(p3 - p0),
               (p2 - p0).cross(p1 - p0)};
  for (auto& v : n) v.normalize();
  double worst = -1;
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) worst = std::max(worst, -n[a].dot(n[b]));
  return worst;
}

}  // namespace

void ImproveTets(TetMesh& mesh, double threshold_deg, int sweeps,
                 const std::function<double(const Vec2&)>& height, const CancelToken& cancel) {
  const size_t nv = mesh.positions.size();
  // 0 interior (moves freely), 1 on the top or bottom surface (moves on it), 2 fixed (contour).
  std::vector<uint8_t> kind(nv, 0);
  for (const auto& f : mesh.surface)
    for (int32_t v : f) kind[v] = height && mesh.positions[v].z() != 0.0 ? 1 : 2;
  // Vertex -> tetrahedra, CSR.
  std::vector<int32_t> start(nv + 1, 0), items(4 * mesh.tets.size());
  for (const auto& t : mesh.tets)
    for (int32_t v : t) ++start[v + 1];
  for (size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<int32_t> fill(start.begin(), start.end() - 1);
  for (size_t k = 0; k < mesh.tets.size(); ++k)
    for (int32_t v : mesh.tets[k]) items[fill[v]++] = static_cast<int32_t>(k);

  auto& P = mesh.positions;
  auto tet_cos = [&](int32_t k) {
    const auto& t = mesh.tets[k];
    return MaxDihedralCos(P[t[0]], P[t[1]], P[t[2]], P[t[3]]);
  };
  auto worst_around = [&](int32_t v) {
    double w = -1;
    for (int32_t i = start[v]; i < start[v + 1]; ++i) w = std::max(w, tet_cos(items[i]));
    return w;
  };
  const double threshold_cos = std::cos(threshold_deg * std::numbers::pi / 180.0);
  std::vector<int32_t> todo;
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    if (cancel.stop_requested()) return;
    todo.clear();
    for (size_t k = 0; k < mesh.tets.size(); ++k)
      if (tet_cos(static_cast<int32_t>(k)) > threshold_cos)
        for (int32_t v : mesh.tets[k])
          if (kind[v] != 2) todo.push_back(v);
    std::sort(todo.begin(), todo.end());
    todo.erase(std::unique(todo.begin(), todo.end()), todo.end());
    if (todo.empty()) break;
    int moved = 0;
    for (size_t n = 0; n < todo.size(); ++n) {
      if ((n & 1023) == 1023 && cancel.stop_requested()) return;
      const int32_t v = todo[n];
      Vec3 centroid = Vec3::Zero();
      int count = 0;
      for (int32_t i = start[v]; i < start[v + 1]; ++i)
        for (int32_t u : mesh.tets[items[i]])
          if (u != v) centroid += P[u], ++count;
      centroid /= count;
      const Vec3 old = P[v];
      const double before = worst_around(v);
      double best = before;
      Vec3 best_p = old;
      for (double step : {1.0, 0.5, 0.25}) {
        P[v] = old + step * (centroid - old);
        if (kind[v] == 1) {
          const double z = height(Vec2(P[v].x(), P[v].y()));
          if (!(z > 0)) continue;  // off the solid's footprint
          P[v].z() = old.z() > 0 ? z : -z;
        }
        const double w = worst_around(v);
        if (w < best) best = w, best_p = P[v];
      }
      P[v] = best_p;
      moved += best < before;
    }
    if (moved == 0) break;
  }
}

}  // namespace rheo::mesh::internal
