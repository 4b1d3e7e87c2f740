// Procedural tetrahedral meshes (boxes, ellipsoids) for tests, benchmarks and demos.
#pragma once

#include "common/geometry.h"
#include "common/status.h"

namespace rheo::sim {

/// A box [0, sx] x [0, sy] x [0, sz] [m] on nx x ny x nz cells, each split into 6 tetrahedra
/// (Kuhn subdivision, conforming), so 6 nx ny nz tets. Lowest face at y = 0.
Result<TetMesh> MakeBoxTetMesh(int nx, int ny, int nz, const Vec3& size);

/// An ellipsoid with semi-axes `radii` [m], centred at `center`, from an n^3-cell cube mapped
/// onto the ball (6 n^3 tets).
Result<TetMesh> MakeEllipsoidTetMesh(int n, const Vec3& radii, const Vec3& center);

}  // namespace rheo::sim
