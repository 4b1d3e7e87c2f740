// Where the haptic tool sits in the scene: the device's workspace placed over a new object, and
// where a press goes. Policy of the device layer, kept out of the API handlers. Pure functions.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"
#include "daemon/loop/engine.h"

namespace rheo::daemon {

/// Clearance between the tool tip and the surface it is placed over [m].
inline constexpr double kToolClearance = 0.005;

/// Width of the vertical columns in which PressPoint measures how much material lies under a
/// point [m].
inline constexpr double kPressColumn = 0.006;

/// The point of an object's surface that a press straight down meets squarely: among the
/// vertices whose (area-weighted) normal is within 30 degrees of straight up and that have at
/// least half as much of the object under them (height above the lowest point of its 6 mm
/// column) as the one with the most, the highest; the highest vertex when none faces up.
/// `triangles` holds 3 indices into `positions` per surface triangle, outward.
Vec3 PressPoint(std::span<const uint32_t> triangles, std::span<const Vec3> positions);

/// The scene position for the device frame's origin when an object enters an empty scene: the
/// tool tip `kToolClearance` above the object's PressPoint (the grip at the frame's centre).
Vec3 WorkspaceOriginOver(std::span<const uint32_t> triangles, std::span<const Vec3> positions,
                         double tip_radius);

/// What a press straight down along the vertical line through `at` meets in `frame`.
struct PressTarget {
  bool found = false;
  uint32_t instance_id = 0;  // the object whose surface is highest there
  double surface_y = 0.0;    // height of that surface on the line [m]
};

/// The top of every object's surface on the vertical line through `at` (its y is ignored):
/// where the line crosses a surface triangle, highest first. `triangles_of(instance_id)` gives
/// the object's surface (3 indices a triangle into its frame vertices; empty when unknown).
template <typename TrianglesOf>
PressTarget FindPressTarget(const LoopFrame& frame, const Vec3& at, TrianglesOf triangles_of);

/// Height of the surface `triangles` over `xyz` (x, y, z floats per vertex, `count` vertices)
/// where the vertical line through (x, z) crosses it, highest crossing; false when it misses.
bool SurfaceTopOnLine(std::span<const uint32_t> triangles, const float* xyz, uint32_t count,
                      double x, double z, double* y);

template <typename TrianglesOf>
PressTarget FindPressTarget(const LoopFrame& frame, const Vec3& at, TrianglesOf triangles_of) {
  PressTarget out;
  for (uint32_t i = 0; i < frame.object_count; ++i) {
    const FrameObject& fo = frame.objects[i];
    double y = 0.0;
    if (!SurfaceTopOnLine(triangles_of(fo.instance_id), frame.positions.data() + 3u * fo.first,
                          fo.vertex_count, at.x(), at.z(), &y))
      continue;
    if (!out.found || y > out.surface_y) {
      out.found = true;
      out.surface_y = y;
      out.instance_id = fo.instance_id;
    }
  }
  return out;
}

/// A press of the emulated hand as waypoints of the grip in the device frame, in two phases: the
/// first in the current workspace placement, then (when `replace_origin`) the workspace is
/// moved to `new_origin` (the tool jumps, at a height above every object, to above the press
/// line), and the second phase goes down from there.
struct PressPlan {
  struct Waypoint {
    double duration = 0.0;  // time to reach it from the previous one [s]
    Vec3 grip = Vec3::Zero();
  };
  std::vector<Waypoint> before;  // from the grip's current position (not listed)
  bool replace_origin = false;
  Vec3 new_origin = Vec3::Zero();
  std::vector<Waypoint> after;  // from the last `before` waypoint (or the current grip)
  Vec3 goal = Vec3::Zero();     // the final grip position, device frame after any replacement
};

struct PressRequest {
  Vec3 line = Vec3::Zero();         // the press line through this scene point (x, z) [m]
  double surface_y = 0.0;           // top of the object on that line [m]
  double highest_y = 0.0;           // the highest vertex of every object [m]
  double depth = 0.0;               // below the surface [m]
  double seconds = 0.0;             // the press ramp [s]
  Vec3 grip = Vec3::Zero();         // where the grip is, device frame [m]
  Vec3 origin = Vec3::Zero();       // scene position of the device frame's origin [m]
  Vec3 half_extent = Vec3::Zero();  // the device's workspace, device frame [m]
  double tip_radius = 0.0;          // [m]
};

/// Plans the press so that the tool never moves sideways below the height of the highest object
/// plus the clearance: it rises first, moves over the line, then goes down. When the goal is
/// outside the workspace (the object fell away from under it), the grip first goes to the
/// workspace centre column and the workspace is re-placed over the line (a clutch).
/// FAILED_PRECONDITION when even that cannot reach the surface.
Result<PressPlan> PlanPress(const PressRequest& r);

}  // namespace rheo::daemon
