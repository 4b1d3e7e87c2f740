// Closest point on a triangle, with the Voronoi region it falls in (needed for the sign test).
#pragma once

#include <cstdint>

#include "common/geometry.h"

namespace rheo::haptics::internal {

/// Voronoi region of a triangle (a, b, c) that holds the closest point. Edge k runs from vertex k
/// to vertex (k + 1) % 3.
enum class Feature : uint8_t { kFace, kEdge0, kEdge1, kEdge2, kVertex0, kVertex1, kVertex2 };

struct ClosestPoint {
  Vec3 point;  ///< closest point [m]
  Vec3 bary;   ///< barycentric coordinates of point in (a, b, c), summing to 1
  Feature feature = Feature::kFace;
};

/// Closest point of triangle (a, b, c) to p (region tests after Ericson, Real-Time Collision
/// Detection, 5.1.5). Degenerate triangles fall back to the closest of their edges.
ClosestPoint ClosestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace rheo::haptics::internal
