// Picture input: decoding, binarization, Hilditch thinning, spur removal, boundary tracing.
// Internal; exposed for tests and benchmarks.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"
#include "sketch/sketch.h"

namespace rheo::sketch::internal {

/// 8-bit grey picture, row-major, 0 black .. 255 white.
struct GrayImage {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> pixels;  // (width * height)
};

bool LooksLikePng(std::span<const uint8_t> bytes);
bool LooksLikeJpeg(std::span<const uint8_t> bytes);

/// Decoders; the picture size is checked against max_pixels from the header, before any pixel
/// buffer is allocated. Colour is converted to grey, transparency composited on white.
Result<GrayImage> DecodePng(std::span<const uint8_t> bytes, const ContourOptions& options);
Result<GrayImage> DecodeJpeg(std::span<const uint8_t> bytes, const ContourOptions& options);

/// Binary picture with a one-pixel frame of zeros around it, so 3x3 neighbourhoods of every
/// inner pixel need no bounds checks. Value 1 = ink.
struct Bitmap {
  int width = 0;           // inner width [px]
  int height = 0;          // inner height [px]
  int stride = 0;          // width + 2
  std::vector<uint8_t> v;  // ((width + 2) * (height + 2))

  Bitmap() = default;
  Bitmap(int w, int h) : width(w), height(h), stride(w + 2), v(size_t(w + 2) * (h + 2), 0) {}
  int Index(int x, int y) const { return (y + 1) * stride + (x + 1); }
  uint8_t& at(int x, int y) { return v[Index(x, y)]; }
  uint8_t at(int x, int y) const { return v[Index(x, y)]; }
  int64_t Count() const;
};

/// Otsu's threshold: pixels <= t are one class.
int OtsuThreshold(const uint32_t (&histogram)[256]);

/// Ink mask of a picture. description receives e.g. "otsu(t=131)".
Bitmap Binarize(const GrayImage& image, const ContourOptions& options, std::string* description,
                std::vector<std::string>* warnings);

/// Hilditch thinning (sequential topology check, parallel border conditions per pass), visiting
/// only border pixels and pixels near the last pass's deletions. Returns the number of passes.
int HilditchThin(Bitmap& bitmap);

/// Extra-line elimination (paper 3.3) by the Yokoi 8-connectivity number: 0 (isolated) and 1
/// (end or redundant pixel) are deleted; 2 and 3 only next to a one-pixel hole. Repeated until
/// nothing changes. Returns the number of deleted pixels.
int64_t RemoveSpurs(Bitmap& bitmap);

/// Yokoi 8-connectivity number and neighbour count of pixel (x, y) (tests).
int ConnectivityNumber(const Bitmap& bitmap, int x, int y);

/// Outer boundary of the 8-connected region of non-zero pixels that contains the first such
/// pixel in raster order, as a closed chain of pixel positions (Moore neighbour tracing).
std::vector<std::pair<int, int>> TraceOuterBoundary(const Bitmap& region);

/// Sets every 0 pixel not 4-connected to the frame to `fill`.
void FillEnclosed(Bitmap& bitmap, uint8_t fill);

}  // namespace rheo::sketch::internal
