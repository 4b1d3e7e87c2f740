#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2_algorithms.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <variant>

#include "mesh/internal.h"

namespace rheo::mesh::internal {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;

double SignedArea(const std::vector<Vec2>& p) {
  double a = 0;
  for (size_t i = 0, n = p.size(); i < n; ++i) {
    const Vec2& u = p[i];
    const Vec2& v = p[(i + 1) % n];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return 0.5 * a;
}

// Exact segment test, only used to locate a self-intersection for the error message.
bool SegmentsIntersect(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  return CGAL::do_intersect(K::Segment_2(K::Point_2(a.x(), a.y()), K::Point_2(b.x(), b.y())),
                            K::Segment_2(K::Point_2(c.x(), c.y()), K::Point_2(d.x(), d.y())));
}

// Cuts loops a pen's jitter leaves (a segment crossing one a few steps later), when the loop is
// short: at most `max_loop` long [m]. Big crossings (a figure eight) stay and are refused later.
std::vector<Vec2> RemoveSmallLoops(std::vector<Vec2> p, double max_loop) {
  constexpr size_t kWindow = 16;  // segments ahead that a small loop may span
  for (size_t i = 0; i + 2 < p.size();) {
    const size_t n = p.size();
    bool cut = false;
    for (size_t d = 2; d <= kWindow && d + 1 < n && !cut; ++d) {
      const size_t j = (i + d) % n;
      if (j < i) break;  // loops across the start are left to the general check
      const K::Segment_2 si(K::Point_2(p[i].x(), p[i].y()), K::Point_2(p[i + 1].x(), p[i + 1].y()));
      const K::Segment_2 sj(K::Point_2(p[j].x(), p[j].y()),
                            K::Point_2(p[(j + 1) % n].x(), p[(j + 1) % n].y()));
      const auto x = CGAL::intersection(si, sj);
      if (!x) continue;
      K::Point_2 q;
      if (const K::Point_2* pt = boost::get<K::Point_2>(&*x))
        q = *pt;
      else
        q = boost::get<K::Segment_2>(*x).source();
      const Vec2 c(q.x(), q.y());
      double loop = (p[i + 1] - c).norm() + (c - p[j]).norm();  // the part that would be cut
      for (size_t k = i + 1; k < j; ++k) loop += (p[k + 1] - p[k]).norm();
      if (loop > max_loop) continue;
      // Keep p[0..i], the crossing point, p[j+1..].
      std::vector<Vec2> out(p.begin(), p.begin() + static_cast<long>(i) + 1);
      out.emplace_back(q.x(), q.y());
      out.insert(out.end(), p.begin() + static_cast<long>(j) + 1, p.end());
      std::vector<Vec2> dedup;
      for (const Vec2& v : out)
        if (dedup.empty() || dedup.back() != v) dedup.push_back(v);
      p.swap(dedup);
      cut = true;
    }
    if (!cut) ++i;
  }
  return p;
}

}  // namespace

bool IsSimplePolygon(const std::vector<Vec2>& polygon) {
  std::vector<K::Point_2> pts;
  pts.reserve(polygon.size());
  for (const Vec2& p : polygon) pts.emplace_back(p.x(), p.y());
  return CGAL::is_simple_2(pts.begin(), pts.end(), K());
}

Result<std::vector<Vec2>> ContourToMetres(const Polygon2& contour_px, double pixel_size) {
  if (!(pixel_size > 0) || !std::isfinite(pixel_size))
    return InvalidArgument("pixel_size must be a positive number of metres per pixel");
  std::vector<Vec2> out;
  out.reserve(contour_px.points.size());
  for (size_t i = 0; i < contour_px.points.size(); ++i) {
    const Vec2& p = contour_px.points[i];
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()))
      return InvalidArgument("contour point " + std::to_string(i) + " is not a finite number");
    Vec2 q(p.x() * pixel_size, -p.y() * pixel_size);
    if (!out.empty() && out.back() == q) continue;  // consecutive duplicate
    out.push_back(q);
  }
  while (out.size() > 1 && out.front() == out.back()) out.pop_back();  // repeated closing point
  if (out.size() < 3)
    return InvalidArgument("contour has " + std::to_string(out.size()) +
                           " distinct points; a closed outline needs at least 3");
  double area = SignedArea(out);
  if (area == 0) return InvalidArgument("contour encloses zero area (all points collinear?)");
  if (area < 0) std::reverse(out.begin(), out.end());
  return out;
}

Result<std::vector<Vec2>> ResampleContour(const std::vector<Vec2>& input, double spacing,
                                          double pixel_size, const CancelToken& cancel) {
  std::vector<Vec2> polygon = input;
  if (!IsSimplePolygon(polygon)) {
    double perimeter = 0;
    for (size_t i = 0; i < input.size(); ++i)
      perimeter += (input[(i + 1) % input.size()] - input[i]).norm();
    polygon = RemoveSmallLoops(input, 0.05 * perimeter);  // loops up to 5 % of the outline
    if (polygon.size() < 3) polygon = input;
  }
  const size_t n = polygon.size();
  std::vector<double> arc(n + 1, 0.0);  // arc length at each vertex [m]
  for (size_t i = 0; i < n; ++i) arc[i + 1] = arc[i] + (polygon[(i + 1) % n] - polygon[i]).norm();
  const double length = arc[n];
  // Loops and zigzags smaller than the spacing (pen jitter) vanish here; the first spacing whose
  // outline is simple wins.
  for (int attempt = 0; attempt < 8; ++attempt, spacing *= 0.5) {
    const size_t m = std::max<size_t>(8, static_cast<size_t>(std::ceil(length / spacing)));
    if (m >= n) break;  // finer than the input: keep the input
    std::vector<Vec2> out;
    out.reserve(m);
    const double step = length / static_cast<double>(m);
    size_t seg = 0;
    for (size_t k = 0; k < m; ++k) {
      const double s = step * static_cast<double>(k);
      while (seg + 1 < n && arc[seg + 1] <= s) ++seg;
      const double len = arc[seg + 1] - arc[seg];
      const double t = len > 0 ? (s - arc[seg]) / len : 0.0;
      out.push_back(polygon[seg] + t * (polygon[(seg + 1) % n] - polygon[seg]));
    }
    if (SignedArea(out) > 0 && IsSimplePolygon(out)) return out;
  }
  const std::vector<Vec2>& out = polygon;
  if (IsSimplePolygon(out)) return out;
  // Locate one crossing for the message (quadratic, but only on the failure path).
  for (size_t i = 0; i < n && i < 20000; ++i) {
    if (Status s = cancel.Check("the contour check"); !s) return s.error();
    for (size_t j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;
      if (SegmentsIntersect(out[i], out[(i + 1) % n], out[j], out[(j + 1) % n])) {
        char buf[200];
        std::snprintf(buf, sizeof buf,
                      "contour intersects itself near (%.1f, %.1f) px: segments %zu and %zu "
                      "cross or touch; the outline must be one simple closed loop",
                      out[j].x() / pixel_size, -out[j].y() / pixel_size, i, j);
        return InvalidArgument(buf);
      }
    }
  }
  return InvalidArgument("contour is not a simple polygon (it touches or crosses itself)");
}

}  // namespace rheo::mesh::internal
