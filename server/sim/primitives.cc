#include "sim/primitives.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "common/tet_mesh_io.h"

namespace rheo::sim {
namespace {

// Kuhn split of the unit cube: one tet per axis permutation, all sharing the 000-111 diagonal.
constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};

TetMesh GridTets(int nx, int ny, int nz) {
  TetMesh mesh;
  auto id = [&](int i, int j, int k) {
    return static_cast<int32_t>((k * (ny + 1) + j) * (nx + 1) + i);
  };
  mesh.positions.reserve(static_cast<size_t>(nx + 1) * (ny + 1) * (nz + 1));
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) mesh.positions.emplace_back(i, j, k);
    }
  }
  mesh.tets.reserve(static_cast<size_t>(6) * nx * ny * nz);
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        for (const auto& perm : kPerm) {
          int c[3] = {i, j, k};
          std::array<int32_t, 4> t;
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[perm[s]];
            t[s + 1] = id(c[0], c[1], c[2]);
          }
          mesh.tets.push_back(t);
        }
      }
    }
  }
  return mesh;
}

void OrientAndBound(TetMesh& mesh) {
  for (auto& t : mesh.tets) {
    const Vec3& p0 = mesh.positions[t[0]];
    const double v = (mesh.positions[t[1]] - p0)
                         .dot((mesh.positions[t[2]] - p0).cross(mesh.positions[t[3]] - p0));
    if (v < 0) std::swap(t[2], t[3]);
  }
  ComputeBoundary(mesh);
}

}  // namespace

Result<TetMesh> MakeBoxTetMesh(int nx, int ny, int nz, const Vec3& size) {
  if (nx < 1 || ny < 1 || nz < 1 || nx > 200 || ny > 200 || nz > 200) {
    return InvalidArgument("box cells per axis must be in [1, 200], got " + std::to_string(nx) +
                           " x " + std::to_string(ny) + " x " + std::to_string(nz));
  }
  if (!(size.minCoeff() > 0.0) || !size.allFinite()) {
    return InvalidArgument("box size must be positive and finite");
  }
  TetMesh mesh = GridTets(nx, ny, nz);
  const Vec3 cell(size.x() / nx, size.y() / ny, size.z() / nz);
  for (auto& p : mesh.positions) p = p.cwiseProduct(cell);
  OrientAndBound(mesh);
  return mesh;
}

Result<TetMesh> MakeEllipsoidTetMesh(int n, const Vec3& radii, const Vec3& center) {
  if (n < 1 || n > 200) {
    return InvalidArgument("ellipsoid cells per axis must be in [1, 200], got " +
                           std::to_string(n));
  }
  if (!(radii.minCoeff() > 0.0) || !radii.allFinite() || !center.allFinite()) {
    return InvalidArgument("ellipsoid radii must be positive and finite");
  }
  TetMesh mesh = GridTets(n, n, n);
  for (auto& p : mesh.positions) {
    const Vec3 q = 2.0 * p / n - Vec3::Ones();  // [-1, 1]^3
    const double r2 = q.norm();
    // Cube -> ball: scale each point by |q|_inf / |q|_2, blended in so the centre stays regular.
    const Vec3 b = r2 > 0 ? Vec3(q * (q.cwiseAbs().maxCoeff() / r2)) : q;
    p = center + b.cwiseProduct(radii);
  }
  OrientAndBound(mesh);
  return mesh;
}

}  // namespace rheo::sim
