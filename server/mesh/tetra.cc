// The 2D mesh under the solid and the tetrahedral division over it.
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_mesh_face_base_2.h>
#include <CGAL/Delaunay_mesh_size_criteria_2.h>
#include <CGAL/Delaunay_mesh_vertex_base_2.h>
#include <CGAL/Delaunay_mesher_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "mesh/cgal_domain.h"
#include "mesh/internal.h"

namespace rheo::mesh::internal {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
struct FaceInfo {
  int nesting = -1;
};
struct VertexInfo {
  int32_t id = -1;
  bool on_contour = false;
};
using Vbi = CGAL::Triangulation_vertex_base_with_info_2<VertexInfo, K>;
using Vb = CGAL::Delaunay_mesh_vertex_base_2<K, Vbi>;
using Fbi = CGAL::Triangulation_face_base_with_info_2<FaceInfo, K>;
using Fbc = CGAL::Constrained_triangulation_face_base_2<K, Fbi>;
using Fb = CGAL::Delaunay_mesh_face_base_2<K, Fbc>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using CDT = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::Exact_predicates_tag>;
using Criteria = CGAL::Delaunay_mesh_size_criteria_2<CDT>;

bool Inside(CDT::Face_handle f) {
  return f->info().nesting % 2 == 1;
}

}  // namespace

Result<Mesh2> QualityMesh(const std::vector<Vec2>& polygon, double size) {
  CDT cdt;
  std::vector<CDT::Vertex_handle> handles;
  handles.reserve(polygon.size());
  std::vector<CDT::Point> pts;
  pts.reserve(polygon.size());
  for (const Vec2& p : polygon) pts.emplace_back(p.x(), p.y());
  cdt.insert(pts.begin(), pts.end());  // spatially sorted, O(n log n)
  // Re-inserting finds the existing vertex; the previous one is a good starting face.
  for (const auto& p : pts)
    handles.push_back(handles.empty() ? cdt.insert(p) : cdt.insert(p, handles.back()->face()));
  for (size_t i = 0; i < handles.size(); ++i) {
    auto a = handles[i], b = handles[(i + 1) % handles.size()];
    if (a != b) cdt.insert_constraint(a, b);
  }
  // 0.125 bounds circumradius / shortest edge, i.e. angles >= 20.7 degrees.
  CGAL::refine_Delaunay_mesh_2(cdt, Criteria(0.125, size));
  // A chord (interior edge between two contour vertices) would pinch the solid to zero thickness.
  for (int round = 0;; ++round) {
    MarkDomains(cdt);
    for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v)
      v->info().on_contour = false;
    for (auto e = cdt.finite_edges_begin(); e != cdt.finite_edges_end(); ++e) {
      if (!cdt.is_constrained(*e)) continue;
      e->first->vertex(CDT::cw(e->second))->info().on_contour = true;
      e->first->vertex(CDT::ccw(e->second))->info().on_contour = true;
    }
    std::vector<CDT::Point> mids;
    for (auto e = cdt.finite_edges_begin(); e != cdt.finite_edges_end(); ++e) {
      if (cdt.is_constrained(*e)) continue;
      auto f = e->first;
      auto g = f->neighbor(e->second);
      if (!Inside(f) || !Inside(g)) continue;
      auto a = f->vertex(CDT::cw(e->second)), b = f->vertex(CDT::ccw(e->second));
      if (a->info().on_contour && b->info().on_contour)
        mids.push_back(CGAL::midpoint(a->point(), b->point()));
    }
    if (mids.empty()) break;
    if (round == 50) return Internal("2D mesh: chords between contour vertices remain");
    for (const auto& p : mids) cdt.insert(p);
  }
  Mesh2 out;
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) v->info().id = -1;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    if (!Inside(f)) continue;
    std::array<int32_t, 3> tr;
    for (int i = 0; i < 3; ++i) {
      auto v = f->vertex(i);
      if (v->info().id < 0) {
        v->info().id = static_cast<int32_t>(out.tri.points.size());
        out.tri.points.emplace_back(v->point().x(), v->point().y());
        out.on_contour.push_back(v->info().on_contour ? 1 : 0);
      }
      tr[i] = v->info().id;
    }
    out.tri.triangles.push_back(tr);
    out.tri.classes.push_back(TriangleClass::kJunction);
  }
  if (out.tri.triangles.empty()) return InvalidArgument("2D mesh: polygon encloses no area");
  return out;
}

Result<TetMesh> BuildColumns(const Mesh2& mesh2, const std::vector<double>& heights, double layer,
                             const ColumnLimits& limits) {
  const size_t n = mesh2.tri.points.size();
  std::vector<int32_t> first(n), count(n);
  int64_t num_vertices = 0;
  for (size_t v = 0; v < n; ++v) {
    const int32_t m =
        std::max<int32_t>(1, static_cast<int32_t>(std::lround(2 * heights[v] / layer)));
    count[v] = mesh2.on_contour[v] ? 1 : 1 + m;
    first[v] = static_cast<int32_t>(num_vertices);
    num_vertices += count[v];
  }
  int64_t num_tets = 0;
  for (const auto& tr : mesh2.tri.triangles)
    for (int i = 0; i < 3; ++i) num_tets += count[tr[i]] - 1;
  if (num_vertices > limits.max_vertices)
    return ResourceExhausted("mesh would have " + std::to_string(num_vertices) +
                             " vertices, over the limit max_vertices = " +
                             std::to_string(limits.max_vertices) + "; raise the resolution");
  if (num_tets > limits.max_tets)
    return ResourceExhausted("mesh would have " + std::to_string(num_tets) +
                             " tetrahedra, over the limit max_tets = " +
                             std::to_string(limits.max_tets) + "; raise the resolution");
  TetMesh mesh;
  mesh.positions.resize(num_vertices);
  for (size_t v = 0; v < n; ++v) {
    const Vec2& p = mesh2.tri.points[v];
    const int32_t m = count[v] - 1;
    const double z = m > 0 ? std::max(heights[v], 1e-9 * layer) : 0.0;
    for (int32_t j = 0; j <= m; ++j)
      mesh.positions[first[v] + j] = Vec3(p.x(), p.y(), m > 0 ? z * (2.0 * j / m - 1.0) : 0.0);
  }
  mesh.tets.reserve(num_tets);
  mesh.surface.reserve(2 * mesh2.tri.triangles.size());
  // Sweep each prism bottom to top, always advancing the column whose next point is lowest in
  // normalised height (ties by vertex id): neighbours then split their shared side alike, and
  // every tet is (base triangle, point straight above one of its corners), so its volume > 0.
  for (const auto& tr : mesh2.tri.triangles) {
    int32_t cur[3] = {0, 0, 0};
    mesh.surface.push_back({first[tr[0]], first[tr[2]], first[tr[1]]});
    while (true) {
      int best = -1;
      double best_t = 0;
      for (int i = 0; i < 3; ++i) {
        const int32_t m = count[tr[i]] - 1;
        if (cur[i] >= m) continue;
        const double t = static_cast<double>(cur[i] + 1) / m;
        if (best < 0 || t < best_t || (t == best_t && tr[i] < tr[best])) best = i, best_t = t;
      }
      if (best < 0) break;
      const int32_t apex = first[tr[best]] + cur[best] + 1;
      mesh.tets.push_back(
          {first[tr[0]] + cur[0], first[tr[1]] + cur[1], first[tr[2]] + cur[2], apex});
      ++cur[best];
    }
    mesh.surface.push_back({first[tr[0]] + cur[0], first[tr[1]] + cur[1], first[tr[2]] + cur[2]});
  }
  return mesh;
}

}  // namespace rheo::mesh::internal
