// Accuracy on the shared sample sketches: from the stroke JSON and from the picture, the contour
// lies within epsilon + line_width / 2 + 1 px (symmetric Hausdorff) of the truth polygon.
#include <gtest/gtest.h>

#include <filesystem>

#include "sketch/polyline.h"
#include "sketch/sketch.h"
#include "test_util.h"

namespace rheo::sketch {
namespace {

using testing::ReadFile;
using testing::ReadTruth;

class SketchSample : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    dir_ = RHEO_SKETCH_SAMPLES;
    if (!std::filesystem::exists(dir_ + "/" + GetParam() + ".truth.json")) {
      GTEST_SKIP() << "sample sketches not found in " << dir_;
    }
    truth_ = *ReadTruth(dir_ + "/" + GetParam() + ".truth.json");
  }

  void Check(const Result<ContourResult>& r, const char* source) {
    ASSERT_TRUE(r.ok()) << source << ": " << r.error().message;
    const auto& c = r->contour.points;
    ASSERT_GE(c.size(), 3u);
    EXPECT_GT(internal::SignedArea(c), 0.0) << "contour must be counter-clockwise";
    EXPECT_FALSE(internal::FindSelfCrossing(c).has_value());
    const double h = SymmetricHausdorff(c, truth_.contour);
    const double bound = r->epsilon_px + truth_.line_width / 2 + 1.0;
    EXPECT_LE(h, bound) << GetParam() << " from " << source;
    // Within epsilon of the drawn line, except where a self-crossing loop of the line was cut off.
    bool cut = false;
    for (const auto& m : r->repairs) cut = cut || m.find("self-crossing") != std::string::npos;
    EXPECT_LE(r->line_distance_px, cut ? bound : r->epsilon_px + 1e-9);
    const double area_truth = std::abs(internal::SignedArea(truth_.contour));
    EXPECT_NEAR(r->area_px2, area_truth, 0.05 * area_truth);
    std::printf("%-9s %-4s hausdorff %.2f px (bound %.2f)  vertices %zu  repairs %zu\n",
                GetParam().c_str(), source, h, bound, c.size(), r->repairs.size());
  }

  std::string dir_;
  testing::Truth truth_;
};

TEST_P(SketchSample, FromStrokesWithinTolerance) {
  auto json = ReadFile(dir_ + "/" + GetParam() + ".json");
  ASSERT_TRUE(json);
  Check(ContourFromStrokesJson(*json, ContourOptions{}), "json");
}

TEST_P(SketchSample, FromPictureWithinTolerance) {
  auto png = ReadFile(dir_ + "/" + GetParam() + ".png");
  ASSERT_TRUE(png);
  std::span<const uint8_t> bytes(reinterpret_cast<const uint8_t*>(png->data()), png->size());
  Check(ContourFromImage(bytes, ContourOptions{}), "png");
}

TEST_P(SketchSample, ContentDetectionMatchesDirectCalls) {
  for (const char* ext : {".json", ".png"}) {
    auto data = ReadFile(dir_ + "/" + GetParam() + ext);
    ASSERT_TRUE(data);
    std::span<const uint8_t> bytes(reinterpret_cast<const uint8_t*>(data->data()), data->size());
    auto r = ContourFromSketchBytes(bytes, ContourOptions{});
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->kind, std::string(ext) == ".json" ? SketchKind::kStrokes : SketchKind::kPng);
  }
}

TEST_P(SketchSample, TighterEpsilonGivesMoreVerticesAndStaysWithinIt) {
  auto json = ReadFile(dir_ + "/" + GetParam() + ".json");
  ASSERT_TRUE(json);
  ContourOptions fine, coarse;
  fine.epsilon_px = 0.75;
  coarse.epsilon_px = 4.0;
  auto a = ContourFromStrokesJson(*json, fine);
  auto b = ContourFromStrokesJson(*json, coarse);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_GT(a->contour.points.size(), b->contour.points.size());
  EXPECT_LE(a->line_distance_px, 0.75 + truth_.line_width / 2 + 1);
  EXPECT_LE(b->line_distance_px, 4.0 + truth_.line_width / 2 + 1);
  EXPECT_LE(SymmetricHausdorff(b->contour.points, truth_.contour), 4.0 + truth_.line_width / 2 + 1);
}

INSTANTIATE_TEST_SUITE_P(Shared, SketchSample,
                         ::testing::Values("ellipse", "bean", "star5", "letter_c", "fish",
                                           "mitten"));

}  // namespace
}  // namespace rheo::sketch
