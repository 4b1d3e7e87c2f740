// Helpers for sketch tests: file reading, truth loading, synthetic sketches (strokes and pictures).
#pragma once

#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "common/geometry.h"

namespace rheo::sketch::testing {

std::optional<std::string> ReadFile(const std::string& path);

struct Truth {
  std::vector<Vec2> contour;  // closed polygon [px]
  double line_width = 0.0;    // [px]
};
std::optional<Truth> ReadTruth(const std::string& path);

/// A closed curve given as a dense polygon [px].
std::vector<Vec2> Ellipse(Vec2 c, double rx, double ry, int n, double phase = 0.0);
std::vector<Vec2> Star(Vec2 c, double r_out, double r_in, int lobes, int n);
/// A C-shaped outline (annulus sector boundary), closed.
std::vector<Vec2> LetterC(Vec2 c, double r_out, double r_in, double opening_rad, int n);

/// Stroke JSON from strokes.
std::string StrokesJson(int width, int height, const std::vector<std::vector<Vec2>>& strokes);

/// Grey picture (0 black .. 255 white), row-major.
struct Picture {
  int width = 0, height = 0;
  std::vector<uint8_t> px;
};
Picture Blank(int w, int h, uint8_t paper = 255);
/// Inks a closed or open polyline with a round pen of the given width, anti-aliased.
void InkPolyline(Picture& p, const std::vector<Vec2>& pts, bool closed, double width,
                 uint8_t ink = 20);
/// Fills a closed polygon (even-odd), anti-aliased by 4x4 supersampling.
void FillPolygon(Picture& p, const std::vector<Vec2>& poly, uint8_t ink = 20);
/// Multiplies the picture by a light falloff and adds Gaussian noise (a photo of paper).
void UnevenLight(Picture& p, double darkest, double noise_sigma, std::mt19937& rng);

std::vector<uint8_t> EncodePng(const Picture& p);
std::vector<uint8_t> EncodeJpeg(const Picture& p, int quality);

/// CRC-32 as PNG chunks use it (ISO 3309), for tests that edit PNG bytes.
uint32_t Crc32(const uint8_t* p, size_t n);

}  // namespace rheo::sketch::testing
