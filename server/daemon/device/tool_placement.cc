#include "daemon/device/tool_placement.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace rheo::daemon {

Vec3 PressPoint(std::span<const uint32_t> triangles, std::span<const Vec3> positions) {
  if (positions.empty()) return Vec3::Zero();
  std::vector<Vec3> normal(positions.size(), Vec3::Zero());
  for (size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const uint32_t a = triangles[t], b = triangles[t + 1], c = triangles[t + 2];
    if (a >= positions.size() || b >= positions.size() || c >= positions.size()) continue;
    // Twice the area times the unit normal: larger faces weigh more.
    const Vec3 n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
    normal[a] += n;
    normal[b] += n;
    normal[c] += n;
  }
  const double cos30 = std::sqrt(3.0) / 2.0;
  int best_up = -1, best_any = 0;
  for (size_t i = 0; i < positions.size(); ++i) {
    if (positions[i].y() > positions[best_any].y()) best_any = static_cast<int>(i);
    const double len = normal[i].norm();
    if (len > 0.0 && normal[i].y() >= cos30 * len &&
        (best_up < 0 || positions[i].y() > positions[best_up].y()))
      best_up = static_cast<int>(i);
  }
  return positions[best_up >= 0 ? best_up : best_any];
}

Vec3 WorkspaceOriginOver(std::span<const uint32_t> triangles, std::span<const Vec3> positions,
                         double tip_radius) {
  return PressPoint(triangles, positions) + Vec3(0.0, tip_radius + kToolClearance, 0.0);
}

PressTarget FindPressTarget(const LoopFrame& frame, const Vec3& at, double tip_radius) {
  PressTarget out;
  out.reach = std::max(3.0 * tip_radius, 0.005);
  const double r2 = out.reach * out.reach;
  for (uint32_t i = 0; i < frame.object_count; ++i) {
    const FrameObject& fo = frame.objects[i];
    const float* x = frame.positions.data() + 3u * fo.first;
    for (uint32_t k = 0; k < fo.vertex_count; ++k) {
      const double dx = x[3 * k] - at.x(), dz = x[3 * k + 2] - at.z();
      if (dx * dx + dz * dz > r2) continue;
      const double y = x[3 * k + 1];
      if (!out.found || y > out.surface_y) {
        out.found = true;
        out.surface_y = y;
        out.instance_id = fo.instance_id;
      }
    }
  }
  return out;
}

}  // namespace rheo::daemon
