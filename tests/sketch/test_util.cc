#include "test_util.h"

// clang-format off
#include <cstddef>
#include <cstdio>  // jpeglib.h needs size_t and FILE first
#include <jpeglib.h>
// clang-format on
#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sketch/polyline.h"

namespace rheo::sketch::testing {

std::optional<std::string> ReadFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return std::nullopt;
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::optional<Truth> ReadTruth(const std::string& path) {
  auto text = ReadFile(path);
  if (!text) return std::nullopt;
  auto j = nlohmann::json::parse(*text);
  Truth t;
  for (const auto& p : j.at("contour"))
    t.contour.emplace_back(p.at(0).get<double>(), p.at(1).get<double>());
  t.line_width = j.at("line_width").get<double>();
  return t;
}

std::vector<Vec2> Ellipse(Vec2 c, double rx, double ry, int n, double phase) {
  std::vector<Vec2> p;
  for (int i = 0; i < n; ++i) {
    const double a = phase + 2 * M_PI * i / n;
    p.emplace_back(c.x() + rx * std::cos(a), c.y() + ry * std::sin(a));
  }
  return p;
}

std::vector<Vec2> Star(Vec2 c, double r_out, double r_in, int lobes, int n) {
  std::vector<Vec2> p;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    const double r = r_in + (r_out - r_in) * 0.5 * (1 + std::cos(lobes * a));
    p.emplace_back(c.x() + r * std::cos(a), c.y() + r * std::sin(a));
  }
  return p;
}

std::vector<Vec2> LetterC(Vec2 c, double ro, double ri, double open, int n) {
  std::vector<Vec2> p;
  const double a0 = open / 2, a1 = 2 * M_PI - open / 2;
  for (int i = 0; i <= n; ++i) {
    const double a = a0 + (a1 - a0) * i / n;
    p.emplace_back(c.x() + ro * std::cos(a), c.y() + ro * std::sin(a));
  }
  const double rm = 0.5 * (ro - ri);
  const Vec2 e1 = c + 0.5 * (ro + ri) * Vec2(std::cos(a1), std::sin(a1));
  for (int i = 1; i < 12; ++i) {  // round end cap
    const double a = a1 + M_PI * i / 12;
    p.push_back(e1 + rm * Vec2(std::cos(a), std::sin(a)));
  }
  for (int i = 0; i <= n; ++i) {
    const double a = a1 - (a1 - a0) * i / n;
    p.emplace_back(c.x() + ri * std::cos(a), c.y() + ri * std::sin(a));
  }
  const Vec2 e0 = c + 0.5 * (ro + ri) * Vec2(std::cos(a0), std::sin(a0));
  for (int i = 1; i < 12; ++i) {
    const double a = a0 + M_PI + M_PI * i / 12;
    p.push_back(e0 + rm * Vec2(std::cos(a), std::sin(a)));
  }
  return p;
}

std::string StrokesJson(int width, int height, const std::vector<std::vector<Vec2>>& strokes) {
  nlohmann::json j;
  j["width"] = width;
  j["height"] = height;
  j["strokes"] = nlohmann::json::array();
  for (const auto& s : strokes) {
    auto a = nlohmann::json::array();
    for (const auto& p : s) a.push_back({p.x(), p.y()});
    j["strokes"].push_back(a);
  }
  return j.dump();
}

Picture Blank(int w, int h, uint8_t paper) {
  return {w, h, std::vector<uint8_t>(size_t(w) * h, paper)};
}

void InkPolyline(Picture& p, const std::vector<Vec2>& pts, bool closed, double width, uint8_t ink) {
  const double r = width / 2;
  const size_t n = pts.size();
  const size_t edges = closed ? n : n - 1;
  for (size_t i = 0; i < edges; ++i) {
    const Vec2 a = pts[i], b = pts[(i + 1) % n];
    const int x0 = std::max(0, int(std::floor(std::min(a.x(), b.x()) - r - 1)));
    const int x1 = std::min(p.width - 1, int(std::ceil(std::max(a.x(), b.x()) + r + 1)));
    const int y0 = std::max(0, int(std::floor(std::min(a.y(), b.y()) - r - 1)));
    const int y1 = std::min(p.height - 1, int(std::ceil(std::max(a.y(), b.y()) + r + 1)));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double d = internal::PointSegmentDistance(Vec2(x + 0.5, y + 0.5), a, b);
        const double cover = std::clamp(r + 0.5 - d, 0.0, 1.0);
        if (cover <= 0) continue;
        uint8_t& q = p.px[size_t(y) * p.width + x];
        const double val = 255.0 - cover * (255.0 - ink);
        q = std::min<uint8_t>(q, static_cast<uint8_t>(std::lround(val)));
      }
    }
  }
}

void FillPolygon(Picture& p, const std::vector<Vec2>& poly, uint8_t ink) {
  double minx = 1e9, miny = 1e9, maxx = -1e9, maxy = -1e9;
  for (const auto& q : poly) {
    minx = std::min(minx, q.x()), maxx = std::max(maxx, q.x());
    miny = std::min(miny, q.y()), maxy = std::max(maxy, q.y());
  }
  const size_t n = poly.size();
  for (int y = std::max(0, int(miny) - 1); y <= std::min(p.height - 1, int(maxy) + 1); ++y) {
    for (int x = std::max(0, int(minx) - 1); x <= std::min(p.width - 1, int(maxx) + 1); ++x) {
      int inside = 0;
      for (int sy = 0; sy < 4; ++sy) {
        for (int sx = 0; sx < 4; ++sx) {
          const double px = x + (sx + 0.5) / 4, py = y + (sy + 0.5) / 4;
          bool in = false;
          for (size_t i = 0, j = n - 1; i < n; j = i++) {
            const Vec2 &a = poly[i], &b = poly[j];
            if ((a.y() > py) != (b.y() > py) &&
                px < (b.x() - a.x()) * (py - a.y()) / (b.y() - a.y()) + a.x()) {
              in = !in;
            }
          }
          inside += in;
        }
      }
      if (!inside) continue;
      const double cover = inside / 16.0;
      uint8_t& q = p.px[size_t(y) * p.width + x];
      q = std::min<uint8_t>(q, static_cast<uint8_t>(std::lround(255.0 - cover * (255.0 - ink))));
    }
  }
}

void UnevenLight(Picture& p, double darkest, double sigma, std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, sigma);
  for (int y = 0; y < p.height; ++y) {
    for (int x = 0; x < p.width; ++x) {
      // Light from the top-left corner, falling off to `darkest` at the far corner.
      const double t = (double(x) / p.width + double(y) / p.height) / 2;
      const double gain = 1.0 - (1.0 - darkest) * t * t;
      uint8_t& q = p.px[size_t(y) * p.width + x];
      q = static_cast<uint8_t>(std::clamp(q * gain + noise(rng), 0.0, 255.0));
    }
  }
}

std::vector<uint8_t> EncodePng(const Picture& p) {
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  image.width = p.width;
  image.height = p.height;
  image.format = PNG_FORMAT_GRAY;
  png_alloc_size_t size = 0;
  png_image_write_to_memory(&image, nullptr, &size, 0, p.px.data(), p.width, nullptr);
  std::vector<uint8_t> out(size);
  png_image_write_to_memory(&image, out.data(), &size, 0, p.px.data(), p.width, nullptr);
  out.resize(size);
  return out;
}

std::vector<uint8_t> EncodeJpeg(const Picture& p, int quality) {
  jpeg_compress_struct c;
  jpeg_error_mgr err;
  c.err = jpeg_std_error(&err);
  jpeg_create_compress(&c);
  unsigned char* buf = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&c, &buf, &size);
  c.image_width = p.width;
  c.image_height = p.height;
  c.input_components = 1;
  c.in_color_space = JCS_GRAYSCALE;
  jpeg_set_defaults(&c);
  jpeg_set_quality(&c, quality, TRUE);
  jpeg_start_compress(&c, TRUE);
  while (c.next_scanline < c.image_height) {
    JSAMPROW row = const_cast<uint8_t*>(p.px.data() + size_t(c.next_scanline) * p.width);
    jpeg_write_scanlines(&c, &row, 1);
  }
  jpeg_finish_compress(&c);
  std::vector<uint8_t> out(buf, buf + size);
  jpeg_destroy_compress(&c);
  free(buf);
  return out;
}

uint32_t Crc32(const uint8_t* p, size_t n) {
  uint32_t c = 0xFFFFFFFFu;
  for (size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

}  // namespace rheo::sketch::testing
