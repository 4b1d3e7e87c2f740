#include "daemon/device/tool_placement.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace rheo::daemon {

Vec3 PressPoint(std::span<const uint32_t> triangles, std::span<const Vec3> positions) {
  if (positions.empty()) return Vec3::Zero();
  std::vector<Vec3> normal(positions.size(), Vec3::Zero());
  std::vector<char> on_surface(positions.size(), 0);
  for (size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const uint32_t a = triangles[t], b = triangles[t + 1], c = triangles[t + 2];
    if (a >= positions.size() || b >= positions.size() || c >= positions.size()) continue;
    // Twice the area times the unit normal: larger faces weigh more.
    const Vec3 n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
    for (uint32_t v : {a, b, c}) normal[v] += n, on_surface[v] = 1;
  }
  // The object's lowest point in each column of a horizontal grid (cells of kPressColumn).
  Eigen::AlignedBox3d box;
  for (const Vec3& x : positions) box.extend(x);
  const double cell = kPressColumn;
  const int nx = std::max(1, static_cast<int>(std::ceil(box.sizes().x() / cell)) + 1);
  const int nz = std::max(1, static_cast<int>(std::ceil(box.sizes().z() / cell)) + 1);
  auto column = [&](const Vec3& x) {
    const int i = std::clamp(static_cast<int>((x.x() - box.min().x()) / cell), 0, nx - 1);
    const int k = std::clamp(static_cast<int>((x.z() - box.min().z()) / cell), 0, nz - 1);
    return static_cast<size_t>(i) * nz + k;
  };
  std::vector<double> lowest(static_cast<size_t>(nx) * nz, std::numeric_limits<double>::max());
  for (const Vec3& x : positions) lowest[column(x)] = std::min(lowest[column(x)], x.y());
  // Among the up-facing surface vertices with at least half the most material under any of them
  // (height above the lowest point of its column), the highest: a thin lobe that sticks up has
  // little below it.
  const double cos30 = std::sqrt(3.0) / 2.0;
  std::vector<double> depth(positions.size(), -1.0);
  double deepest = -1.0;
  int highest = 0;
  for (size_t i = 0; i < positions.size(); ++i) {
    if (positions[i].y() > positions[highest].y()) highest = static_cast<int>(i);
    const double len = normal[i].norm();
    if (!on_surface[i] || !(len > 0.0) || normal[i].y() < cos30 * len) continue;
    depth[i] = positions[i].y() - lowest[column(positions[i])];
    deepest = std::max(deepest, depth[i]);
  }
  int best = -1;
  for (size_t i = 0; i < positions.size(); ++i) {
    if (depth[i] < 0.0 || depth[i] < 0.5 * deepest) continue;
    if (best < 0 || positions[i].y() > positions[best].y()) best = static_cast<int>(i);
  }
  return positions[best >= 0 ? best : highest];
}

Vec3 WorkspaceOriginOver(std::span<const uint32_t> triangles, std::span<const Vec3> positions,
                         double tip_radius) {
  return PressPoint(triangles, positions) + Vec3(0.0, tip_radius + kToolClearance, 0.0);
}

bool SurfaceTopOnLine(std::span<const uint32_t> triangles, const float* xyz, uint32_t count,
                      double x, double z, double* y) {
  bool hit = false;
  for (size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const uint32_t ia = triangles[t], ib = triangles[t + 1], ic = triangles[t + 2];
    if (ia >= count || ib >= count || ic >= count) continue;
    const Vec3 a(xyz[3 * ia], xyz[3 * ia + 1], xyz[3 * ia + 2]);
    const Vec3 b(xyz[3 * ib], xyz[3 * ib + 1], xyz[3 * ib + 2]);
    const Vec3 c(xyz[3 * ic], xyz[3 * ic + 1], xyz[3 * ic + 2]);
    // Barycentric coordinates of (x, z) in the triangle's projection onto the floor.
    const double d = (b.z() - c.z()) * (a.x() - c.x()) + (c.x() - b.x()) * (a.z() - c.z());
    if (std::abs(d) < 1e-18) continue;  // seen edge-on from above
    const double u = ((b.z() - c.z()) * (x - c.x()) + (c.x() - b.x()) * (z - c.z())) / d;
    const double v = ((c.z() - a.z()) * (x - c.x()) + (a.x() - c.x()) * (z - c.z())) / d;
    const double w = 1.0 - u - v;
    constexpr double kEdge = -1e-9;  // a line through a vertex or an edge counts
    if (u < kEdge || v < kEdge || w < kEdge) continue;
    const double h = u * a.y() + v * b.y() + w * c.y();
    if (!hit || h > *y) *y = h;
    hit = true;
  }
  return hit;
}

namespace {

bool Inside(const Vec3& p, const Vec3& half) {
  return (p.array().abs() <= half.array()).all();
}

}  // namespace

Result<PressPlan> PlanPress(const PressRequest& r) {
  constexpr double kRise = 0.25, kMove = 0.5;  // [s]
  PressPlan plan;
  const double safe_scene = r.highest_y + r.tip_radius + kToolClearance;
  const double safe = safe_scene - r.origin.y();  // device height above every object
  if (safe > r.half_extent.y())
    return FailedPrecondition(
        "the scene's objects reach above the device's workspace; the tool cannot pass over them");
  auto goal_in = [&](const Vec3& origin) {
    return Vec3(r.line.x() - origin.x(), r.surface_y + r.tip_radius - r.depth - origin.y(),
                r.line.z() - origin.z());
  };
  Vec3 at = r.grip;
  const Vec3 goal = goal_in(r.origin);
  const double dx = goal.x() - at.x(), dz = goal.z() - at.z();
  const bool on_line = dx * dx + dz * dz <= 1e-6;  // within 1 mm
  if (Inside(goal, r.half_extent)) {
    if (!on_line) {
      if (at.y() < safe) plan.before.push_back({kRise, at = Vec3(at.x(), safe, at.z())});
      plan.before.push_back({kMove, at = Vec3(goal.x(), at.y(), goal.z())});
    }
    plan.before.push_back({r.seconds, goal});
    plan.goal = goal;
    return plan;
  }
  // Clutch: up above every object, to the centre column, then the workspace moves so that the
  // tool stands at the safe height over the line, and the press goes down from there.
  if (at.y() < safe) plan.before.push_back({kRise, at = Vec3(at.x(), safe, at.z())});
  const Vec3 centre(0.0, std::max(0.0, safe), 0.0);
  plan.before.push_back({kMove, centre});
  plan.replace_origin = true;
  plan.new_origin = Vec3(r.line.x(), safe_scene - centre.y(), r.line.z());
  plan.goal = goal_in(plan.new_origin);
  if (!Inside(plan.goal, r.half_extent))
    return FailedPrecondition("the press goes " + std::to_string(std::lround(r.depth * 1e3)) +
                              " mm below a surface that lies too far below the highest object "
                              "for the device's workspace; press less deep or another object");
  plan.after.push_back({r.seconds, plan.goal});
  return plan;
}

}  // namespace rheo::daemon
