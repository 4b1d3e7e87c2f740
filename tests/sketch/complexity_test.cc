// Work that a sketch can ask for: stroke counts that used to take minutes, the complexity limits,
// and cancellation through the token inside every long loop.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <ctime>
#include <random>
#include <set>

#include "sketch/sketch.h"
#include "test_util.h"

namespace rheo::sketch {
namespace {

// `n` two-point strokes of 3..12 px in random directions, their starts within 40 px of the
// canvas centre: every stroke is within joining reach of every other.
std::string ClusteredStrokes(int n, uint32_t seed = 7) {
  std::mt19937 rng(seed);
  auto u = [&] { return rng() / 4294967296.0; };
  std::vector<std::vector<Vec2>> strokes;
  for (int k = 0; k < n; ++k) {
    const double r = 40.0 * std::sqrt(u()), phi = 2.0 * M_PI * u();
    const Vec2 a(256.0 + r * std::cos(phi), 256.0 + r * std::sin(phi));
    const double len = 3.0 + 9.0 * u(), dir = 2.0 * M_PI * u();
    strokes.push_back({a, a + len * Vec2(std::cos(dir), std::sin(dir))});
  }
  return testing::StrokesJson(512, 512, strokes);
}

// A circle of radius 200 drawn as `n` overlapping arcs of 5 points, in a shuffled order, every
// other one drawn backwards.
std::string CircleOfStrokes(int n) {
  std::vector<std::vector<Vec2>> strokes;
  for (int k = 0; k < n; ++k) {
    std::vector<Vec2> arc;
    for (int i = 0; i <= 4; ++i) {
      const double a = 2.0 * M_PI * (k + 1.5 * i / 4.0) / n;
      arc.emplace_back(256.0 + 200.0 * std::cos(a), 256.0 + 200.0 * std::sin(a));
    }
    if (k % 2) std::reverse(arc.begin(), arc.end());
    strokes.push_back(arc);
  }
  std::mt19937 rng(3);
  std::shuffle(strokes.begin(), strokes.end(), rng);
  return testing::StrokesJson(512, 512, strokes);
}

double CpuSeconds() {
  return double(std::clock()) / CLOCKS_PER_SEC;
}

// Before the stroke merge used a grid, 8,000 clustered strokes took over 100 s (cubic in the
// stroke count). The bound is 20 times what it takes now on one slow core.
TEST(SketchComplexity, ClusteredStrokeBombEndsQuickly) {
  const std::string json = ClusteredStrokes(8000);
  const double t0 = CpuSeconds();
  auto r = ContourFromStrokesJson(json, {});
  const double cpu = CpuSeconds() - t0;
  EXPECT_LT(cpu, 10.0) << "8000 clustered strokes took " << cpu << " s of CPU";
  if (!r.ok()) {
    EXPECT_NE(r.error().code, ErrorCode::kInternal) << r.error().message;
  } else {
    EXPECT_GE(r->contour.points.size(), 3u);
  }
}

TEST(SketchComplexity, CircleOfManyStrokesMergesIntoTheCircle) {
  const std::string json = CircleOfStrokes(8000);
  const double t0 = CpuSeconds();
  auto r = ContourFromStrokesJson(json, {});
  const double cpu = CpuSeconds() - t0;
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_LT(cpu, 10.0) << "a circle of 8000 strokes took " << cpu << " s of CPU";
  EXPECT_NEAR(r->area_px2, M_PI * 200.0 * 200.0, 0.01 * M_PI * 200.0 * 200.0);
  EXPECT_TRUE(r->warnings.empty()) << r->warnings.front();
}

TEST(SketchComplexity, TooManyStrokesAreRefusedNamingTheLimit) {
  ContourOptions o;
  o.max_strokes = 100;
  auto r = ContourFromStrokesJson(ClusteredStrokes(101), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kResourceExhausted);
  EXPECT_NE(r.error().message.find("101 strokes"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("max_strokes"), std::string::npos) << r.error().message;
  EXPECT_TRUE(ContourFromStrokesJson(ClusteredStrokes(100), o).ok() ||
              ContourFromStrokesJson(ClusteredStrokes(100), o).error().code !=
                  ErrorCode::kResourceExhausted);
}

TEST(SketchComplexity, TooDetailedOutlineIsRefusedNamingTheLimit) {
  ContourOptions o;
  o.max_contour_points = 50;
  auto star = testing::Star({256, 256}, 200, 120, 40, 4000);
  star.push_back(star[0]);
  auto r = ContourFromStrokesJson(testing::StrokesJson(512, 512, {star}), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kResourceExhausted);
  EXPECT_NE(r.error().message.find("max_contour_points"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("limit of 50"), std::string::npos) << r.error().message;
}

TEST(SketchComplexity, CancelledTokenStopsStrokesAndPictures) {
  std::atomic<bool> cancelled{true};
  ContourOptions o;
  o.cancel = CancelToken(&cancelled);
  auto r = ContourFromStrokesJson(ClusteredStrokes(8000), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kCancelled) << r.error().message;

  testing::Picture p = testing::Blank(512, 512);
  testing::InkPolyline(p, testing::Ellipse({256, 256}, 150, 100, 400), true, 4.0);
  const auto png = testing::EncodePng(p);
  auto img = ContourFromImage({png.data(), png.size()}, o);
  ASSERT_FALSE(img.ok());
  EXPECT_EQ(img.error().code, ErrorCode::kCancelled) << img.error().message;
  cancelled = false;
  EXPECT_TRUE(ContourFromImage({png.data(), png.size()}, o).ok());
}

// A deadline that passes at the k-th look: whatever k, the extraction stops with
// kDeadlineExceeded naming the stage, or (k past its last look) finishes. Over all k it stops in
// several different stages, and the looks come often: the bomb is looked at thousands of times.
struct CountingDeadline {
  int64_t looks = 0;
  int64_t expire_at = 0;
  static bool Expired(const void* self) {
    auto* d = const_cast<CountingDeadline*>(static_cast<const CountingDeadline*>(self));
    return ++d->looks >= d->expire_at;
  }
};

TEST(SketchComplexity, DeadlineStopsEveryStage) {
  for (const bool picture : {false, true}) {
    std::string json;
    std::vector<uint8_t> png;
    if (picture) {
      testing::Picture p = testing::Blank(400, 400);
      testing::InkPolyline(p, testing::Star({200, 200}, 150, 90, 6, 600), true, 5.0);
      png = testing::EncodePng(p);
    } else {
      json = CircleOfStrokes(3000);
    }
    auto run = [&](CountingDeadline& d) {
      ContourOptions o;
      o.cancel = CancelToken(nullptr, &CountingDeadline::Expired, &d);
      return picture ? ContourFromImage({png.data(), png.size()}, o)
                     : ContourFromStrokesJson(json, o);
    };
    CountingDeadline never{0, int64_t(1) << 60};
    ASSERT_TRUE(run(never).ok()) << (picture ? "picture" : "strokes");
    const int64_t total = never.looks;
    EXPECT_GE(total, picture ? 6 : 1000) << "looks at the token";
    std::set<std::string> stages;
    // Every look near the end (the stages after the merge look a few times each), a sample
    // of the rest.
    const int64_t step = std::max<int64_t>(1, total / 100);
    for (int64_t k = 1; k <= total; k += (k < total - 30 ? step : 1)) {
      CountingDeadline d{0, k};
      auto r = run(d);
      ASSERT_FALSE(r.ok()) << "expired at look " << k << " of " << total;
      EXPECT_EQ(r.error().code, ErrorCode::kDeadlineExceeded) << r.error().message;
      stages.insert(r.error().message);
    }
    EXPECT_GE(stages.size(), picture ? 4u : 3u) << (picture ? "picture" : "strokes");
  }
}

}  // namespace
}  // namespace rheo::sketch
