// Refusals: each bad sketch gives the right error code and a message that says what and where.
#include <gtest/gtest.h>

#include <cstring>

#include "sketch/raster.h"
#include "sketch/sketch.h"
#include "test_util.h"

namespace rheo::sketch {
namespace {

std::span<const uint8_t> Bytes(const std::vector<uint8_t>& v) {
  return {v.data(), v.size()};
}

void ExpectError(const Result<ContourResult>& r, ErrorCode code, const std::string& needle) {
  ASSERT_FALSE(r.ok()) << "expected an error containing '" << needle << "'";
  EXPECT_EQ(r.error().code, code) << r.error().message;
  EXPECT_NE(r.error().message.find(needle), std::string::npos) << r.error().message;
}

void Put32(uint8_t* p, uint32_t v) {
  p[0] = v >> 24, p[1] = v >> 16, p[2] = v >> 8, p[3] = v;
}

TEST(SketchRefusal, EmptyAndBlankSketchesSayNothingWasDrawn) {
  ExpectError(ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[]})", {}),
              ErrorCode::kInvalidArgument, "nothing drawn");
  ExpectError(ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[[[3,4]]]})", {}),
              ErrorCode::kInvalidArgument, "nothing drawn");
  auto blank = testing::EncodePng(testing::Blank(300, 200));
  ExpectError(ContourFromImage(Bytes(blank), {}), ErrorCode::kInvalidArgument, "nothing drawn");
  ExpectError(ContourFromSketchBytes({}, {}), ErrorCode::kInvalidArgument, "empty");
}

TEST(SketchRefusal, TooSmallShapeNamesItsArea) {
  auto tiny = testing::Ellipse({100, 100}, 5, 4, 60);
  tiny.push_back(tiny[0]);
  ExpectError(ContourFromStrokesJson(testing::StrokesJson(512, 512, {tiny}), {}),
              ErrorCode::kInvalidArgument, "shape too small to mesh: area");
  testing::Picture p = testing::Blank(512, 512);
  testing::InkPolyline(p, testing::Ellipse({100, 100}, 6, 5, 80), true, 2.0);
  ExpectError(ContourFromImage(Bytes(testing::EncodePng(p)), {}), ErrorCode::kInvalidArgument,
              "too small");
}

TEST(SketchRefusal, StrokeJsonErrorsSayWhere) {
  ExpectError(ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[[[1,2],[3]]]})", {}),
              ErrorCode::kInvalidArgument, "strokes[0][1]");
  ExpectError(
      ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[[[1,2]],[[1,"a"]]]})", {}),
      ErrorCode::kInvalidArgument, "strokes[1][0]");
  ExpectError(ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[[[1,2],)", {}),
              ErrorCode::kInvalidArgument, "byte");
  ExpectError(ContourFromStrokesJson(R"({"width":-5,"height":512,"strokes":[]})", {}),
              ErrorCode::kInvalidArgument, "\"width\"");
  ExpectError(ContourFromStrokesJson(R"({"height":512,"strokes":[]})", {}),
              ErrorCode::kInvalidArgument, "width");
  ExpectError(ContourFromStrokesJson(R"([1,2,3])", {}), ErrorCode::kInvalidArgument, "object");
  // Broken JSON is refused with its place, also inside keys that are otherwise ignored, and
  // after the end of the sketch.
  ExpectError(
      ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[[[1,2]]],"x":tru})", {}),
      ErrorCode::kInvalidArgument, "byte 54");
  ExpectError(
      ContourFromStrokesJson(R"({"width":512,"height":512,"pen":{"a":[1,}},"strokes":[]})", {}),
      ErrorCode::kInvalidArgument, "byte 41");
  ExpectError(ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[]} xyz)", {}),
              ErrorCode::kInvalidArgument, "byte 41");
  ExpectError(ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[],"strokes":[]})", {}),
              ErrorCode::kInvalidArgument, "twice");
  ExpectError(ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[[[1,1e999]]]})", {}),
              ErrorCode::kInvalidArgument, "strokes[0][0]");
  ExpectError(ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[[[1,2,3]]]})", {}),
              ErrorCode::kInvalidArgument, "two numbers");
  ExpectError(ContourFromStrokesJson(R"({"width":512,"height":512,"strokes":[5]})", {}),
              ErrorCode::kInvalidArgument, "strokes[0]: expected an array");
  // Unknown keys, nested or not, are skipped.
  auto ring = testing::Ellipse({256, 256}, 100, 80, 400);
  ring.push_back(ring[0]);
  std::string j = testing::StrokesJson(512, 512, {ring});
  j.insert(1, R"("pen":{"colour":[1,2,{"x":[]}],"w":3},)");
  EXPECT_TRUE(ContourFromStrokesJson(j, {}).ok());
}

TEST(SketchRefusal, PointFarOffTheCanvasIsRefusedWithItsPlace) {
  ExpectError(
      ContourFromStrokesJson(
          R"({"width":512,"height":512,"strokes":[[[10,10],[300,20],[139.7,322221.9]]]})", {}),
      ErrorCode::kInvalidArgument, "strokes[0][2]: point (139.7, 322221.9) lies far outside");
}

TEST(SketchRefusal, HugeOutlineIsResampledCoarserWithAWarning) {
  // Three points on a 1e6 px canvas make an outline 2.7 million px long: the work stays bounded.
  auto r = ContourFromStrokesJson(
      R"({"width":1000000,"height":1000000,"strokes":[[[0,0],[900000,0],[450000,800000],[0,0]]]})",
      {});
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_FALSE(r->warnings.empty());
  EXPECT_NE(r->warnings.back().find("resampled every"), std::string::npos) << r->warnings.back();
  EXPECT_GE(r->contour.points.size(), 3u);
}

TEST(SketchRefusal, TooManyStrokePointsIsResourceExhausted) {
  std::string j = R"({"width":512,"height":512,"strokes":[[)";
  for (int i = 0; i < 100001; ++i) j += (i ? ",[" : "[") + std::to_string(i % 500) + ",1]";
  j += "]]}";
  ExpectError(ContourFromStrokesJson(j, {}), ErrorCode::kResourceExhausted, "max_stroke_points");
  ContourOptions small;
  small.max_input_bytes = 1000;
  ExpectError(ContourFromStrokesJson(j, small), ErrorCode::kResourceExhausted, "max_input_bytes");
}

TEST(SketchRefusal, PictureOverThePixelLimitIsRefusedFromTheHeader) {
  // A real 64 x 64 PNG whose header claims 5000 x 4000: refused before any pixel buffer exists.
  auto png = testing::EncodePng(testing::Blank(64, 64));
  ASSERT_EQ(std::memcmp(&png[12], "IHDR", 4), 0);
  Put32(&png[16], 5000);
  Put32(&png[20], 4000);
  Put32(&png[29], testing::Crc32(&png[12], 17));
  ExpectError(ContourFromImage(Bytes(png), {}), ErrorCode::kResourceExhausted, "max_pixels");
  ExpectError(ContourFromImage(Bytes(png), {}), ErrorCode::kResourceExhausted, "5000 x 4000");

  auto jpg = testing::EncodeJpeg(testing::Blank(64, 64), 90);
  bool patched = false;
  for (size_t i = 2; i + 9 < jpg.size(); ++i) {
    if (jpg[i] == 0xFF && jpg[i + 1] == 0xC0) {  // SOF0: length(2) precision(1) height(2) width(2)
      jpg[i + 5] = 0x1F, jpg[i + 6] = 0x40;      // 8000
      jpg[i + 7] = 0x1F, jpg[i + 8] = 0x40;
      patched = true;
      break;
    }
  }
  ASSERT_TRUE(patched);
  ExpectError(ContourFromImage(Bytes(jpg), {}), ErrorCode::kResourceExhausted, "max_pixels");
}

TEST(SketchRefusal, InputOverTheByteLimitIsRefused) {
  std::vector<uint8_t> big(32u * 1024 * 1024 + 1, 0);
  const uint8_t sig[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  std::memcpy(big.data(), sig, 8);
  ExpectError(ContourFromImage(Bytes(big), {}), ErrorCode::kResourceExhausted, "max_input_bytes");
}

TEST(SketchRefusal, CorruptPicturesAreInvalidArgument) {
  testing::Picture p = testing::Blank(128, 128);
  testing::InkPolyline(p, testing::Ellipse({64, 64}, 40, 30, 200), true, 3.0);
  auto png = testing::EncodePng(p);
  std::vector<uint8_t> cut(png.begin(), png.begin() + png.size() / 2);
  ExpectError(ContourFromImage(Bytes(cut), {}), ErrorCode::kInvalidArgument, "corrupt PNG");
  auto bad = png;
  bad[40] ^= 0xFF;  // inside the first chunk: CRC mismatch
  ExpectError(ContourFromImage(Bytes(bad), {}), ErrorCode::kInvalidArgument, "corrupt PNG");
  std::vector<uint8_t> jpg = {0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x02, 0x12, 0x34, 0x56};
  ExpectError(ContourFromImage(Bytes(jpg), {}), ErrorCode::kInvalidArgument, "corrupt JPEG");
  std::vector<uint8_t> gif = {'G', 'I', 'F', '8', '9', 'a', 0, 0};
  ExpectError(ContourFromSketchBytes(Bytes(gif), {}), ErrorCode::kInvalidArgument,
              "unknown sketch format");
}

TEST(SketchRefusal, BadOptionsAreInvalidArgument) {
  ContourOptions o;
  o.epsilon_px = 0.0;
  ExpectError(ContourFromStrokesJson("{}", o), ErrorCode::kInvalidArgument, "epsilon");
}

}  // namespace
}  // namespace rheo::sketch
