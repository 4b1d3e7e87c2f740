// The checker itself must catch broken meshes.
#include <gtest/gtest.h>

#include "common/tet_mesh_io.h"
#include "mesh/mesh.h"

namespace rheo::mesh {
namespace {

TetMesh OneTet() {
  TetMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.tets = {{0, 1, 2, 3}};
  ComputeBoundary(m);
  return m;
}

TEST(MeshQuality, RegularCornerTet) {
  QualityReport q = CheckTetMesh(OneTet());
  EXPECT_TRUE(q.valid) << (q.failures.empty() ? "" : q.failures[0]);
  EXPECT_NEAR(q.tet_volume_sum, 1.0 / 6, 1e-15);
  EXPECT_NEAR(q.surface_volume, 1.0 / 6, 1e-15);
  EXPECT_NEAR(q.min_dihedral_deg, 54.7356103172, 1e-6);  // acos(1/sqrt(3))
  EXPECT_NEAR(q.max_dihedral_deg, 90, 1e-9);
  // Circumradius sqrt(3)/2, shortest edge 1.
  EXPECT_NEAR(q.max_radius_edge, std::sqrt(3.0) / 2, 1e-12);
}

TEST(MeshQuality, InvertedTetIsCaught) {
  TetMesh m = OneTet();
  std::swap(m.tets[0][0], m.tets[0][1]);
  QualityReport q = CheckTetMesh(m);
  EXPECT_FALSE(q.valid);
  EXPECT_EQ(q.num_nonpositive_tets, 1);
}

TEST(MeshQuality, MissingFaceIsCaught) {
  TetMesh m = OneTet();
  m.surface.pop_back();
  QualityReport q = CheckTetMesh(m);
  EXPECT_FALSE(q.valid);
  EXPECT_FALSE(q.boundary_matches_surface);
  EXPECT_FALSE(q.surface_closed);
}

TEST(MeshQuality, InwardSurfaceIsCaught) {
  TetMesh m = OneTet();
  for (auto& f : m.surface) std::swap(f[1], f[2]);
  QualityReport q = CheckTetMesh(m);
  EXPECT_FALSE(q.valid);
  EXPECT_FALSE(q.surface_outward);
  EXPECT_FALSE(q.boundary_matches_surface);
}

TEST(MeshQuality, OverlappingTetsBreakTheVolumeCheck) {
  TetMesh m = OneTet();
  m.positions.push_back({0.2, 0.2, 0.2});  // inside the first tet
  m.tets.push_back({0, 1, 2, 4});          // overlaps it
  QualityReport q = CheckTetMesh(m);
  EXPECT_FALSE(q.valid);
}

TEST(MeshQuality, PinchedSurfaceIsNotManifold) {
  // Two tets touching at one vertex: closed, but the shared vertex has two link cycles.
  TetMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
  m.tets = {{0, 1, 2, 3}, {0, 4, 5, 6}};
  for (auto& t : m.tets) {
    const Vec3 a = m.positions[t[1]] - m.positions[t[0]], b = m.positions[t[2]] - m.positions[t[0]],
               c = m.positions[t[3]] - m.positions[t[0]];
    if (a.dot(b.cross(c)) < 0) std::swap(t[0], t[1]);
  }
  ComputeBoundary(m);
  QualityReport q = CheckTetMesh(m);
  EXPECT_TRUE(q.surface_closed);
  EXPECT_FALSE(q.surface_manifold);
  EXPECT_FALSE(q.valid);
}

}  // namespace
}  // namespace rheo::mesh
