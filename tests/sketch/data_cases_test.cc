// The stroke cases of tests/sketch/data (written by make_cases.py): within epsilon +
// line_width / 2 + 1 px of their truth, like the shared samples.
#include <gtest/gtest.h>

#include <filesystem>

#include "sketch/polyline.h"
#include "sketch/sketch.h"
#include "test_util.h"

namespace rheo::sketch {
namespace {

TEST(SketchDataCases, EveryCaseWithinTolerance) {
  const std::filesystem::path dir = RHEO_SKETCH_TEST_DATA;
  int cases = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    const std::string file = entry.path().filename().string();
    const std::string suffix = ".truth.json";
    if (file.size() <= suffix.size() ||
        file.compare(file.size() - suffix.size(), suffix.size(), suffix) != 0) {
      continue;
    }
    const std::string name = file.substr(0, file.size() - suffix.size());
    auto truth = testing::ReadTruth(entry.path().string());
    auto json = testing::ReadFile((dir / (name + ".json")).string());
    ASSERT_TRUE(truth && json) << name;
    auto r = ContourFromStrokesJson(*json, ContourOptions{});
    ASSERT_TRUE(r.ok()) << name << ": " << r.error().message;
    const double h = SymmetricHausdorff(r->contour.points, truth->contour);
    EXPECT_LE(h, r->epsilon_px + truth->line_width / 2 + 1) << name;
    EXPECT_GT(internal::SignedArea(r->contour.points), 0.0) << name;
    EXPECT_FALSE(internal::FindSelfCrossing(r->contour.points)) << name;
    std::printf("%-24s hausdorff %.2f px, %zu vertices, %zu repairs\n", name.c_str(), h,
                r->contour.points.size(), r->repairs.size());
    ++cases;
  }
  EXPECT_GE(cases, 3);
}

}  // namespace
}  // namespace rheo::sketch
