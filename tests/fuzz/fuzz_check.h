// Invariants every sketch result must keep, whatever the input; a violation aborts the run.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "sketch/polyline.h"
#include "sketch/sketch.h"

namespace rheo::sketch::fuzz {

inline void Fail(const char* what) {
  std::fprintf(stderr, "sketch invariant broken: %s\n", what);
  std::abort();
}

inline void CheckResult(const Result<ContourResult>& r) {
  if (!r.ok()) {
    const auto code = r.error().code;
    if (code != ErrorCode::kInvalidArgument && code != ErrorCode::kResourceExhausted) {
      Fail("error code other than InvalidArgument or ResourceExhausted");
    }
    if (r.error().message.empty()) Fail("error without a message");
    return;
  }
  const auto& p = r->contour.points;
  if (p.size() < 3) Fail("contour with fewer than 3 points");
  double area = 0.0;
  for (size_t i = 0; i < p.size(); ++i) {
    if (!std::isfinite(p[i].x()) || !std::isfinite(p[i].y())) Fail("non-finite contour point");
    const auto& q = p[(i + 1) % p.size()];
    area += p[i].x() * q.y() - q.x() * p[i].y();
  }
  if (!(area > 0.0)) Fail("contour not counter-clockwise");
  if (internal::FindSelfCrossing(p)) Fail("self-crossing contour");
  if (!(r->epsilon_px > 0.0)) Fail("epsilon not reported");
}

}  // namespace rheo::sketch::fuzz
