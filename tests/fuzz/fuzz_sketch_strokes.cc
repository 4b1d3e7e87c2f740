// libFuzzer target: stroke JSON decoder, stroke merging and vectorization.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_check.h"
#include "sketch/sketch.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rheo::sketch::ContourOptions o;
  auto r = rheo::sketch::ContourFromStrokesJson(
      std::string_view(reinterpret_cast<const char*>(data), size), o);
  rheo::sketch::fuzz::CheckResult(r);
  // Content detection must agree with the direct call on what it accepts.
  auto d = rheo::sketch::ContourFromSketchBytes(std::span<const uint8_t>(data, size), o);
  rheo::sketch::fuzz::CheckResult(d);
  return 0;
}
