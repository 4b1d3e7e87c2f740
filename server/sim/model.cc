#include "sim/model.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <string>

#include "common/tet_mesh_io.h"

namespace rheo::sim {
namespace {

double SignedTetVolume(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  return (p1 - p0).dot((p2 - p0).cross(p3 - p0)) / 6.0;
}

}  // namespace

// Fills the edge -> element lists (model.h), or leaves them empty when some pair is not an edge
// and not between two fixed nodes.
void IndexElementsByEdge(Model& m) {
  for (auto* v : {&m.edge_tet_start, &m.edge_tet, &m.edge_face_start, &m.edge_face}) v->clear();
  // (lower node, higher node, edge index), sorted for lookup whatever the order of m.edges.
  std::vector<std::array<int32_t, 3>> keys(m.edges.size());
  for (size_t k = 0; k < m.edges.size(); ++k) {
    const auto [i, j] = m.edges[k];
    keys[k] = {std::min(i, j), std::max(i, j), static_cast<int32_t>(k)};
  }
  std::sort(keys.begin(), keys.end());
  // Edge k of the pair (a, b) and whether it runs from b to a; k = -1 when it is not an edge.
  auto find = [&](int32_t a, int32_t b, int32_t& flip) -> int32_t {
    const std::array<int32_t, 3> key = {std::min(a, b), std::max(a, b), -1};
    const auto it = std::lower_bound(keys.begin(), keys.end(), key);
    if (it == keys.end() || (*it)[0] != key[0] || (*it)[1] != key[1]) return -1;
    flip = m.edges[(*it)[2]][0] == a ? 0 : 1;
    return (*it)[2];
  };
  // CSR lists of `elems` (each with `pairs` node pairs) by edge; false when a pair is not an edge.
  auto build = [&](const auto& elems, std::span<const std::array<int, 2>> pairs,
                   std::vector<int32_t>& start, std::vector<int32_t>& list) {
    if (elems.size() >= (size_t{1} << 27)) return false;  // the entry would overflow
    std::vector<std::array<int32_t, 2>> by_edge;          // (edge, entry)
    by_edge.reserve(elems.size() * pairs.size());
    for (size_t t = 0; t < elems.size(); ++t) {
      for (size_t p = 0; p < pairs.size(); ++p) {
        int32_t flip = 0;
        const int32_t a = elems[t][pairs[p][0]], b = elems[t][pairs[p][1]];
        const int32_t k = find(a, b, flip);
        if (k < 0) {
          // The pair's block couples two fixed nodes only: rows and columns the implicit solve
          // leaves out (a multi-rate patch's boundary, whose edges the patch does not carry).
          if (!m.fixed.empty() && m.fixed[a] && m.fixed[b]) continue;
          return false;
        }
        const int32_t q = pairs[p][flip], r = pairs[p][1 - flip];  // at the edge's first node: q
        by_edge.push_back({k, static_cast<int32_t>(16 * t) + 4 * q + r});
      }
    }
    std::sort(by_edge.begin(), by_edge.end());
    start.assign(m.edges.size() + 1, 0);
    for (const auto& [k, entry] : by_edge) ++start[k + 1];
    for (size_t k = 0; k < m.edges.size(); ++k) start[k + 1] += start[k];
    list.resize(by_edge.size());
    for (size_t q = 0; q < by_edge.size(); ++q) list[q] = by_edge[q][1];
    return true;
  };
  constexpr std::array<std::array<int, 2>, 6> kTetPairs = {
      {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};
  constexpr std::array<std::array<int, 2>, 3> kFacePairs = {{{0, 1}, {0, 2}, {1, 2}}};
  if (!build(m.tets, kTetPairs, m.edge_tet_start, m.edge_tet) ||
      !build(m.faces, kFacePairs, m.edge_face_start, m.edge_face)) {
    for (auto* v : {&m.edge_tet_start, &m.edge_tet, &m.edge_face_start, &m.edge_face}) v->clear();
  }
}

namespace {

// Finishes the geometric fields of a model whose nodes, masses, edges, faces and tets are set.
Status FinishModel(Model& m) {
  const int32_t n = m.num_nodes;
  auto bad_index = [&](const char* what, size_t k, int32_t idx) {
    return InvalidArgument(std::string(what) + " " + std::to_string(k) + " refers to node " +
                           std::to_string(idx) + ", outside [0, " + std::to_string(n) + ")");
  };
  for (int32_t i = 0; i < n; ++i) {
    if (!m.rest_positions[i].allFinite()) {
      return InvalidArgument("node " + std::to_string(i) + " has a non-finite position");
    }
  }
  m.edge_rest_length.resize(m.edges.size());
  for (size_t k = 0; k < m.edges.size(); ++k) {
    for (int32_t idx : m.edges[k]) {
      if (idx < 0 || idx >= n) return bad_index("edge", k, idx);
    }
    const double l = (m.rest_positions[m.edges[k][1]] - m.rest_positions[m.edges[k][0]]).norm();
    if (!(l > 0.0)) {
      return InvalidArgument("edge " + std::to_string(k) + " (nodes " +
                             std::to_string(m.edges[k][0]) + ", " + std::to_string(m.edges[k][1]) +
                             ") has zero rest length");
    }
    m.edge_rest_length[k] = l;
  }
  m.face_rest_area.resize(m.faces.size());
  m.face_min_height.resize(m.faces.size());
  m.rest_volume = 0.0;
  for (size_t k = 0; k < m.faces.size(); ++k) {
    for (int32_t idx : m.faces[k]) {
      if (idx < 0 || idx >= n) return bad_index("face", k, idx);
    }
    const Vec3& a = m.rest_positions[m.faces[k][0]];
    const Vec3& b = m.rest_positions[m.faces[k][1]];
    const Vec3& c = m.rest_positions[m.faces[k][2]];
    const double area = 0.5 * (b - a).cross(c - a).norm();
    m.face_rest_area[k] = area;
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    m.face_min_height[k] = longest > 0 ? 2.0 * area / longest : 0.0;
    m.rest_volume += a.dot(b.cross(c)) / 6.0;
  }
  m.tet_rest_volume.resize(m.tets.size());
  m.tet_min_height.resize(m.tets.size());
  m.tet_grad_floor.resize(m.tets.size());
  m.inverted_tets = 0;
  for (size_t k = 0; k < m.tets.size(); ++k) {
    for (int32_t idx : m.tets[k]) {
      if (idx < 0 || idx >= n) return bad_index("tetrahedron", k, idx);
    }
    const auto& t = m.tets[k];
    const Vec3* p[4] = {&m.rest_positions[t[0]], &m.rest_positions[t[1]], &m.rest_positions[t[2]],
                        &m.rest_positions[t[3]]};
    const double vol = SignedTetVolume(*p[0], *p[1], *p[2], *p[3]);
    m.tet_rest_volume[k] = vol;
    if (!(vol > 0.0)) ++m.inverted_tets;
    double max_face = 0.0, min_face = std::numeric_limits<double>::infinity();
    for (int f = 0; f < 4; ++f) {
      const Vec3& a = *p[(f + 1) % 4];
      const Vec3& b = *p[(f + 2) % 4];
      const Vec3& c = *p[(f + 3) % 4];
      const double area = 0.5 * (b - a).cross(c - a).norm();
      max_face = std::max(max_face, area);
      min_face = std::min(min_face, area);
    }
    m.tet_min_height[k] = max_face > 0 ? 3.0 * std::abs(vol) / max_face : 0.0;
    m.tet_grad_floor[k] = static_cast<float>(min_face);
  }
  m.fixed.assign(n, 0);
  IndexElementsByEdge(m);
  Eigen::AlignedBox3d box;
  for (const Vec3& p : m.rest_positions) box.extend(p);
  m.size = n > 0 ? box.diagonal().norm() : 0.0;
  m.inv_mass.resize(n);
  for (int32_t i = 0; i < n; ++i) {
    if (!(m.mass[i] > 0.0) || !std::isfinite(m.mass[i])) {
      return InvalidArgument("node " + std::to_string(i) +
                             " has no mass (it belongs to no tetrahedron, or its mass is not "
                             "positive)");
    }
    m.inv_mass[i] = 1.0 / m.mass[i];
  }
  return Status::Ok();
}

}  // namespace

Result<Model> BuildModel(const TetMesh& mesh_in, double density) {
  if (mesh_in.tets.empty() || mesh_in.positions.size() < 4) {
    return InvalidArgument("mesh has no tetrahedra (" + std::to_string(mesh_in.tets.size()) +
                           " tets, " + std::to_string(mesh_in.positions.size()) + " nodes)");
  }
  if (!(density > 0.0)) return InvalidArgument("density must be positive");
  Model m;
  m.num_nodes = static_cast<int32_t>(mesh_in.positions.size());
  m.rest_positions = mesh_in.positions;
  m.tets = mesh_in.tets;
  const int32_t n = m.num_nodes;
  for (size_t k = 0; k < m.tets.size(); ++k) {
    for (int32_t idx : m.tets[k]) {
      if (idx < 0 || idx >= n) {
        return InvalidArgument("tetrahedron " + std::to_string(k) + " refers to node " +
                               std::to_string(idx) + ", outside [0, " + std::to_string(n) + ")");
      }
    }
    auto& t = m.tets[k];
    if (SignedTetVolume(m.rest_positions[t[0]], m.rest_positions[t[1]], m.rest_positions[t[2]],
                        m.rest_positions[t[3]]) < 0.0) {
      std::swap(t[2], t[3]);
    }
  }
  if (mesh_in.surface.empty()) {
    TetMesh copy;
    copy.positions = mesh_in.positions;
    copy.tets = m.tets;
    ComputeBoundary(copy);
    m.faces = std::move(copy.surface);
  } else {
    m.faces = mesh_in.surface;
  }
  // Unique edges, sorted so that memory access follows node order.
  m.edges.reserve(m.tets.size() * 6);
  for (const auto& t : m.tets) {
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        m.edges.push_back({std::min(t[i], t[j]), std::max(t[i], t[j])});
      }
    }
  }
  std::sort(m.edges.begin(), m.edges.end());
  m.edges.erase(std::unique(m.edges.begin(), m.edges.end()), m.edges.end());
  m.edges.shrink_to_fit();
  // Lumped masses: a quarter of each tet's volume to each of its nodes.
  m.node_volume.assign(n, 0.0);
  for (const auto& t : m.tets) {
    const double vol = std::abs(SignedTetVolume(m.rest_positions[t[0]], m.rest_positions[t[1]],
                                                m.rest_positions[t[2]], m.rest_positions[t[3]]));
    for (int32_t idx : t) m.node_volume[idx] += 0.25 * vol;
  }
  m.mass.resize(n);
  for (int32_t i = 0; i < n; ++i) m.mass[i] = density * m.node_volume[i];
  if (Status s = FinishModel(m); !s.ok()) return s.error();
  return m;
}

Result<Model> BuildModelFromParts(std::span<const Vec3> positions, std::span<const double> masses,
                                  std::span<const std::array<int32_t, 2>> edges,
                                  std::span<const std::array<int32_t, 3>> faces,
                                  std::span<const std::array<int32_t, 4>> tets) {
  if (positions.size() != masses.size()) {
    return InvalidArgument("positions (" + std::to_string(positions.size()) + ") and masses (" +
                           std::to_string(masses.size()) + ") differ in length");
  }
  Model m;
  m.num_nodes = static_cast<int32_t>(positions.size());
  m.rest_positions.assign(positions.begin(), positions.end());
  m.mass.assign(masses.begin(), masses.end());
  m.node_volume.assign(positions.size(), 0.0);
  m.edges.assign(edges.begin(), edges.end());
  m.faces.assign(faces.begin(), faces.end());
  m.tets.assign(tets.begin(), tets.end());
  if (Status s = FinishModel(m); !s.ok()) return s.error();
  return m;
}

}  // namespace rheo::sim
