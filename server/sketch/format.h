// Small text helpers for messages that say where.
#pragma once

#include <cstdio>
#include <string>

#include "common/geometry.h"

namespace rheo::sketch::internal {

inline std::string Pt(const Vec2& p) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "(%.0f,%.0f)", p.x(), p.y());
  return buf;
}

inline std::string Num(double v, int digits = 1) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

}  // namespace rheo::sketch::internal
