// Every check over 1,000 deterministic random polygons (star, spiky, thin necks, cocircular,
// collinear, duplicated points).
#include <gtest/gtest.h>

#include <map>

#include "mesh/mesh.h"
#include "test_polygons.h"

namespace rheo::mesh {
namespace {

TEST(MeshProperty, ThousandRandomPolygons) {
  std::map<std::string, int> count;
  double worst_dihedral = 180;
  for (int i = 0; i < 1000; ++i) {
    std::string family;
    const Polygon2 poly = testing::PropertyPolygon(i, &family);
    ++count[family];
    auto r = BuildSolid(poly, MeshOptions());
    ASSERT_TRUE(r.ok()) << "polygon " << i << " (" << family << "): " << r.error().message;
    const QualityReport& q = r->quality;
    std::string why;
    for (const auto& f : q.failures) why += f + "; ";
    ASSERT_TRUE(q.valid) << "polygon " << i << " (" << family << "): " << why;
    EXPECT_EQ(q.num_nonpositive_tets, 0);
    EXPECT_TRUE(q.boundary_matches_surface && q.surface_closed && q.surface_manifold &&
                q.surface_outward);
    EXPECT_LE(q.volume_rel_error, 1e-9);
    EXPECT_GT(q.min_dihedral_deg, 0);
    worst_dihedral = std::min(worst_dihedral, q.min_dihedral_deg);
  }
  for (const auto& [f, n] : count) EXPECT_GE(n, 100) << f;
  RecordProperty("worst_min_dihedral_deg", std::to_string(worst_dihedral));
}

TEST(MeshProperty, PaperDivisionOnRandomPolygons) {
  MeshOptions opt;
  opt.division = Division::kPaper;
  for (int i = 0; i < 400; ++i) {
    std::string family;
    const Polygon2 poly = testing::PropertyPolygon(i, &family);
    auto r = BuildSolid(poly, opt);
    ASSERT_TRUE(r.ok()) << "polygon " << i << " (" << family << "): " << r.error().message;
    std::string why;
    for (const auto& f : r->quality.failures) why += f + "; ";
    ASSERT_TRUE(r->quality.valid) << "polygon " << i << " (" << family << "): " << why;
  }
}

}  // namespace
}  // namespace rheo::mesh
