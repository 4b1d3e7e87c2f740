// Teddy: pruning, chordal axis, final triangulation typed by spine points, elevation.
#include <gtest/gtest.h>

#include "mesh/internal.h"
#include "mesh/mesh.h"
#include "test_polygons.h"

namespace rheo::mesh {
namespace {

double Area(const Vec2& a, const Vec2& b, const Vec2& c) {
  return 0.5 * ((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
}

struct TeddyRun {
  internal::Cdt cdt;
  TeddyTriangulation teddy;
  double polygon_area = 0;
};

TeddyRun RunTeddy(const Polygon2& px, double thickness = 1.0) {
  TeddyRun r;
  auto m = internal::ContourToMetres(px, 1.0);
  EXPECT_TRUE(m.ok());
  for (size_t i = 0; i < m->size(); ++i) {
    const Vec2 &u = (*m)[i], &v = (*m)[(i + 1) % m->size()];
    r.polygon_area += 0.5 * (u.x() * v.y() - v.x() * u.y());
  }
  auto c = internal::TriangulateWithNeighbors(*m);
  EXPECT_TRUE(c.ok());
  r.cdt = *c;
  auto t = internal::BuildTeddy(r.cdt, thickness);
  EXPECT_TRUE(t.ok()) << t.error().message;
  if (t.ok()) r.teddy = *t;
  return r;
}

// The final triangulation tiles the polygon with positive triangles, each with 1..3 spine
// points; contour vertices stay at height 0 and spine vertices rise.
void ExpectValidTeddy(const TeddyRun& r) {
  const auto& t = r.teddy;
  ASSERT_EQ(t.triangles.size(), t.spine_count.size());
  double area = 0;
  for (size_t k = 0; k < t.triangles.size(); ++k) {
    const auto& tr = t.triangles[k];
    const double a = Area(t.points[tr[0]], t.points[tr[1]], t.points[tr[2]]);
    EXPECT_GT(a, 0) << "triangle " << k;
    area += a;
    int spines = 0;
    for (int v : tr) spines += t.is_spine[v];
    EXPECT_EQ(spines, t.spine_count[k]);
    EXPECT_GE(spines, 1);
  }
  EXPECT_NEAR(area, r.polygon_area, 1e-9 * r.polygon_area);
  for (size_t v = 0; v < t.points.size(); ++v) {
    if (t.is_spine[v])
      EXPECT_GT(t.heights[v], 0);
    else
      EXPECT_EQ(t.heights[v], 0);
  }
  for (const auto& e : t.spine_edges) {
    EXPECT_TRUE(t.is_spine[e[0]] && t.is_spine[e[1]]);
  }
}

TEST(MeshTeddy, EllipseSpineHeightIsHalfWidth) {
  const double a = 200, b = 80;
  TeddyRun r = RunTeddy(testing::Ellipse(a, b, 120));
  ExpectValidTeddy(r);
  double hmax = 0;
  for (double h : r.teddy.heights) hmax = std::max(hmax, h);
  // The chordal axis of an ellipse lies on its major axis; its height is the half-width.
  EXPECT_GT(hmax, 0.85 * b);
  EXPECT_LT(hmax, 1.25 * b);
  for (size_t v = 0; v < r.teddy.points.size(); ++v)
    if (r.teddy.is_spine[v]) {
      EXPECT_LT(std::abs(r.teddy.points[v].y() + 256), 0.35 * b);
    }
  EXPECT_GE(r.teddy.pruned_branches, 2);  // both round ends are pruned into fans
}

TEST(MeshTeddy, ThicknessScalesHeights) {
  TeddyRun r1 = RunTeddy(testing::Ellipse(150, 90, 60), 1.0);
  TeddyRun r2 = RunTeddy(testing::Ellipse(150, 90, 60), 2.5);
  ASSERT_EQ(r1.teddy.heights.size(), r2.teddy.heights.size());
  for (size_t i = 0; i < r1.teddy.heights.size(); ++i)
    EXPECT_NEAR(r2.teddy.heights[i], 2.5 * r1.teddy.heights[i], 1e-12);
}

TEST(MeshTeddy, PlusShapeHasJunctionAndThreeSpineTriangles) {
  // Arms long enough that the centre stays a junction (not all pruned).
  Polygon2 plus;
  const double L = 300, W = 40;
  const double pts[12][2] = {{W, -L}, {W, -W}, {L, -W}, {L, W},   {W, W},   {W, L},
                             {-W, L}, {-W, W}, {-L, W}, {-L, -W}, {-W, -W}, {-W, -L}};
  // Dense sampling so the CDT has sleeves along the arms.
  for (int i = 0; i < 12; ++i) {
    const double* a = pts[i];
    const double* b = pts[(i + 1) % 12];
    const int n = static_cast<int>(std::hypot(b[0] - a[0], b[1] - a[1]) / 20) + 1;
    for (int k = 0; k < n; ++k)
      plus.points.emplace_back(a[0] + (b[0] - a[0]) * k / n, a[1] + (b[1] - a[1]) * k / n);
  }
  TeddyRun r = RunTeddy(plus);
  ExpectValidTeddy(r);
  int junctions = 0;
  for (auto c : r.cdt.tri.classes) junctions += c == TriangleClass::kJunction;
  EXPECT_GE(junctions, 1);
  int types[4] = {0, 0, 0, 0};
  for (auto c : r.teddy.spine_count) ++types[c];
  EXPECT_GT(types[1], 0);
  EXPECT_GT(types[2], 0);
  // Arms are W wide: the spine along them sits about W above the contour.
  double hmax = 0;
  for (double h : r.teddy.heights) hmax = std::max(hmax, h);
  EXPECT_GT(hmax, 0.8 * W);
}

TEST(MeshTeddy, TriangleContourIsFannedAroundItsCentre) {
  TeddyRun r = RunTeddy(Polygon2{{{0, 0}, {100, 0}, {50, 80}}});
  ExpectValidTeddy(r);
  EXPECT_EQ(r.teddy.triangles.size(), 3u);
}

TEST(MeshTeddy, HeightFieldIsZeroOnContourAndMatchesSpine) {
  TeddyRun r = RunTeddy(testing::Ellipse(180, 100, 80));
  internal::HeightField h(r.teddy);
  for (size_t v = 0; v < r.teddy.points.size(); ++v)
    EXPECT_NEAR(h(r.teddy.points[v]), r.teddy.heights[v], 1e-9 * 100) << v;
  // Along a spine-to-contour edge the profile is a quarter ellipse: at a quarter of the way
  // from the contour the height is h * sqrt(1 - 0.75^2).
  for (size_t k = 0; k < r.teddy.triangles.size(); ++k) {
    if (r.teddy.spine_count[k] != 1) continue;
    const auto& tr = r.teddy.triangles[k];
    int s = 0;
    while (!r.teddy.is_spine[tr[s]]) ++s;
    const Vec2 p = r.teddy.points[tr[(s + 1) % 3]] * 0.75 + r.teddy.points[tr[s]] * 0.25;
    EXPECT_NEAR(h(p), r.teddy.heights[tr[s]] * std::sqrt(1 - 0.75 * 0.75), 1e-6 * 100);
  }
}

TEST(MeshTeddy, PropertyPolygonsGiveValidFinalTriangulations) {
  for (int i = 0; i < 200; ++i) {
    SCOPED_TRACE(i);
    TeddyRun r = RunTeddy(testing::PropertyPolygon(i));
    ExpectValidTeddy(r);
  }
}

}  // namespace
}  // namespace rheo::mesh
