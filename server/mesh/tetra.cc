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

// Points of a hexagonal lattice with spacing `size` strictly inside the polygon and at least
// `keep` from its boundary: near-equilateral triangles everywhere but a band along the contour,
// so the refinement that follows only works on that band. Linear in lattice points + edges.
std::vector<CDT::Point> HexLatticeInside(const std::vector<Vec2>& polygon, double size,
                                         double keep) {
  Vec2 lo = polygon[0], hi = polygon[0];
  for (const Vec2& p : polygon) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double row = size * std::sqrt(3.0) / 2;
  const int rows = static_cast<int>(std::floor((hi.y() - lo.y()) / row)) + 1;
  // Scanline crossings of every row with the polygon (half-open in y: each vertex once).
  std::vector<std::vector<double>> cross(rows);
  const size_t n = polygon.size();
  for (size_t i = 0; i < n; ++i) {
    const Vec2 &a = polygon[i], &b = polygon[(i + 1) % n];
    if (a.y() == b.y()) continue;
    const double y0 = std::min(a.y(), b.y()), y1 = std::max(a.y(), b.y());
    const int j0 = std::max(0, static_cast<int>(std::ceil((y0 - lo.y()) / row - 0.5)));
    for (int j = j0; j < rows; ++j) {
      const double y = lo.y() + (j + 0.5) * row;
      if (y >= y1) break;
      if (y < y0) continue;
      cross[j].push_back(a.x() + (b.x() - a.x()) * (y - a.y()) / (b.y() - a.y()));
    }
  }
  // Boundary edges bucketed on a grid of cells >= keep, for the clearance test.
  const double cell = std::max(keep, size);
  const int nx = static_cast<int>((hi.x() - lo.x()) / cell) + 1;
  const int ny = static_cast<int>((hi.y() - lo.y()) / cell) + 1;
  std::vector<int32_t> start(static_cast<size_t>(nx) * ny + 1, 0), items;
  auto cells_of = [&](size_t i, auto&& visit) {
    const Vec2 &a = polygon[i], &b = polygon[(i + 1) % n];
    const int x0 = static_cast<int>((std::min(a.x(), b.x()) - lo.x()) / cell);
    const int x1 = static_cast<int>((std::max(a.x(), b.x()) - lo.x()) / cell);
    const int y0 = static_cast<int>((std::min(a.y(), b.y()) - lo.y()) / cell);
    const int y1 = static_cast<int>((std::max(a.y(), b.y()) - lo.y()) / cell);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) visit(static_cast<size_t>(y) * nx + x);
  };
  for (size_t i = 0; i < n; ++i) cells_of(i, [&](size_t c) { ++start[c + 1]; });
  for (size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
  items.resize(start.back());
  std::vector<int32_t> fill(start.begin(), start.end() - 1);
  for (size_t i = 0; i < n; ++i)
    cells_of(i, [&](size_t c) { items[fill[c]++] = static_cast<int32_t>(i); });
  auto clear_of_boundary = [&](const Vec2& p) {
    const int cx = static_cast<int>((p.x() - lo.x()) / cell);
    const int cy = static_cast<int>((p.y() - lo.y()) / cell);
    for (int y = std::max(0, cy - 1); y <= std::min(ny - 1, cy + 1); ++y)
      for (int x = std::max(0, cx - 1); x <= std::min(nx - 1, cx + 1); ++x) {
        const size_t c = static_cast<size_t>(y) * nx + x;
        for (int32_t k = start[c]; k < start[c + 1]; ++k) {
          const Vec2 &a = polygon[items[k]], &b = polygon[(items[k] + 1) % n];
          const Vec2 ab = b - a;
          const double t =
              std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-300), 0.0, 1.0);
          if ((a + t * ab - p).squaredNorm() < keep * keep) return false;
        }
      }
    return true;
  };
  std::vector<CDT::Point> out;
  for (int j = 0; j < rows; ++j) {
    auto& xs = cross[j];
    std::sort(xs.begin(), xs.end());
    const double y = lo.y() + (j + 0.5) * row;
    const double shift = (j % 2) * 0.5 * size;
    for (size_t k = 0; k + 1 < xs.size(); k += 2) {
      for (double x = lo.x() + shift + size * std::ceil((xs[k] + keep - lo.x() - shift) / size);
           x < xs[k + 1] - keep; x += size) {
        const Vec2 p(x, y);
        if (clear_of_boundary(p)) out.emplace_back(x, y);
      }
    }
  }
  return out;
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
  // Slightly under `size`: lattice edges exactly at the bound would fail the size criterion on
  // round-off and be split.
  const std::vector<CDT::Point> lattice = HexLatticeInside(polygon, 0.98 * size, 0.6 * size);
  cdt.insert(lattice.begin(), lattice.end());
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
