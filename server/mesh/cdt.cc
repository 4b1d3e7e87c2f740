#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include "mesh/cgal_domain.h"
#include "mesh/internal.h"

namespace rheo::mesh {
namespace internal {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
struct FaceInfo {
  int nesting = -1;  // constraint crossings from the outside; odd = inside the polygon
  int32_t id = -1;
};
using Vb = CGAL::Triangulation_vertex_base_with_info_2<int32_t, K>;
using Fbi = CGAL::Triangulation_face_base_with_info_2<FaceInfo, K>;
using Fb = CGAL::Constrained_triangulation_face_base_2<K, Fbi>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using CDT = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::Exact_predicates_tag>;

}  // namespace

Result<Cdt> TriangulateWithNeighbors(const std::vector<Vec2>& polygon) {
  CDT cdt;
  // Range insertion sorts spatially (O(n log n)); info carries the polygon index.
  std::vector<std::pair<CDT::Point, int32_t>> input;
  input.reserve(polygon.size());
  for (size_t i = 0; i < polygon.size(); ++i)
    input.emplace_back(CDT::Point(polygon[i].x(), polygon[i].y()), static_cast<int32_t>(i));
  cdt.insert(input.begin(), input.end());
  std::vector<CDT::Vertex_handle> handles(polygon.size());
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v)
    handles[v->info()] = v;
  for (size_t i = 0; i < polygon.size(); ++i)  // duplicates of an earlier point
    if (handles[i] == CDT::Vertex_handle()) handles[i] = cdt.insert(input[i].first);
  // Number vertices by first appearance along the polygon, so contour order is kept.
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) v->info() = -1;
  Cdt out;
  for (auto& h : handles) {
    if (h->info() >= 0) continue;
    h->info() = static_cast<int32_t>(out.tri.points.size());
    out.tri.points.emplace_back(h->point().x(), h->point().y());
  }
  if (out.tri.points.size() < 3) return InvalidArgument("polygon has fewer than 3 distinct points");
  for (size_t i = 0; i < handles.size(); ++i) {
    auto a = handles[i], b = handles[(i + 1) % handles.size()];
    if (a != b) cdt.insert_constraint(a, b);
  }
  MarkDomains(cdt);
  int32_t count = 0;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f)
    f->info().id = (f->info().nesting % 2 == 1) ? count++ : -1;
  if (count == 0) return InvalidArgument("polygon encloses no area");
  out.tri.triangles.resize(count);
  out.tri.classes.resize(count);
  out.neighbors.resize(count);
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    const int32_t id = f->info().id;
    if (id < 0) continue;
    int on_contour = 0;
    for (int i = 0; i < 3; ++i) {
      out.tri.triangles[id][i] = f->vertex(i)->info();
      const bool constrained = cdt.is_constrained(CDT::Edge(f, i));
      const int32_t nb = f->neighbor(i)->info().id;
      out.neighbors[id][i] = (constrained || cdt.is_infinite(f->neighbor(i))) ? -1 : nb;
      on_contour += constrained ? 1 : 0;
    }
    out.tri.classes[id] = static_cast<TriangleClass>(on_contour);
  }
  return out;
}

}  // namespace internal

const char* TriangleClassName(TriangleClass c) {
  switch (c) {
    case TriangleClass::kJunction: return "junction";
    case TriangleClass::kSleeve: return "sleeve";
    case TriangleClass::kTerminal: return "terminal";
    case TriangleClass::kIsolated: return "isolated";
  }
  return "?";
}

Result<Triangulation2> TriangulatePolygon(const std::vector<Vec2>& polygon) {
  std::vector<Vec2> pts;
  pts.reserve(polygon.size());
  for (const Vec2& p : polygon)
    if (pts.empty() || pts.back() != p) pts.push_back(p);
  while (pts.size() > 1 && pts.front() == pts.back()) pts.pop_back();
  auto cdt = internal::TriangulateWithNeighbors(pts);
  if (!cdt.ok()) return cdt.error();
  return std::move(cdt->tri);
}

}  // namespace rheo::mesh
