// Recursive-split vectorization (paper 3.4), resampling and self-crossing detection.
#include "sketch/polyline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sketch/sketch.h"
#include "test_util.h"

namespace rheo::sketch::internal {
namespace {

TEST(SketchPolyline, SignedAreaOfUnitSquareIsPositiveCounterClockwise) {
  std::vector<Vec2> sq = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  EXPECT_DOUBLE_EQ(SignedArea(sq), 1.0);
  std::reverse(sq.begin(), sq.end());
  EXPECT_DOUBLE_EQ(SignedArea(sq), -1.0);
  EXPECT_DOUBLE_EQ(ClosedLength(sq), 4.0);
}

TEST(SketchPolyline, SimplifyKeepsEveryPointWithinEpsilonOfItsEdge) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 0.7);
  auto ring = testing::Ellipse({200, 150}, 120, 70, 900);
  for (auto& p : ring) p += Vec2(n(rng), n(rng));
  for (double eps : {0.5, 1.0, 2.0, 4.0}) {
    double hmax = -1;
    const auto idx = SimplifyClosed(ring, eps, &hmax);
    ASSERT_GE(idx.size(), 3u);
    EXPECT_LE(hmax, eps);
    // Independent check: every chain point against the edge spanning it.
    for (size_t k = 0; k < idx.size(); ++k) {
      const int a = idx[k];
      const int b = k + 1 < idx.size() ? idx[k + 1] : static_cast<int>(ring.size());
      for (int i = a; i < b; ++i) {
        EXPECT_LE(PointSegmentDistance(ring[i], ring[a], ring[b % ring.size()]), eps + 1e-12);
      }
    }
  }
}

TEST(SketchPolyline, SimplifyOfPolygonWithCornersFindsTheCorners) {
  // A dense square (4 px spacing): the recursive split must keep exactly its 4 corners.
  std::vector<Vec2> dense;
  const Vec2 c[4] = {{10, 10}, {110, 10}, {110, 110}, {10, 110}};
  for (int e = 0; e < 4; ++e)
    for (int k = 0; k < 25; ++k) dense.push_back(c[e] + (c[(e + 1) % 4] - c[e]) * (k / 25.0));
  double h;
  const auto idx = SimplifyClosed(dense, 0.5, &h);
  ASSERT_EQ(idx.size(), 4u);
  for (int i : idx) EXPECT_EQ(i % 25, 0);
  EXPECT_NEAR(h, 0.0, 1e-9);
}

TEST(SketchPolyline, VertexCountFallsAsEpsilonGrowsOnACircle) {
  // Closed form: a chord of a radius-R circle deviates by R (1 - cos(theta / 2)).
  const double R = 100;
  auto circle = testing::Ellipse({0, 0}, R, R, 3600);
  size_t last = 1u << 30;
  for (double eps : {0.25, 1.0, 4.0}) {
    double h;
    const size_t n = SimplifyClosed(circle, eps, &h).size();
    const double min_n = M_PI / std::acos(1 - eps / R);  // fewest chords within eps
    EXPECT_GE(n, std::floor(min_n));
    EXPECT_LE(n, 2.5 * min_n + 4);
    EXPECT_LT(n, last);
    last = n;
  }
}

TEST(SketchPolyline, ResampleClosedHasEqualSpacing) {
  auto sq = std::vector<Vec2>{{0, 0}, {100, 0}, {100, 50}, {0, 50}};
  auto r = ResampleClosed(sq, 2.0);
  EXPECT_EQ(r.size(), 150u);
  for (size_t i = 0; i + 1 < r.size(); ++i) EXPECT_LE((r[i + 1] - r[i]).norm(), 2.0 + 1e-9);
  EXPECT_NEAR(ClosedLength(r), 300.0, 1e-9);
}

TEST(SketchPolyline, FindsAFigureEightCrossing) {
  std::vector<Vec2> eight = {{0, 0}, {10, 10}, {10, 0}, {0, 10}};
  auto x = FindSelfCrossing(eight);
  ASSERT_TRUE(x);
  EXPECT_NEAR(x->point.x(), 5.0, 1e-12);
  EXPECT_NEAR(x->point.y(), 5.0, 1e-12);
  std::vector<Vec2> sq = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  EXPECT_FALSE(FindSelfCrossing(sq));
}

TEST(SketchPolyline, HausdorffOfConcentricCirclesIsRadiusDifference) {
  auto a = testing::Ellipse({0, 0}, 50, 50, 2000);
  auto b = testing::Ellipse({0, 0}, 53, 53, 2000);
  EXPECT_NEAR(SymmetricHausdorff(a, b), 3.0, 0.01);
}

}  // namespace
}  // namespace rheo::sketch::internal
