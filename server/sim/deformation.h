// How much an object's shape changed, free of rigid motion: the current positions are first
// brought onto the rest positions by the best rigid fit (Kabsch: translation and rotation,
// least squares over every node), so a drop, a slide or a roll alone measure zero.
#pragma once

#include <span>

#include "common/geometry.h"

namespace rheo::sim {

struct ShapeChange {
  double rest_extent = 0.0;  // the rest shape's extent along `up` [m]
  double extent = 0.0;       // the fitted current shape's extent along `up` [m]
  double compression = 0.0;  // 1 - extent / rest_extent: > 0 when shorter along `up` [-]
  double rms = 0.0;          // RMS distance of the fitted nodes from their rest positions [m]
  double max = 0.0;          // the largest such distance [m]
};

/// `rest` and `current` hold the same nodes in the same order; `up` is the direction against
/// gravity in the rest frame (unit length). Zeros for fewer than 2 nodes.
ShapeChange MeasureShapeChange(std::span<const Vec3> rest, std::span<const Vec3> current,
                               const Vec3& up);

}  // namespace rheo::sim
