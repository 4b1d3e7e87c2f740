// Euclidean projection of a point onto the intersection of a few half-spaces: the god-object step.
#pragma once

#include <span>

#include "common/geometry.h"

namespace rheo::haptics::internal {

/// The half-space n . y >= c, with n a unit vector.
struct HalfSpace {
  Vec3 n;
  double c = 0.0;  ///< [m]
};

/// Writes to `out` the point of the intersection of `h` (at most 8 half-spaces) closest to `t`.
/// The optimum has at most three active constraints in 3-D, so every subset of one to three is
/// tried (KKT: non-negative multipliers, all constraints met to `tol` [m]). Returns false when no
/// subset qualifies (an empty or numerically degenerate intersection).
bool ProjectOntoHalfSpaces(const Vec3& t, std::span<const HalfSpace> h, double tol, Vec3& out);

}  // namespace rheo::haptics::internal
