// Geometry types shared by the pure libraries. SI units (metres) unless a field says otherwise.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <vector>

namespace rheo {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

/// A closed polygon, counter-clockwise, without a repeated closing point.
struct Polygon2 {
  std::vector<Vec2> points;  // vertices (n), units of the producer (pixels for sketches)
};

/// A triangle surface: indices into positions, counter-clockwise seen from outside.
struct TriSurface {
  std::vector<Vec3> positions;                    // vertex positions (n) [m]
  std::vector<std::array<int32_t, 3>> triangles;  // faces (m), outward by right-hand rule
};

/// A tetrahedral mesh with its boundary surface. Every tetrahedron is positively oriented:
/// (p1-p0) . ((p2-p0) x (p3-p0)) > 0.
struct TetMesh {
  std::vector<Vec3> positions;                  // vertex positions (n) [m]
  std::vector<std::array<int32_t, 4>> tets;     // tetrahedra (m)
  std::vector<std::array<int32_t, 3>> surface;  // boundary faces (k), outward
};

}  // namespace rheo
