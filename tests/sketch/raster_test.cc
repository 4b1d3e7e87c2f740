// Binarization, Hilditch thinning, spur removal and tracing on small pictures with known answers.
#include "sketch/raster.h"

#include <gtest/gtest.h>

#include <random>
#include <set>

#include "sketch/polyline.h"
#include "test_util.h"

namespace rheo::sketch::internal {
namespace {

Bitmap FromRows(const std::vector<std::string>& rows) {
  Bitmap b(static_cast<int>(rows[0].size()), static_cast<int>(rows.size()));
  for (int y = 0; y < b.height; ++y)
    for (int x = 0; x < b.width; ++x) b.at(x, y) = rows[y][x] == '#';
  return b;
}

int Neighbours(const Bitmap& b, int x, int y) {
  int n = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx)
      if ((dx || dy) && b.at(x + dx, y + dy)) ++n;
  return n;
}

// Every ink pixel of a one-pixel closed curve has exactly two 8-neighbours.
void ExpectSimpleLoop(const Bitmap& b) {
  ASSERT_GT(b.Count(), 0);
  for (int y = 0; y < b.height; ++y)
    for (int x = 0; x < b.width; ++x)
      if (b.at(x, y)) {
        EXPECT_EQ(Neighbours(b, x, y), 2) << "at " << x << "," << y;
      }
}

TEST(SketchRaster, OtsuSplitsTwoLevelsBetweenThem) {
  uint32_t h[256] = {};
  h[40] = 1000;
  h[210] = 3000;
  const int t = OtsuThreshold(h);
  EXPECT_GE(t, 40);
  EXPECT_LT(t, 210);
}

TEST(SketchRaster, ConnectivityNumberMatchesYokoiCases) {
  auto b = FromRows({
      ".....",
      ".#.#.",
      "..#..",
      ".....",
      "###..",
  });
  EXPECT_EQ(ConnectivityNumber(b, 2, 2), 2);  // joins two diagonal branches
  EXPECT_EQ(ConnectivityNumber(b, 1, 1), 1);  // end point
  EXPECT_EQ(ConnectivityNumber(b, 1, 4), 2);  // middle of a line
  auto t = FromRows({"#.#", ".#.", "..#"});
  EXPECT_EQ(ConnectivityNumber(t, 1, 1), 3);  // branch point
  auto c = FromRows({"#.#", ".#.", "#.#"});
  EXPECT_EQ(ConnectivityNumber(c, 1, 1), 4);  // crossing
}

TEST(SketchRaster, HilditchThinsAThickRingToAOnePixelLoopNearItsCentreLine) {
  testing::Picture p = testing::Blank(200, 200);
  auto ring = testing::Ellipse({100, 100}, 70, 50, 600);
  testing::InkPolyline(p, ring, true, 9.0);
  internal::GrayImage g{p.width, p.height, p.px};
  std::string desc;
  Bitmap b = Binarize(g, ContourOptions{}, &desc, nullptr);
  const int64_t ink = b.Count();
  const int passes = HilditchThin(b);
  EXPECT_GE(passes, 3);
  EXPECT_LE(passes, 8);
  RemoveSpurs(b);
  ExpectSimpleLoop(b);
  // Skeleton length close to the ellipse perimeter, and every pixel near the centre line.
  EXPECT_NEAR(double(ink) / b.Count(), 9.0, 2.0);
  for (int y = 0; y < b.height; ++y)
    for (int x = 0; x < b.width; ++x)
      if (b.at(x, y)) {
        EXPECT_LE(PointPolygonDistance(Vec2(x + 0.5, y + 0.5), ring), 1.5);
      }
}

TEST(SketchRaster, HilditchKeepsTwoPixelLinesAndConnectivity) {
  auto b = FromRows({
      "..........",
      ".########.",
      ".########.",
      ".##....##.",
      ".##....##.",
      ".########.",
      ".########.",
      "..........",
  });
  HilditchThin(b);
  RemoveSpurs(b);
  ExpectSimpleLoop(b);
  EXPECT_GE(b.Count(), 14);
}

TEST(SketchRaster, SpurRemovalDeletesBranchesAndNoiseButKeepsTheLoop) {
  auto b = FromRows({
      "#...........",
      "....#.......",
      "....#.......",
      "..#######...",
      "..#.....#...",
      "..#.....####",
      "..#.....#...",
      "..#######...",
      "...#........",
      "....#.......",
  });
  const int64_t before = b.Count();
  const int64_t removed = RemoveSpurs(b);
  ExpectSimpleLoop(b);
  EXPECT_EQ(before - removed, b.Count());
  // Noise pixel, the spurs above, right and below are gone; the 20-pixel loop loses at most its
  // four corners (redundant in 8-connectivity).
  // (9,5) may stay: the loop can take it instead of the corner (8,5).
  for (auto [x, y] : {std::pair{0, 0}, {4, 1}, {4, 2}, {10, 5}, {11, 5}, {3, 8}, {4, 9}}) {
    EXPECT_EQ(b.at(x, y), 0) << x << "," << y;
  }
  EXPECT_GE(b.Count(), 16);
  EXPECT_LE(b.Count(), 20);
}

TEST(SketchRaster, SpurRemovalOpensOnePixelHolesInTheLine) {
  // A loop whose line has a one-pixel bubble at the top: connectivity 2 pixels next to the
  // hole are deleted, the loop stays closed.
  auto b = FromRows({
      "....#....",
      "####.####",
      "#...#...#",
      "#.......#",
      "#########",
  });
  RemoveSpurs(b);
  ExpectSimpleLoop(b);
}

TEST(SketchRaster, TraceReturnsEveryPixelOfASquareLoopOnce) {
  auto b = FromRows({
      "......",
      ".####.",
      ".#..#.",
      ".#..#.",
      ".####.",
      "......",
  });
  const auto chain = TraceOuterBoundary(b);
  EXPECT_EQ(chain.size(), 12u);
  std::set<std::pair<int, int>> seen(chain.begin(), chain.end());
  EXPECT_EQ(seen.size(), 12u);
  for (size_t i = 0; i < chain.size(); ++i) {
    const auto [x0, y0] = chain[i];
    const auto [x1, y1] = chain[(i + 1) % chain.size()];
    EXPECT_LE(std::max(std::abs(x1 - x0), std::abs(y1 - y0)), 1);
  }
}

TEST(SketchRaster, FillEnclosedFillsTheInsideOnly) {
  auto b = FromRows({
      "#####.",
      "#...#.",
      "#####.",
  });
  FillEnclosed(b, 1);
  EXPECT_EQ(b.Count(), 15);
  EXPECT_EQ(b.at(5, 1), 0);
}

TEST(SketchRaster, AdaptiveBinarizationSurvivesUnevenLightWhereOtsuFails) {
  testing::Picture p = testing::Blank(256, 256, 235);
  auto ring = testing::Ellipse({128, 128}, 90, 70, 500);
  testing::InkPolyline(p, ring, true, 4.0, 60);
  std::mt19937 rng(3);
  testing::UnevenLight(p, 0.25, 2.0, rng);
  internal::GrayImage g{p.width, p.height, p.px};
  std::string desc;
  ContourOptions adaptive;
  adaptive.binarization = Binarization::kAdaptive;
  Bitmap a = Binarize(g, adaptive, &desc, nullptr);
  ContourOptions otsu;
  otsu.binarization = Binarization::kOtsu;
  Bitmap o = Binarize(g, otsu, &desc, nullptr);
  // Ink pixels far from the line are false ink: the shadowed paper corner.
  auto false_ink = [&](const Bitmap& b) {
    int64_t n = 0;
    for (int y = 0; y < b.height; ++y)
      for (int x = 0; x < b.width; ++x)
        if (b.at(x, y) && PointPolygonDistance(Vec2(x + 0.5, y + 0.5), ring) > 4) ++n;
    return n;
  };
  EXPECT_LT(false_ink(a), 50);
  EXPECT_GT(false_ink(o), 1000);
  ContourOptions auto_mode;
  Binarize(g, auto_mode, &desc, nullptr);
  EXPECT_EQ(desc.rfind("adaptive", 0), 0u) << desc;
}

// A photo of grey paper whose light falls off gently (to 0.6 in the far corner) with grey ink:
// Otsu puts the shadowed paper in with the ink, so the blocks it calls ink are paper in shadow,
// and auto must count them when it measures how uneven the paper is (it chose Otsu before).
TEST(SketchRaster, AutoCountsShadowedPaperBlocksThatOtsuCallsInk) {
  testing::Picture p = testing::Blank(256, 256, 200);
  auto ring = testing::Ellipse({128, 128}, 90, 70, 500);
  testing::InkPolyline(p, ring, true, 4.0, 100);
  std::mt19937 rng(5);
  testing::UnevenLight(p, 0.6, 3.0, rng);
  internal::GrayImage g{p.width, p.height, p.px};
  auto false_ink = [&](const Bitmap& b) {
    int64_t n = 0;
    for (int y = 0; y < b.height; ++y)
      for (int x = 0; x < b.width; ++x)
        if (b.at(x, y) && PointPolygonDistance(Vec2(x + 0.5, y + 0.5), ring) > 4) ++n;
    return n;
  };
  std::string desc;
  ContourOptions otsu;
  otsu.binarization = Binarization::kOtsu;
  EXPECT_GT(false_ink(Binarize(g, otsu, &desc, nullptr)), 1000);
  Bitmap a = Binarize(g, ContourOptions{}, &desc, nullptr);
  EXPECT_EQ(desc.rfind("adaptive", 0), 0u) << desc;
  EXPECT_LT(false_ink(a), 50);
}

// A filled silhouette on evenly lit paper still gets one global threshold: its ink blocks lie a
// jump below the paper, not a continuation of it.
TEST(SketchRaster, AutoKeepsOtsuForAFilledShapeOnEvenPaper) {
  testing::Picture p = testing::Blank(256, 256, 230);
  testing::FillPolygon(p, testing::Ellipse({128, 128}, 100, 80, 400), 30);
  std::mt19937 rng(6);
  testing::UnevenLight(p, 0.97, 2.0, rng);
  internal::GrayImage g{p.width, p.height, p.px};
  std::string desc;
  Binarize(g, ContourOptions{}, &desc, nullptr);
  EXPECT_EQ(desc.rfind("otsu", 0), 0u) << desc;
}

}  // namespace
}  // namespace rheo::sketch::internal
