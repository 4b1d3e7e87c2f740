// Planar polyline tools of the sketch library: resampling, recursive-split vectorization,
// self-crossing detection. Internal; exposed for tests.
#pragma once

#include <optional>
#include <vector>

#include "common/cancel.h"
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
/// Stops early (the result is then incomplete) when `cancel` asks to.
std::vector<int> SimplifyClosed(const std::vector<Vec2>& chain, double epsilon,
                                double* max_distance, const CancelToken& cancel = CancelToken());

/// First crossing of two non-adjacent edges of a closed polygon, if any.
struct Crossing {
  int edge_a = 0;  ///< edge from point edge_a to edge_a + 1
  int edge_b = 0;  ///< edge_b > edge_a
  Vec2 point;
};
/// The first by (edge_a, edge_b). Edges are binned in a uniform grid, so only edges that share a
/// cell are compared: about linear for drawn outlines (all pairs only when every edge crosses the
/// whole outline). Returns nothing when `cancel` stops it.
std::optional<Crossing> FindSelfCrossing(const std::vector<Vec2>& closed,
                                         const CancelToken& cancel = CancelToken());

/// Largest distance to the closed polygon over the points of `points` that lie within `reach` of
/// it (0 when none does). Compares each point only with the edges near it.
double MaxNearDistance(const std::vector<Vec2>& points, const std::vector<Vec2>& closed,
                       double reach, const CancelToken& cancel = CancelToken());

/// Removes consecutive points closer than min_spacing (closing point included).
void RemoveNearDuplicates(std::vector<Vec2>& closed, double min_spacing);

}  // namespace rheo::sketch::internal
