// Small text helpers for messages that say where (common/format.h does the formatting).
#pragma once

#include <string>

#include "common/format.h"
#include "common/geometry.h"

namespace rheo::sketch::internal {

/// A pixel position, rounded: "(12,34)".
inline std::string Pt(const Vec2& p) {
  return Format("(%.0f,%.0f)", p.x(), p.y());
}

/// A length or area with `digits` digits after the point.
inline std::string Num(double v, int digits = 1) {
  return Fixed(v, digits);
}

}  // namespace rheo::sketch::internal
