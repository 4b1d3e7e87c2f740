// Deterministic polygon families for the mesh tests and benchmarks (pixels, any orientation).
#pragma once

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "common/geometry.h"

namespace rheo::mesh::testing {

inline Polygon2 Ellipse(double a, double b, int n, double cx = 256, double cy = 256) {
  Polygon2 p;
  for (int i = 0; i < n; ++i) {
    const double t = 2 * std::numbers::pi * i / n;
    p.points.emplace_back(cx + a * std::cos(t), cy + b * std::sin(t));
  }
  return p;
}

// Star-shaped around the centre: sorted random angles, random radii in [r0, r1].
inline Polygon2 Star(std::mt19937& rng, int n, double r0, double r1) {
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> ang(n);
  for (int i = 0; i < n; ++i) ang[i] = 2 * std::numbers::pi * (i + 0.1 + 0.8 * u(rng)) / n;
  Polygon2 p;
  for (int i = 0; i < n; ++i) {
    const double r = r0 + (r1 - r0) * u(rng);
    p.points.emplace_back(256 + r * std::cos(ang[i]), 256 + r * std::sin(ang[i]));
  }
  return p;
}

// Spikes: alternating outer tips and inner valleys.
inline Polygon2 Spiky(std::mt19937& rng, int spikes, double r_in, double r_out) {
  std::uniform_real_distribution<double> u(0, 1);
  Polygon2 p;
  for (int i = 0; i < 2 * spikes; ++i) {
    const double t = std::numbers::pi * i / spikes;
    const double r = (i % 2 ? r_in * (0.8 + 0.4 * u(rng)) : r_out * (0.85 + 0.15 * u(rng)));
    p.points.emplace_back(256 + r * std::cos(t), 256 + r * std::sin(t));
  }
  return p;
}

// Two round blobs joined by a neck of half-width `neck` [px].
inline Polygon2 Dumbbell(double blob, double gap, double neck, int n) {
  const double c = blob + gap / 2, xmax = c + blob;
  auto w = [&](double x) {
    const double d1 = blob * blob - (x - c) * (x - c), d2 = blob * blob - (x + c) * (x + c);
    return std::max({d1 > 0 ? std::sqrt(d1) : 0.0, d2 > 0 ? std::sqrt(d2) : 0.0, neck});
  };
  Polygon2 p;
  p.points.emplace_back(256 + xmax, 256);
  for (int i = 1; i < n; ++i) {
    const double x = xmax - 2 * xmax * i / n;
    p.points.emplace_back(256 + x, 256 + w(x));
  }
  p.points.emplace_back(256 - xmax, 256);
  for (int i = 1; i < n; ++i) {
    const double x = -xmax + 2 * xmax * i / n;
    p.points.emplace_back(256 + x, 256 - w(x));
  }
  return p;
}

// A square with many collinear points per side, jittered by `jitter` [px].
inline Polygon2 CollinearSquare(std::mt19937& rng, int per_side, double side, double jitter) {
  std::uniform_real_distribution<double> u(-1, 1);
  Polygon2 p;
  const double corners[4][2] = {{0, 0}, {side, 0}, {side, side}, {0, side}};
  for (int s = 0; s < 4; ++s) {
    const double* a = corners[s];
    const double* b = corners[(s + 1) % 4];
    for (int i = 0; i < per_side; ++i) {
      const double t = static_cast<double>(i) / per_side;
      p.points.emplace_back(100 + a[0] + t * (b[0] - a[0]) + jitter * u(rng),
                            100 + a[1] + t * (b[1] - a[1]) + jitter * u(rng));
    }
  }
  return p;
}

// Each point repeated `times` times in a row.
inline Polygon2 WithDuplicates(const Polygon2& in, int times) {
  Polygon2 p;
  for (const Vec2& q : in.points)
    for (int k = 0; k < times; ++k) p.points.push_back(q);
  return p;
}

// Family `i` of the property set (deterministic).
inline Polygon2 PropertyPolygon(int i, std::string* family = nullptr) {
  std::mt19937 rng(1000003u * static_cast<unsigned>(i) + 17u);
  std::uniform_real_distribution<double> u(0, 1);
  auto name = [&](const char* s) {
    if (family) *family = s;
  };
  switch (i % 8) {
    case 0:
    case 1:
      name("star");
      return Star(rng, 8 + static_cast<int>(u(rng) * 120), 60 + 60 * u(rng), 150 + 100 * u(rng));
    case 2:
    case 3:
      name("spiky");
      return Spiky(rng, 3 + static_cast<int>(u(rng) * 14), 40 + 50 * u(rng), 160 + 90 * u(rng));
    case 4:
      name("neck");
      return Dumbbell(50 + 60 * u(rng), 20 + 80 * u(rng), 0.5 + 15 * u(rng),
                      40 + static_cast<int>(u(rng) * 160));
    case 5:
      name("cocircular");
      return Ellipse(80 + 150 * u(rng),
                     80 + 150 * u(rng) * (i % 16 == 5 ? 0 : 1) + (i % 16 == 5 ? 0 : 0),
                     6 + static_cast<int>(u(rng) * 300));
    case 6:
      name("collinear");
      return CollinearSquare(rng, 2 + static_cast<int>(u(rng) * 60), 100 + 250 * u(rng),
                             u(rng) < 0.5 ? 0.0 : 1e-7);
    default: {
      name("duplicates");
      return WithDuplicates(Star(rng, 10 + static_cast<int>(u(rng) * 60), 80, 200),
                            2 + (i / 8) % 3);
    }
  }
}

inline bool ReadContour(const std::string& path, Polygon2& out) {
  std::ifstream f(path);
  if (!f) return false;
  nlohmann::json j = nlohmann::json::parse(f);
  for (const auto& p : j.at("contour"))
    out.points.emplace_back(p[0].get<double>(), p[1].get<double>());
  return true;
}

// The cases of samples/ (samples/README.md).
inline const char* kSampleNames[] = {"bean",  "ellipse",  "fish",    "letter_c", "mitten",
                                     "star5", "dumbbell", "octopus", "spiral",   "overdraw",
                                     "gaps",  "pear",     "heart"};

}  // namespace rheo::mesh::testing
