// Picture input: decoding, binarization, Hilditch thinning, spur removal, boundary tracing.
// Internal; exposed for tests and benchmarks.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
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
/// Stops between passes (unfinished) when `cancel` asks to.
int HilditchThin(Bitmap& bitmap, const CancelToken& cancel = CancelToken());

/// Extra-line elimination (paper 3.3) by the Yokoi 8-connectivity number: 0 (isolated) and 1
/// (end or redundant pixel) are deleted; 2 and 3 only next to a one-pixel hole. Repeated until
/// nothing changes. Returns the number of deleted pixels.
int64_t RemoveSpurs(Bitmap& bitmap, const CancelToken& cancel = CancelToken());

/// Yokoi 8-connectivity number and neighbour count of pixel (x, y) (tests).
int ConnectivityNumber(const Bitmap& bitmap, int x, int y);

/// Outer boundary of the 8-connected region of non-zero pixels that contains the first such
/// pixel in raster order, as a closed chain of pixel positions (Moore neighbour tracing).
std::vector<std::pair<int, int>> TraceOuterBoundary(const Bitmap& region);

/// Sets every 0 pixel not 4-connected to the frame to `fill`.
void FillEnclosed(Bitmap& bitmap, uint8_t fill);

/// Span flood fill: turns the 4-connected region of `from` pixels around seed (an index into
/// bm.v) into `to`, calling on_span(row_index, x_first, x_last, edges) per filled run (padded x),
/// where edges counts the 4-neighbours of the run that are neither `from` nor `to` (when
/// kCountEdges; else 0).
template <bool kCountEdges, typename OnSpan>
void SpanFill(Bitmap& bm, int seed, uint8_t from, uint8_t to, OnSpan on_span) {
  const int s = bm.stride, rows = bm.height + 2;
  uint8_t* v = bm.v.data();
  std::vector<int> stack = {seed};
  while (!stack.empty()) {
    const int i = stack.back();
    stack.pop_back();
    if (v[i] != from) continue;
    const int y = i / s, row = y * s;
    int xl = i - row, xr = xl;
    while (xl > 0 && v[row + xl - 1] == from) --xl;
    while (xr < s - 1 && v[row + xr + 1] == from) ++xr;
    std::fill(v + row + xl, v + row + xr + 1, to);
    int edges = 0;
    if constexpr (kCountEdges) {
      edges = (xl > 0 && v[row + xl - 1] != to) + (xr < s - 1 && v[row + xr + 1] != to);
    }
    for (int ny : {y - 1, y + 1}) {
      if (ny < 0 || ny >= rows) continue;
      uint8_t* nrow = v + ny * s;
      const int len = xr - xl + 1;
      if constexpr (kCountEdges) {
        edges += len - static_cast<int>(std::count(nrow + xl, nrow + xr + 1, from)) -
                 static_cast<int>(std::count(nrow + xl, nrow + xr + 1, to));
      }
      // Seed each run of `from` in the neighbour row once.
      int x = xl;
      while (x <= xr) {
        const void* hit = std::memchr(nrow + x, from, xr - x + 1);
        if (!hit) break;
        x = static_cast<int>(static_cast<const uint8_t*>(hit) - nrow);
        stack.push_back(ny * s + x);
        while (x <= xr && nrow[x] == from) ++x;
      }
    }
    on_span(row, xl, xr, edges);
  }
}

}  // namespace rheo::sketch::internal
