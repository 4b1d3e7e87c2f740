#include "haptics/surface_grid.h"

#include <algorithm>
#include <cmath>

namespace rheo::haptics::internal {
namespace {

int32_t CellCoord(double v, double inv_cell) {
  const double c = std::floor(v * inv_cell);
  return static_cast<int32_t>(std::clamp(c, -1.0e9, 1.0e9));
}

}  // namespace

void SurfaceGrid::Build(std::span<const std::array<int32_t, 3>> tris, std::span<const Vec3> x,
                        double cell, double time) {
  const size_t m = tris.size();
  cell_ = cell;
  inv_cell_ = 1.0 / cell;
  uint32_t size = 64;
  while (size < 2 * m) size *= 2;
  mask_ = size - 1;
  head_.assign(size, -1);
  next_.assign(m, -1);
  prev_.assign(m, -1);
  cell_of_.assign(m, {0, 0, 0});
  bin_time_.assign(m, time);
  cursor_ = 0;
  reach_cur_ = reach_prev_ = 0.0;
  for (size_t f = 0; f < m; ++f) {
    Link(static_cast<int32_t>(f), {0, 0, 0});
    Bin(static_cast<int32_t>(f), tris, x, time);
  }
  reach_prev_ = reach_cur_;
}

uint32_t SurfaceGrid::Slot(const std::array<int32_t, 3>& c) const {
  const uint32_t h = static_cast<uint32_t>(c[0]) * 73856093u ^
                     static_cast<uint32_t>(c[1]) * 19349663u ^
                     static_cast<uint32_t>(c[2]) * 83492791u;
  return h & mask_;
}

void SurfaceGrid::Unlink(int32_t f) {
  if (prev_[f] >= 0) {
    next_[prev_[f]] = next_[f];
  } else {
    head_[Slot(cell_of_[f])] = next_[f];
  }
  if (next_[f] >= 0) prev_[next_[f]] = prev_[f];
  next_[f] = prev_[f] = -1;
}

void SurfaceGrid::Link(int32_t f, const std::array<int32_t, 3>& c) {
  cell_of_[f] = c;
  const uint32_t s = Slot(c);
  next_[f] = head_[s];
  prev_[f] = -1;
  if (head_[s] >= 0) prev_[head_[s]] = f;
  head_[s] = f;
}

void SurfaceGrid::Bin(int32_t f, std::span<const std::array<int32_t, 3>> tris,
                      std::span<const Vec3> x, double time) {
  const auto& t = tris[f];
  const Vec3& a = x[t[0]];
  const Vec3& b = x[t[1]];
  const Vec3& c = x[t[2]];
  const Vec3 centroid = (a + b + c) / 3.0;
  const double reach = std::sqrt(std::max(
      {(a - centroid).squaredNorm(), (b - centroid).squaredNorm(), (c - centroid).squaredNorm()}));
  reach_cur_ = std::max(reach_cur_, reach);
  const std::array<int32_t, 3> cell = {CellCoord(centroid.x(), inv_cell_),
                                       CellCoord(centroid.y(), inv_cell_),
                                       CellCoord(centroid.z(), inv_cell_)};
  if (cell != cell_of_[f]) {
    Unlink(f);
    Link(f, cell);
  }
  bin_time_[f] = time;
}

void SurfaceGrid::Rebin(std::span<const std::array<int32_t, 3>> tris, std::span<const Vec3> x,
                        int32_t budget, double time) {
  const int32_t m = face_count();
  const int32_t n = std::min(budget, m);
  for (int32_t i = 0; i < n; ++i) {
    Bin(cursor_, tris, x, time);
    if (++cursor_ == m) {
      cursor_ = 0;
      reach_prev_ = reach_cur_;
      reach_cur_ = 0.0;
    }
  }
}

void SurfaceGrid::Query(const Vec3& center, double radius, std::vector<int32_t>& out) const {
  std::array<int32_t, 3> lo, hi;
  double cells = 1.0;
  for (int k = 0; k < 3; ++k) {
    lo[k] = CellCoord(center[k] - radius, inv_cell_);
    hi[k] = CellCoord(center[k] + radius, inv_cell_);
    cells *= static_cast<double>(hi[k] - lo[k] + 1);
  }
  const int32_t m = face_count();
  if (cells >= static_cast<double>(m)) {
    for (int32_t f = 0; f < m; ++f) {
      const auto& c = cell_of_[f];
      if (c[0] >= lo[0] && c[0] <= hi[0] && c[1] >= lo[1] && c[1] <= hi[1] && c[2] >= lo[2] &&
          c[2] <= hi[2]) {
        out.push_back(f);
      }
    }
    return;
  }
  for (int32_t i = lo[0]; i <= hi[0]; ++i) {
    for (int32_t j = lo[1]; j <= hi[1]; ++j) {
      for (int32_t k = lo[2]; k <= hi[2]; ++k) {
        const std::array<int32_t, 3> c = {i, j, k};
        for (int32_t f = head_[Slot(c)]; f >= 0; f = next_[f]) {
          if (cell_of_[f] == c) out.push_back(f);
        }
      }
    }
  }
}

}  // namespace rheo::haptics::internal
