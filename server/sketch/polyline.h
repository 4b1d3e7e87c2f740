// Planar polyline tools of the sketch library: resampling, recursive-split vectorization,
// self-crossing detection. Internal; exposed for tests.
#pragma once

#include <optional>
#include <vector>

#include "common/geometry.h"

namespace rheo::sketch::internal {

double SignedArea(const std::vector<Vec2>& closed);
double ClosedLength(const std::vector<Vec2>& closed);
double OpenLength(const std::vector<Vec2>& open);
double PointSegmentDistance(const Vec2& p, const Vec2& a, const Vec2& b);
/// Distance from p to a closed polygon's edges.
double PointPolygonDistance(const Vec2& p, const std::vector<Vec2>& closed);

/// Proper or touching intersection of segments ab and cd; returns the point and the parameters.
struct SegmentHit {
  Vec2 point;
  double t_ab = 0.0;  ///< position along ab (0..1)
  double t_cd = 0.0;  ///< position along cd (0..1)
};
std::optional<SegmentHit> IntersectSegments(const Vec2& a, const Vec2& b, const Vec2& c,
                                            const Vec2& d);

/// Resamples a closed polyline at equal arc-length spacing (at least 8 points).
std::vector<Vec2> ResampleClosed(const std::vector<Vec2>& closed, double spacing);

/// Recursive split (paper 3.4) of a closed chain: indices of the kept points, in order, such that
/// every chain point lies within epsilon of the polygon edge spanning it. Iterative (no recursion
/// depth limit). max_distance receives the largest chain-to-edge distance.
std::vector<int> SimplifyClosed(const std::vector<Vec2>& chain, double epsilon,
                                double* max_distance);

/// First crossing of two non-adjacent edges of a closed polygon, if any.
struct Crossing {
  int edge_a = 0;  ///< edge from point edge_a to edge_a + 1
  int edge_b = 0;  ///< edge_b > edge_a
  Vec2 point;
};
std::optional<Crossing> FindSelfCrossing(const std::vector<Vec2>& closed);

/// Removes consecutive points closer than min_spacing (closing point included).
void RemoveNearDuplicates(std::vector<Vec2>& closed, double min_spacing);

}  // namespace rheo::sketch::internal
