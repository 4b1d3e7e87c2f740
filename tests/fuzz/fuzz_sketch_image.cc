// libFuzzer target: picture decoders (PNG, JPEG) and the whole raster path to a contour.
#include <cstddef>
#include <cstdint>

#include "fuzz_check.h"
#include "sketch/sketch.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rheo::sketch::ContourOptions o;
  o.max_pixels = 4 * 1024 * 1024;  // keeps each run fast; the limit path is exercised all the same
  auto r = rheo::sketch::ContourFromImage(std::span<const uint8_t>(data, size), o);
  rheo::sketch::fuzz::CheckResult(r);
  return 0;
}
