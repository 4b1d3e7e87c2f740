// Uniform hash grid over face centroids, kept current by re-binning a fixed number of faces per
// tick (round robin), so that a tick's cost does not depend on the surface size.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "common/geometry.h"

namespace rheo::haptics::internal {

/// Each face lives in exactly one cell, the one holding its centroid when it was last binned.
/// A face whose vertices have moved at most `s` since its binning has every point within
/// `reach_bound() + s` of its binned centroid; Query() callers widen the radius accordingly.
class SurfaceGrid {
 public:
  /// Allocates and bins every face at `x` at time `time` [s]. `cell` is the cell edge [m].
  void Build(std::span<const std::array<int32_t, 3>> tris, std::span<const Vec3> x, double cell,
             double time);

  /// Re-bins the next `budget` faces (wrapping) at their current positions. No allocation.
  void Rebin(std::span<const std::array<int32_t, 3>> tris, std::span<const Vec3> x, int32_t budget,
             double time);

  /// Appends to `out` (whose capacity must hold every face) each face binned in a cell that meets
  /// the cube of half-edge `radius` around `center`; scans every face instead when that is cheaper.
  void Query(const Vec3& center, double radius, std::vector<int32_t>& out) const;

  /// Age of the oldest binning at time `time` [s].
  double staleness(double time) const { return time - bin_time_[cursor_]; }
  /// Largest centroid-to-vertex distance over the faces, as binned [m].
  double reach_bound() const { return std::max(reach_cur_, reach_prev_); }
  double cell_size() const { return cell_; }
  int32_t face_count() const { return static_cast<int32_t>(cell_of_.size()); }
  /// Faces per full sweep divided by the budget, rounded up: ticks for every face to be re-binned.
  int32_t SweepTicks(int32_t budget) const { return (face_count() + budget - 1) / budget; }

 private:
  void Bin(int32_t f, std::span<const std::array<int32_t, 3>> tris, std::span<const Vec3> x,
           double time);
  uint32_t Slot(const std::array<int32_t, 3>& c) const;
  void Unlink(int32_t f);
  void Link(int32_t f, const std::array<int32_t, 3>& c);

  double cell_ = 1.0;                            // cell edge [m]
  double inv_cell_ = 1.0;                        // [1/m]
  uint32_t mask_ = 0;                            // hash table size - 1
  std::vector<int32_t> head_;                    // first face of each slot, -1 if none (table)
  std::vector<int32_t> next_, prev_;             // intrusive doubly linked slot lists (m)
  std::vector<std::array<int32_t, 3>> cell_of_;  // integer cell of each face (m)
  std::vector<double> bin_time_;                 // when each face was binned [s] (m)
  int32_t cursor_ = 0;                           // next face to re-bin
  double reach_cur_ = 0.0;   // largest reach binned in the sweep in progress [m]
  double reach_prev_ = 0.0;  // largest reach binned in the previous sweep [m]
};

}  // namespace rheo::haptics::internal
