// Where the haptic tool sits in the scene: the device's workspace placed over a new object, and
// where a press goes. Policy of the device layer, kept out of the API handlers. Pure functions.
#pragma once

#include <cstdint>
#include <span>

#include "common/geometry.h"
#include "daemon/loop/engine.h"

namespace rheo::daemon {

/// Clearance between the tool tip and the surface it is placed over [m].
inline constexpr double kToolClearance = 0.005;

/// The point of an object's surface that a press straight down meets squarely: the highest
/// vertex whose (area-weighted) normal is within 30 degrees of straight up, or the highest vertex
/// when none is. `triangles` holds 3 indices into `positions` per surface triangle, outward.
Vec3 PressPoint(std::span<const uint32_t> triangles, std::span<const Vec3> positions);

/// The scene position for the device frame's origin when an object enters an empty scene: the
/// tool tip `kToolClearance` above the object's PressPoint (the grip at the frame's centre).
Vec3 WorkspaceOriginOver(std::span<const uint32_t> triangles, std::span<const Vec3> positions,
                         double tip_radius);

/// What a press straight down along the vertical line through `at` meets in `frame`.
struct PressTarget {
  bool found = false;
  uint32_t instance_id = 0;  // the object whose vertex is highest there
  double surface_y = 0.0;    // height of that vertex [m]
  double reach = 0.0;        // horizontal distance from the line that counted [m]
};

/// The highest vertex of any object within max(3 tip radii, 5 mm) of the vertical line through
/// `at` (its y is ignored).
PressTarget FindPressTarget(const LoopFrame& frame, const Vec3& at, double tip_radius);

}  // namespace rheo::daemon
