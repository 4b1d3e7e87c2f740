// Closed test surfaces (voxel solids, lat-long spheres) and brute-force geometric truth.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <set>
#include <tuple>
#include <vector>

#include "common/geometry.h"

namespace rheo::haptics::testing {

/// Boundary of a union of axis-aligned voxels of edge `h` [m] with its minimum corner at `origin`,
/// two triangles per exposed voxel face, outward.
inline TriSurface VoxelSurface(const std::set<std::array<int, 3>>& voxels, double h,
                               const Vec3& origin) {
  TriSurface s;
  std::map<std::array<int, 3>, int32_t> index;
  auto vid = [&](std::array<int, 3> c) {
    auto [it, inserted] = index.emplace(c, static_cast<int32_t>(s.positions.size()));
    if (inserted) s.positions.push_back(origin + h * Vec3(c[0], c[1], c[2]));
    return it->second;
  };
  for (const auto& v : voxels) {
    for (int axis = 0; axis < 3; ++axis) {
      for (int side = 0; side < 2; ++side) {
        std::array<int, 3> nb = v;
        nb[axis] += side == 0 ? -1 : 1;
        if (voxels.count(nb)) continue;
        const int u = (axis + 1) % 3, w = (axis + 2) % 3;  // e_u x e_w = e_axis
        std::array<int, 3> c0 = v;
        c0[axis] += side;
        std::array<int, 3> c1 = c0, c2 = c0, c3 = c0;
        c1[u] += 1;
        c2[u] += 1;
        c2[w] += 1;
        c3[w] += 1;
        int32_t a = vid(c0), b = vid(c1), c = vid(c2), d = vid(c3);
        if (side == 0) std::swap(b, d);  // facing -axis
        s.triangles.push_back({a, b, c});
        s.triangles.push_back({a, c, d});
      }
    }
  }
  return s;
}

/// Box of nx x ny x nz voxels of edge h [m].
inline TriSurface BoxSurface(int nx, int ny, int nz, double h, const Vec3& origin) {
  std::set<std::array<int, 3>> v;
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j)
      for (int k = 0; k < nz; ++k) v.insert({i, j, k});
  return VoxelSurface(v, h, origin);
}

/// Latitude-longitude sphere: `lon` segments around, `lat` bands; 2 lon (lat - 1) triangles.
inline TriSurface SphereSurface(const Vec3& center, double radius, int lat, int lon) {
  TriSurface s;
  const double pi = std::numbers::pi;
  s.positions.push_back(center + Vec3(0, 0, radius));
  for (int i = 1; i < lat; ++i) {
    const double th = pi * i / lat;
    for (int j = 0; j < lon; ++j) {
      const double ph = 2 * pi * j / lon;
      s.positions.push_back(center + radius * Vec3(std::sin(th) * std::cos(ph),
                                                   std::sin(th) * std::sin(ph), std::cos(th)));
    }
  }
  s.positions.push_back(center + Vec3(0, 0, -radius));
  const int32_t south = static_cast<int32_t>(s.positions.size()) - 1;
  auto ring = [&](int i, int j) { return 1 + (i - 1) * lon + (j % lon); };
  for (int j = 0; j < lon; ++j) s.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i < lat - 1; ++i) {
    for (int j = 0; j < lon; ++j) {
      s.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      s.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  }
  for (int j = 0; j < lon; ++j)
    s.triangles.push_back({south, ring(lat - 1, j + 1), ring(lat - 1, j)});
  return s;
}

/// Generalised winding number of the closed surface at p (1 inside, 0 outside).
inline double WindingNumber(const std::vector<std::array<int32_t, 3>>& tris,
                            const std::vector<Vec3>& x, const Vec3& p) {
  double total = 0.0;
  for (const auto& t : tris) {
    const Vec3 a = x[t[0]] - p, b = x[t[1]] - p, c = x[t[2]] - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    total += 2.0 * std::atan2(num, den);
  }
  return total / (4.0 * std::numbers::pi);
}

/// Distance from p to the nearest triangle, by brute force (Ericson's closest point repeated
/// here independently: projection onto the plane, else onto the three edges).
inline double DistanceToSurface(const std::vector<std::array<int32_t, 3>>& tris,
                                const std::vector<Vec3>& x, const Vec3& p) {
  auto seg = [](const Vec3& q, const Vec3& a, const Vec3& b) {
    const Vec3 ab = b - a;
    const double t = std::clamp((q - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    return (a + t * ab - q).norm();
  };
  double best = 1e300;
  for (const auto& t : tris) {
    const Vec3 &a = x[t[0]], &b = x[t[1]], &c = x[t[2]];
    const Vec3 n = (b - a).cross(c - a).normalized();
    const Vec3 q = p - n * n.dot(p - a);
    // Inside test by edge half-planes.
    const bool in = n.dot((b - a).cross(q - a)) >= 0 && n.dot((c - b).cross(q - b)) >= 0 &&
                    n.dot((a - c).cross(q - c)) >= 0;
    double d = in ? std::abs(n.dot(p - a)) : std::min({seg(p, a, b), seg(p, b, c), seg(p, c, a)});
    best = std::min(best, d);
  }
  return best;
}

}  // namespace rheo::haptics::testing
