// Cases generated here, each with its truth polygon: noisy and overdrawn strokes, gaps, thick
// lines, filled silhouettes, a photo with uneven light and JPEG compression, several shapes.
#include <gtest/gtest.h>

#include <random>

#include "sketch/format.h"
#include "sketch/polyline.h"
#include "sketch/sketch.h"
#include "test_util.h"

namespace rheo::sketch {
namespace {

using testing::Picture;

std::span<const uint8_t> Bytes(const std::vector<uint8_t>& v) {
  return {v.data(), v.size()};
}

bool Mentions(const std::vector<std::string>& lines, const std::string& word) {
  for (const auto& l : lines)
    if (l.find(word) != std::string::npos) return true;
  return false;
}

// Slices a closed curve into strokes that overlap by `overlap` points at their joins, with noise.
std::vector<std::vector<Vec2>> Strokes(const std::vector<Vec2>& curve, int pieces, int overlap,
                                       double sigma, std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, sigma);
  const int len = static_cast<int>(curve.size());
  std::vector<std::vector<Vec2>> out;
  for (int k = 0; k < pieces; ++k) {
    const int a = k * len / pieces, b = (k + 1) * len / pieces + overlap;
    std::vector<Vec2> s;
    for (int i = a; i <= b; ++i) s.push_back(curve[i % len] + Vec2(n(rng), n(rng)));
    out.push_back(std::move(s));
  }
  return out;
}

void ExpectWithin(const Result<ContourResult>& r, const std::vector<Vec2>& truth, double lw,
                  const char* what) {
  ASSERT_TRUE(r.ok()) << what << ": " << r.error().message;
  const double h = SymmetricHausdorff(r->contour.points, truth);
  EXPECT_LE(h, r->epsilon_px + lw / 2 + 1.0) << what;
  EXPECT_GT(internal::SignedArea(r->contour.points), 0.0) << what;
  EXPECT_FALSE(internal::FindSelfCrossing(r->contour.points)) << what;
  std::printf("%-34s hausdorff %.2f px (bound %.2f), %zu vertices\n", what, h,
              r->epsilon_px + lw / 2 + 1.0, r->contour.points.size());
}

TEST(SketchSyntheticStrokes, NoisyOverlappingStrokesInShuffledDirections) {
  std::mt19937 rng(11);
  auto truth = testing::Star({256, 256}, 180, 110, 5, 1400);
  auto strokes = Strokes(truth, 4, 25, 0.6, rng);
  std::reverse(strokes[1].begin(), strokes[1].end());  // drawn the other way
  std::swap(strokes[0], strokes[2]);                   // and out of order
  auto r = ContourFromStrokesJson(testing::StrokesJson(512, 512, strokes), ContourOptions{});
  ExpectWithin(r, truth, 2.0, "strokes: noisy, 4 overlapping");
  EXPECT_TRUE(Mentions(r->repairs, "joined strokes")) << "joins are reported";
}

TEST(SketchSyntheticStrokes, OvershootAtTheCloseIsTrimmed) {
  auto truth = testing::Ellipse({256, 256}, 150, 90, 900);
  std::vector<Vec2> s(truth.begin(), truth.end());
  for (int i = 0; i < 60; ++i) s.push_back(truth[i] + Vec2(0, 3.0 * i / 60));  // runs on past
  auto r = ContourFromStrokesJson(testing::StrokesJson(512, 512, {s}), ContourOptions{});
  ExpectWithin(r, truth, 2.0, "strokes: overshoot at the close");
  EXPECT_NEAR(r->perimeter_px, internal::ClosedLength(truth), 0.02 * internal::ClosedLength(truth));
}

TEST(SketchSyntheticStrokes, SmallGapIsClosedAndReportedWithWhere) {
  auto truth = testing::Ellipse({256, 256}, 150, 90, 1000);
  std::vector<Vec2> s(truth.begin(), truth.end() - 20);  // 2 % of the perimeter missing
  auto r = ContourFromStrokesJson(testing::StrokesJson(512, 512, {s}), ContourOptions{});
  ExpectWithin(r, truth, 2.0, "strokes: 2 % gap");
  ASSERT_TRUE(Mentions(r->repairs, "closed a gap of")) << ::testing::PrintToString(r->repairs);
  EXPECT_TRUE(Mentions(r->repairs, "between (")) << r->repairs[0];
}

TEST(SketchSyntheticStrokes, GapOverTheLimitIsRefusedWithItsEnds) {
  auto ring = testing::Ellipse({256, 256}, 150, 90, 1000);
  std::vector<Vec2> s(ring.begin(), ring.end() - 80);  // about 8 % missing
  auto r = ContourFromStrokesJson(testing::StrokesJson(512, 512, {s}), ContourOptions{});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(r.error().message.find("not closed: gap of"), std::string::npos) << r.error().message;
  // The ends are named: the last and first points drawn.
  EXPECT_NE(r.error().message.find(internal::Pt(s.front())), std::string::npos)
      << r.error().message;
  ContourOptions lenient;
  lenient.max_gap_fraction = 0.12;
  EXPECT_TRUE(ContourFromStrokesJson(testing::StrokesJson(512, 512, {s}), lenient).ok());
}

TEST(SketchSyntheticStrokes, RetracedStretchIsMerged) {
  // One stroke around, then a second stroke retracing 150 points of it with an offset of 1 px.
  std::mt19937 rng(5);
  auto truth = testing::Ellipse({256, 256}, 170, 120, 1200);
  std::vector<Vec2> a(truth.begin(), truth.end());
  a.push_back(truth[0]);
  std::vector<Vec2> b;
  for (int i = 300; i < 450; ++i) b.push_back(truth[i] + Vec2(1.0, 0.5));
  auto r = ContourFromStrokesJson(testing::StrokesJson(512, 512, {a, b}), ContourOptions{});
  ExpectWithin(r, truth, 2.0, "strokes: retraced stretch");
  EXPECT_TRUE(Mentions(r->warnings, "open stroke") || Mentions(r->repairs, "joined"))
      << "the extra stroke is either ignored or merged, and said so";
}

TEST(SketchSyntheticStrokes, SeveralShapesKeepTheLargestAndNameTheOthers) {
  auto big = testing::Ellipse({300, 300}, 150, 100, 800);
  auto small = testing::Ellipse({60, 60}, 30, 30, 200);
  std::vector<Vec2> b(big.begin(), big.end()), s(small.begin(), small.end());
  b.push_back(big[0]);
  s.push_back(small[0]);
  auto r = ContourFromStrokesJson(testing::StrokesJson(512, 512, {s, b}), ContourOptions{});
  ExpectWithin(r, big, 2.0, "strokes: two shapes");
  EXPECT_TRUE(Mentions(r->warnings, "several shapes")) << ::testing::PrintToString(r->warnings);
  EXPECT_TRUE(Mentions(r->warnings, "(30,30)")) << ::testing::PrintToString(r->warnings);
}

TEST(SketchSyntheticStrokes, FigureEightIsRepairedOrRefusedWithTheCrossing) {
  // A lemniscate-like curve with a big and a small lobe crossing at (256, 256).
  std::vector<Vec2> eight;
  for (int i = 0; i < 800; ++i) {
    const double t = 2 * M_PI * i / 800;
    const double sx = std::sin(t) > 0 ? 150 : 60;
    eight.emplace_back(256 + sx * std::sin(t), 256 + 0.6 * sx * std::sin(t) * std::cos(t));
  }
  eight.push_back(eight[0]);
  auto json = testing::StrokesJson(512, 512, {eight});
  auto r = ContourFromStrokesJson(json, ContourOptions{});
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_TRUE(Mentions(r->repairs, "self-crossing at (256,256)"))
      << ::testing::PrintToString(r->repairs);
  for (const auto& p : r->contour.points) EXPECT_GE(p.x(), 255.0);  // the big lobe only
  ContourOptions strict;
  strict.repair_self_crossing = false;
  auto s = ContourFromStrokesJson(json, strict);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("self-crossing outline at (256,256)"), std::string::npos)
      << s.error().message;
}

// Pictures.

TEST(SketchSyntheticPictures, ThickLines) {
  for (double lw : {8.0, 14.0}) {
    Picture p = testing::Blank(512, 512);
    auto truth = testing::Star({256, 256}, 200, 120, 5, 1500);
    testing::InkPolyline(p, truth, true, lw);
    auto r = ContourFromImage(Bytes(testing::EncodePng(p)), ContourOptions{});
    ExpectWithin(r, truth, lw, lw < 10 ? "png: 8 px line" : "png: 14 px line");
    EXPECT_NEAR(r->line_width_px, lw, 0.3 * lw);
  }
}

TEST(SketchSyntheticPictures, FilledSilhouetteGivesItsEdge) {
  Picture p = testing::Blank(512, 512);
  auto truth = testing::Star({256, 256}, 200, 120, 5, 1500);
  testing::FillPolygon(p, truth);
  auto r = ContourFromImage(Bytes(testing::EncodePng(p)), ContourOptions{});
  ExpectWithin(r, truth, 0.0, "png: filled silhouette");
  EXPECT_TRUE(r->filled_silhouette);
  const double area = std::abs(internal::SignedArea(truth));
  EXPECT_NEAR(r->area_px2, area, 0.02 * area);
}

TEST(SketchSyntheticPictures, PhotoWithUnevenLightAndJpeg) {
  std::mt19937 rng(21);
  Picture p = testing::Blank(640, 480, 230);
  auto truth = testing::Star({320, 240}, 200, 140, 3, 1500);
  std::normal_distribution<double> n(0.0, 0.5);
  std::vector<Vec2> drawn = truth;
  for (auto& q : drawn) q += Vec2(n(rng), n(rng));
  testing::InkPolyline(p, drawn, true, 5.0, 50);
  testing::UnevenLight(p, 0.3, 4.0, rng);
  auto r = ContourFromImage(Bytes(testing::EncodeJpeg(p, 70)), ContourOptions{});
  ExpectWithin(r, truth, 5.0, "jpeg: photo, uneven light");
  EXPECT_EQ(r->binarization.rfind("adaptive", 0), 0u) << r->binarization;
  EXPECT_EQ(r->kind, SketchKind::kJpeg);
}

TEST(SketchSyntheticPictures, SmallGapInTheLineIsClosed) {
  Picture p = testing::Blank(512, 512);
  auto truth = testing::Ellipse({256, 256}, 180, 120, 1500);
  std::vector<Vec2> open(truth.begin(), truth.end() - 25);  // ~1.7 % gap
  testing::InkPolyline(p, open, false, 4.0);
  auto r = ContourFromImage(Bytes(testing::EncodePng(p)), ContourOptions{});
  ExpectWithin(r, truth, 4.0, "png: 1.7 % gap");
  EXPECT_TRUE(Mentions(r->repairs, "closed a gap of"));
  std::vector<Vec2> wide(truth.begin(), truth.end() - 150);  // 10 %
  Picture q = testing::Blank(512, 512);
  testing::InkPolyline(q, wide, false, 4.0);
  auto e = ContourFromImage(Bytes(testing::EncodePng(q)), ContourOptions{});
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().message.find("not closed: gap of"), std::string::npos) << e.error().message;
}

TEST(SketchSyntheticPictures, OverdrawnDoubleLineGivesOneOutline) {
  Picture p = testing::Blank(512, 512);
  auto truth = testing::Ellipse({256, 256}, 180, 120, 1500);
  auto second = truth;
  for (auto& q : second) q += Vec2(4.0, 1.5);  // a second pass, 4 px off
  testing::InkPolyline(p, truth, true, 3.0);
  testing::InkPolyline(p, second, true, 3.0);
  auto r = ContourFromImage(Bytes(testing::EncodePng(p)), ContourOptions{});
  ExpectWithin(r, truth, 3.0 + 4.3, "png: overdrawn twice, 4 px apart");
}

TEST(SketchSyntheticPictures, SpursAndSpecksAreIgnored) {
  Picture p = testing::Blank(512, 512);
  auto truth = testing::Ellipse({256, 256}, 180, 120, 1500);
  testing::InkPolyline(p, truth, true, 4.0);
  testing::InkPolyline(p, {{436, 256}, {480, 250}}, false, 4.0);  // stroke run on past the line
  testing::InkPolyline(p, {{256, 136}, {250, 170}}, false, 4.0);  // one into the inside
  testing::InkPolyline(p, {{20, 20}, {21, 21}}, false, 2.0);      // a speck
  auto r = ContourFromImage(Bytes(testing::EncodePng(p)), ContourOptions{});
  ExpectWithin(r, truth, 4.0, "png: spurs and a speck");
}

TEST(SketchSyntheticPictures, HoleInsideTheOutlineIsIgnoredWithAWarning) {
  Picture p = testing::Blank(512, 512);
  auto truth = testing::Ellipse({256, 256}, 200, 140, 1500);
  testing::InkPolyline(p, truth, true, 4.0);
  auto hole = testing::Ellipse({256, 256}, 60, 40, 500);
  testing::InkPolyline(p, hole, true, 4.0);
  testing::InkPolyline(p, {{256, 116}, {256, 216}}, false, 4.0);  // joined to the outline
  auto r = ContourFromImage(Bytes(testing::EncodePng(p)), ContourOptions{});
  ExpectWithin(r, truth, 4.0, "png: inner loop");
  EXPECT_TRUE(Mentions(r->warnings, "inner loops ignored"))
      << ::testing::PrintToString(r->warnings);
}

TEST(SketchSyntheticPictures, SeveralShapesKeepTheLargest) {
  Picture p = testing::Blank(512, 512);
  auto big = testing::Ellipse({300, 300}, 170, 110, 1500);
  testing::InkPolyline(p, big, true, 4.0);
  testing::InkPolyline(p, testing::Ellipse({60, 60}, 40, 30, 300), true, 4.0);
  auto r = ContourFromImage(Bytes(testing::EncodePng(p)), ContourOptions{});
  ExpectWithin(r, big, 4.0, "png: two shapes");
  EXPECT_TRUE(Mentions(r->warnings, "several shapes")) << ::testing::PrintToString(r->warnings);
}

TEST(SketchSyntheticPictures, LargePictureMatchesTheSmallOneScaled) {
  // 2048 x 2048 with a 16 px line: the same shape as the 512 case, scaled by 4.
  Picture p = testing::Blank(2048, 2048);
  auto truth = testing::Star({1024, 1024}, 800, 480, 5, 4000);
  testing::InkPolyline(p, truth, true, 16.0);
  auto r = ContourFromImage(Bytes(testing::EncodePng(p)), ContourOptions{});
  ExpectWithin(r, truth, 16.0, "png: 2048 x 2048, 16 px line");
}

}  // namespace
}  // namespace rheo::sketch
