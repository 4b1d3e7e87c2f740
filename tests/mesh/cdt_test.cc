// Constrained Delaunay triangulation and triangle classes.
#include <gtest/gtest.h>

#include <map>
#include <random>

#include "mesh/internal.h"
#include "mesh/mesh.h"
#include "test_polygons.h"

namespace rheo::mesh {
namespace {

double Area(const Vec2& a, const Vec2& b, const Vec2& c) {
  return 0.5 * ((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
}

double PolygonArea(const std::vector<Vec2>& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const Vec2 &u = p[i], &v = p[(i + 1) % p.size()];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return 0.5 * std::abs(a);
}

std::vector<Vec2> Points(const Polygon2& p) {
  return p.points;
}

// Checks every invariant of a polygon CDT: positive triangles tiling the polygon, every contour
// edge used once, classes equal to the number of contour edges, interior edges locally Delaunay,
// and the dual tree's leaf count (terminal = junction + 2).
void ExpectValidCdt(const std::vector<Vec2>& poly_in, const Triangulation2& t) {
  std::vector<Vec2> poly;
  for (const Vec2& p : poly_in)
    if (poly.empty() || poly.back() != p) poly.push_back(p);
  while (poly.size() > 1 && poly.front() == poly.back()) poly.pop_back();
  ASSERT_EQ(t.triangles.size(), t.classes.size());
  double area = 0;
  std::map<std::pair<int, int>, int> edges;  // directed edge -> uses
  for (const auto& tr : t.triangles) {
    const double a = Area(t.points[tr[0]], t.points[tr[1]], t.points[tr[2]]);
    EXPECT_GT(a, 0);
    area += a;
    for (int i = 0; i < 3; ++i) ++edges[{tr[i], tr[(i + 1) % 3]}];
  }
  const double pa = PolygonArea(poly);
  EXPECT_NEAR(area, pa, 1e-9 * pa);
  // Contour edges: one direction used once, the other never.
  std::map<std::pair<int, int>, bool> contour;
  auto index_of = [&](const Vec2& p) {
    for (size_t i = 0; i < t.points.size(); ++i)
      if (t.points[i] == p) return static_cast<int>(i);
    return -1;
  };
  std::vector<int> ids;
  for (const Vec2& p : poly) ids.push_back(index_of(p));
  for (size_t i = 0; i < ids.size(); ++i) {
    const int a = ids[i], b = ids[(i + 1) % ids.size()];
    ASSERT_GE(a, 0);
    contour[{a, b}] = true;
    contour[{b, a}] = true;
    EXPECT_EQ(edges.count({a, b}) + edges.count({b, a}), 1u) << "contour edge " << i;
  }
  int terminal = 0, junction = 0;
  for (size_t k = 0; k < t.triangles.size(); ++k) {
    const auto& tr = t.triangles[k];
    int on = 0;
    for (int i = 0; i < 3; ++i) on += contour.count({tr[i], tr[(i + 1) % 3]}) ? 1 : 0;
    EXPECT_EQ(static_cast<int>(t.classes[k]), on);
    terminal += on == 2;
    junction += on == 0;
  }
  if (t.triangles.size() > 1) {
    EXPECT_EQ(terminal, junction + 2);
  }
  // Local Delaunay: the opposite vertex of each interior edge is not strictly inside the
  // circumcircle (tolerance for the inexact in-circle evaluation here).
  std::map<std::pair<int, int>, int> opposite;
  for (const auto& tr : t.triangles)
    for (int i = 0; i < 3; ++i) opposite[{tr[i], tr[(i + 1) % 3]}] = tr[(i + 2) % 3];
  for (const auto& tr : t.triangles) {
    for (int i = 0; i < 3; ++i) {
      const int a = tr[i], b = tr[(i + 1) % 3];
      if (contour.count({a, b})) continue;
      auto it = opposite.find({b, a});
      ASSERT_NE(it, opposite.end());
      const Vec2 &pa2 = t.points[a], &pb = t.points[b], &pc = t.points[tr[(i + 2) % 3]],
                 &pd = t.points[it->second];
      const Vec2 A = pa2 - pd, B = pb - pd, C = pc - pd;
      const double det = A.squaredNorm() * (B.x() * C.y() - B.y() * C.x()) -
                         B.squaredNorm() * (A.x() * C.y() - A.y() * C.x()) +
                         C.squaredNorm() * (A.x() * B.y() - A.y() * B.x());
      const double scale = A.squaredNorm() * B.norm() * C.norm() + 1e-300;
      EXPECT_LE(det / scale, 1e-9) << "edge " << a << "-" << b << " not locally Delaunay";
    }
  }
}

TEST(MeshCdt, ConvexPolygonHasNMinusTwoTriangles) {
  const auto poly = Points(testing::Ellipse(200, 120, 40));
  auto t = TriangulatePolygon(poly);
  ASSERT_TRUE(t.ok()) << t.error().message;
  EXPECT_EQ(t->triangles.size(), poly.size() - 2);
  ExpectValidCdt(poly, *t);
}

TEST(MeshCdt, CocircularRegularPolygon) {
  for (int n : {4, 8, 64, 257}) {
    const auto poly = Points(testing::Ellipse(150, 150, n));
    auto t = TriangulatePolygon(poly);
    ASSERT_TRUE(t.ok());
    EXPECT_EQ(t->triangles.size(), poly.size() - 2) << n;
    ExpectValidCdt(poly, *t);
  }
}

TEST(MeshCdt, CollinearPointsAndJitter) {
  std::mt19937 rng(7);
  for (double jitter : {0.0, 1e-9, 1e-6}) {
    const auto poly = Points(testing::CollinearSquare(rng, 50, 200, jitter));
    auto t = TriangulatePolygon(poly);
    ASSERT_TRUE(t.ok());
    EXPECT_EQ(t->points.size(), poly.size());
    ExpectValidCdt(poly, *t);
  }
}

TEST(MeshCdt, DuplicatesAreMerged) {
  std::mt19937 rng(3);
  const Polygon2 star = testing::Star(rng, 30, 80, 200);
  auto poly = Points(testing::WithDuplicates(star, 3));
  poly.push_back(poly.front());  // repeated closing point
  auto t = TriangulatePolygon(poly);
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(t->points.size(), star.points.size());
  ExpectValidCdt(poly, *t);
}

TEST(MeshCdt, NeckOneNanometreWide) {
  // Two squares joined by a neck 1e-9 wide.
  const double w = 1e-9;
  std::vector<Vec2> poly = {{0, 0}, {1, 0}, {1, 0.5 - w}, {2, 0.5 - w}, {2, 0}, {3, 0},
                            {3, 1}, {2, 1}, {2, 0.5 + w}, {1, 0.5 + w}, {1, 1}, {0, 1}};
  auto t = TriangulatePolygon(poly);
  ASSERT_TRUE(t.ok());
  ExpectValidCdt(poly, *t);
}

TEST(MeshCdt, ConcavePolygonClasses) {
  // A plus sign: its CDT needs junctions or terminals at each arm.
  std::vector<Vec2> plus = {{1, 0}, {2, 0}, {2, 1}, {3, 1}, {3, 2}, {2, 2},
                            {2, 3}, {1, 3}, {1, 2}, {0, 2}, {0, 1}, {1, 1}};
  auto t = TriangulatePolygon(plus);
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(t->triangles.size(), plus.size() - 2);
  ExpectValidCdt(plus, *t);
  int terminal = 0;
  for (auto c : t->classes) terminal += c == TriangleClass::kTerminal;
  EXPECT_GE(terminal, 2);
}

TEST(MeshCdt, SingleTriangleIsIsolated) {
  auto t = TriangulatePolygon({{0, 0}, {1, 0}, {0, 1}});
  ASSERT_TRUE(t.ok());
  ASSERT_EQ(t->triangles.size(), 1u);
  EXPECT_EQ(t->classes[0], TriangleClass::kIsolated);
}

TEST(MeshCdt, ClockwiseInputGivesCounterClockwiseTriangles) {
  auto poly = Points(testing::Ellipse(100, 50, 30));
  std::reverse(poly.begin(), poly.end());
  auto t = TriangulatePolygon(poly);
  ASSERT_TRUE(t.ok());
  ExpectValidCdt(poly, *t);
}

}  // namespace
}  // namespace rheo::mesh
