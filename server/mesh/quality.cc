// Validity and quality checks run on every mesh.
#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/format.h"
#include "mesh/mesh.h"

namespace rheo::mesh {
namespace {

using Face = std::array<int32_t, 3>;

// Same cyclic order, smallest index first: equal orientation <=> equal key.
Face Canonical(Face f) {
  const int i = static_cast<int>(std::min_element(f.begin(), f.end()) - f.begin());
  return {f[i], f[(i + 1) % 3], f[(i + 2) % 3]};
}
double Median(std::vector<double>& v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

QualityReport CheckTetMesh(const TetMesh& mesh) {
  QualityReport r;
  const auto& P = mesh.positions;
  const int32_t nv = static_cast<int32_t>(P.size());
  r.num_vertices = nv;
  r.num_tets = static_cast<int64_t>(mesh.tets.size());
  r.num_surface_faces = static_cast<int64_t>(mesh.surface.size());
  for (const auto& t : mesh.tets)
    for (int32_t v : t)
      if (v < 0 || v >= nv) {
        r.failures.push_back("tetrahedron refers to a vertex out of range");
        return r;
      }
  for (const auto& f : mesh.surface)
    for (int32_t v : f)
      if (v < 0 || v >= nv) {
        r.failures.push_back("surface face refers to a vertex out of range");
        return r;
      }

  // Volumes, dihedral angles, radius-edge ratios.
  std::vector<double> volumes, radius_edge;
  std::vector<float> dihedrals;  // cosines
  double max_cos = -1, min_cos = 1;
  volumes.reserve(mesh.tets.size());
  dihedrals.reserve(6 * mesh.tets.size());
  radius_edge.reserve(mesh.tets.size());
  constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  for (const auto& t : mesh.tets) {
    const Vec3 a = P[t[1]] - P[t[0]], b = P[t[2]] - P[t[0]], c = P[t[3]] - P[t[0]];
    const double det = a.dot(b.cross(c));
    const double vol = det / 6.0;
    volumes.push_back(vol);
    r.tet_volume_sum += vol;
    if (!(vol > 0)) {
      ++r.num_nonpositive_tets;
      continue;
    }
    // Face normals (outward) opposite each vertex.
    Vec3 n[4];
    n[0] = (P[t[2]] - P[t[1]]).cross(P[t[3]] - P[t[1]]);
    n[1] = (P[t[3]] - P[t[0]]).cross(P[t[2]] - P[t[0]]);
    n[2] = (P[t[1]] - P[t[0]]).cross(P[t[3]] - P[t[0]]);
    n[3] = (P[t[2]] - P[t[0]]).cross(P[t[1]] - P[t[0]]);
    for (auto& v : n) v.normalize();
    double min_edge2 = 1e300;
    for (const auto& e : kEdges) {
      // The dihedral angle at edge (i, j) is between the faces opposite the other two vertices.
      int o[2], no = 0;
      for (int q = 0; q < 4; ++q)
        if (q != e[0] && q != e[1]) o[no++] = q;
      // cos of the dihedral angle; angles follow from the cosines' order statistics.
      const double cosang = std::clamp(-n[o[0]].dot(n[o[1]]), -1.0, 1.0);
      dihedrals.push_back(static_cast<float>(cosang));
      max_cos = std::max(max_cos, cosang);
      min_cos = std::min(min_cos, cosang);
      min_edge2 = std::min(min_edge2, (P[t[e[0]]] - P[t[e[1]]]).squaredNorm());
    }
    const Vec3 cc = (a.squaredNorm() * b.cross(c) + b.squaredNorm() * c.cross(a) +
                     c.squaredNorm() * a.cross(b)) /
                    (2.0 * det);
    radius_edge.push_back(cc.norm() / std::sqrt(min_edge2));
  }
  auto deg = [](double c) {
    return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / std::numbers::pi;
  };
  if (!dihedrals.empty()) {
    r.min_dihedral_deg = deg(max_cos);
    r.max_dihedral_deg = deg(min_cos);
    auto mid = dihedrals.begin() + static_cast<long>(dihedrals.size() / 2);
    std::nth_element(dihedrals.begin(), mid, dihedrals.end());
    r.median_dihedral_deg = deg(*mid);
  }
  if (!volumes.empty()) {
    r.min_volume = *std::min_element(volumes.begin(), volumes.end());
    std::vector<double> tmp = volumes;
    r.median_volume = Median(tmp);
    r.min_volume_ratio = r.median_volume > 0 ? r.min_volume / r.median_volume : 0;
  }
  if (!radius_edge.empty()) {
    r.max_radius_edge = *std::max_element(radius_edge.begin(), radius_edge.end());
    r.median_radius_edge = Median(radius_edge);
  }
  if (r.num_nonpositive_tets > 0)
    r.failures.push_back(std::to_string(r.num_nonpositive_tets) +
                         " tetrahedra have zero or negative volume");

  // Faces used by exactly one tetrahedron, outward, must be the surface (sorting, no hashing).
  struct TetFace {
    Face key;       // sorted vertex ids
    Face oriented;  // canonical outward orientation
    bool operator<(const TetFace& o) const { return key < o.key; }
  };
  std::vector<TetFace> all;
  all.reserve(4 * mesh.tets.size());
  for (const auto& t : mesh.tets) {
    const Face fs[4] = {
        {t[1], t[2], t[3]}, {t[0], t[3], t[2]}, {t[0], t[1], t[3]}, {t[0], t[2], t[1]}};
    for (const Face& f : fs) {
      Face key = f;
      std::sort(key.begin(), key.end());
      all.push_back({key, Canonical(f)});
    }
  }
  std::sort(all.begin(), all.end());
  int64_t overused = 0;
  std::vector<Face> boundary;
  for (size_t i = 0; i < all.size();) {
    size_t j = i;
    while (j < all.size() && all[j].key == all[i].key) ++j;
    if (j - i > 2) ++overused;
    if (j - i == 1) boundary.push_back(all[i].oriented);
    i = j;
  }
  if (overused)
    r.failures.push_back(std::to_string(overused) + " faces shared by more than two tetrahedra");
  std::vector<Face> surf;
  surf.reserve(mesh.surface.size());
  for (const Face& f : mesh.surface) surf.push_back(Canonical(f));
  std::sort(boundary.begin(), boundary.end());
  std::sort(surf.begin(), surf.end());
  r.boundary_matches_surface = boundary == surf;
  if (!r.boundary_matches_surface)
    r.failures.push_back("boundary of the tetrahedra (" + std::to_string(boundary.size()) +
                         " faces) differs from the surface (" +
                         std::to_string(mesh.surface.size()) + " faces)");

  // Closed and consistently oriented: each directed edge once, its reverse once.
  auto key = [](int32_t a, int32_t b) { return (uint64_t(uint32_t(a)) << 32) | uint32_t(b); };
  std::vector<uint64_t> directed;
  directed.reserve(3 * mesh.surface.size());
  for (const Face& f : mesh.surface)
    for (int i = 0; i < 3; ++i) directed.push_back(key(f[i], f[(i + 1) % 3]));
  std::sort(directed.begin(), directed.end());
  bool closed = true, oriented_ok = true;
  for (size_t i = 0; i < directed.size(); ++i) {
    if (i + 1 < directed.size() && directed[i + 1] == directed[i]) oriented_ok = false;
    const uint64_t rev = key(int32_t(directed[i] & 0xffffffffu), int32_t(directed[i] >> 32));
    if (!std::binary_search(directed.begin(), directed.end(), rev)) closed = false;
  }
  r.surface_closed = closed && !mesh.surface.empty();
  if (!r.surface_closed) r.failures.push_back("surface is not closed (an edge lacks its twin)");
  // Vertex links: the faces around each vertex must form a single cycle.
  std::vector<int32_t> start(nv + 1, 0);
  for (const Face& f : mesh.surface)
    for (int32_t v : f) ++start[v + 1];
  for (int32_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<std::pair<int32_t, int32_t>> link(start[nv]);
  std::vector<int32_t> fill(start.begin(), start.end() - 1);
  for (const Face& f : mesh.surface)
    for (int i = 0; i < 3; ++i) link[fill[f[i]]++] = {f[(i + 1) % 3], f[(i + 2) % 3]};
  bool manifold = oriented_ok;
  for (int32_t v = 0; v < nv && manifold; ++v) {
    const int32_t b0 = start[v], e0 = start[v + 1];
    if (b0 == e0) continue;
    auto next = [&](int32_t a) {
      int32_t found = -1, hits = 0;
      for (int32_t k = b0; k < e0; ++k)
        if (link[k].first == a) found = link[k].second, ++hits;
      return hits == 1 ? found : -1;
    };
    const int32_t first = link[b0].first;
    int32_t cur = first, steps = 0;
    do {
      cur = next(cur);
      ++steps;
    } while (cur >= 0 && cur != first && steps <= e0 - b0);
    if (cur != first || steps != e0 - b0) manifold = false;
  }
  r.surface_manifold = manifold;
  if (!manifold) r.failures.push_back("surface is not manifold (a vertex link is not one cycle)");

  // Enclosed volume by the divergence theorem.
  for (const Face& f : mesh.surface) r.surface_volume += P[f[0]].dot(P[f[1]].cross(P[f[2]])) / 6.0;
  r.surface_outward = oriented_ok && r.surface_volume > 0;
  if (!r.surface_outward) r.failures.push_back("surface is not consistently oriented outward");
  r.volume_rel_error = r.surface_volume != 0 ? std::abs(r.tet_volume_sum - r.surface_volume) /
                                                   std::abs(r.surface_volume)
                                             : 1.0;
  if (!(r.volume_rel_error <= 1e-9))
    r.failures.push_back(
        Format("sum of tetrahedron volumes %.9g m^3 differs from the enclosed volume %.9g m^3",
               r.tet_volume_sum, r.surface_volume));
  r.valid = r.failures.empty();
  return r;
}

}  // namespace rheo::mesh
