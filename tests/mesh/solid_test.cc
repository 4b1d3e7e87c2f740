// BuildSolid end to end: units, checks, limits, cancellation, exports, sample sketches.
#include <gtest/gtest.h>

#include <iterator>
#include <sstream>

#include "common/tet_mesh_io.h"
#include "mesh/internal.h"
#include "mesh/mesh.h"
#include "test_polygons.h"

namespace rheo::mesh {
namespace {

std::string Failures(const QualityReport& q) {
  std::string s;
  for (const auto& f : q.failures) s += f + "; ";
  return s;
}

TEST(MeshSolid, EllipseInMetresYUp) {
  MeshOptions opt;
  // Ellipse 400 x 240 px, centre (256, 200) px.
  auto r = BuildSolid(testing::Ellipse(200, 120, 200, 256, 200), opt);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_TRUE(r->quality.valid) << Failures(r->quality);
  Vec3 lo = r->mesh.positions[0], hi = lo;
  for (const Vec3& p : r->mesh.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double s = opt.pixel_size;
  EXPECT_NEAR(hi.x() - lo.x(), 400 * s, 2 * s);  // resampled outline within 2 px of the extremes
  EXPECT_NEAR(hi.y() - lo.y(), 240 * s, opt.resolution * 0.1);
  EXPECT_NEAR(0.5 * (hi.y() + lo.y()), -200 * s, 1e-3);  // y flipped: image row 200 -> -0.05 m
  EXPECT_NEAR(hi.z(), -lo.z(), 1e-12);                   // bottom mirrors top
  EXPECT_GT(hi.z(), 0.8 * 120 * s);                      // Teddy: height ~ half-width
  EXPECT_LT(hi.z(), 1.25 * 120 * s);
  // The solid's volume lies between a box-less bound: inscribed elliptic "pillow" and ellipsoid.
  const double a = 200 * s, b = 120 * s, ellipsoid = 4.0 / 3 * std::numbers::pi * a * b * b;
  EXPECT_GT(r->quality.surface_volume, 0.6 * ellipsoid);
  EXPECT_LT(r->quality.surface_volume, 1.1 * ellipsoid);
}

TEST(MeshSolid, VolumeIsLinearInThickness) {
  MeshOptions opt;
  auto r1 = BuildSolid(testing::Ellipse(180, 110, 150), opt);
  opt.thickness = 2.0;
  auto r2 = BuildSolid(testing::Ellipse(180, 110, 150), opt);
  ASSERT_TRUE(r1.ok() && r2.ok());
  EXPECT_TRUE(r1->quality.valid && r2->quality.valid);
  // The same height field, doubled; smoothing samples it at slightly different points for each
  // thickness, so the piecewise-linear volumes agree to the sampling error, not to round-off.
  EXPECT_NEAR(r2->quality.surface_volume, 2 * r1->quality.surface_volume,
              5e-3 * r1->quality.surface_volume);
  EXPECT_GT(r2->quality.num_tets, r1->quality.num_tets);  // more layers through the thickness
}

TEST(MeshSolid, FinerResolutionGivesMoreTets) {
  MeshOptions opt;
  auto coarse = BuildSolid(testing::Ellipse(200, 120, 200), opt);
  opt.resolution = 0.004;
  auto fine = BuildSolid(testing::Ellipse(200, 120, 200), opt);
  ASSERT_TRUE(coarse.ok() && fine.ok());
  EXPECT_TRUE(fine->quality.valid) << Failures(fine->quality);
  EXPECT_GT(fine->quality.num_tets, 4 * coarse->quality.num_tets);
  // Both sample the same smooth solid: volumes agree within a few percent.
  EXPECT_NEAR(fine->quality.surface_volume, coarse->quality.surface_volume,
              0.08 * fine->quality.surface_volume);
}

TEST(MeshSolid, RejectsBadInput) {
  MeshOptions opt;
  auto two = BuildSolid(Polygon2{{{0, 0}, {10, 0}, {10, 0}}}, opt);
  ASSERT_FALSE(two.ok());
  EXPECT_EQ(two.error().code, ErrorCode::kInvalidArgument);
  auto nan = BuildSolid(Polygon2{{{0, 0}, {std::nan(""), 0}, {10, 10}}}, opt);
  ASSERT_FALSE(nan.ok());
  EXPECT_NE(nan.error().message.find("point 1"), std::string::npos) << nan.error().message;
  auto line = BuildSolid(Polygon2{{{0, 0}, {10, 0}, {20, 0}, {30, 0}}}, opt);
  ASSERT_FALSE(line.ok());
  EXPECT_EQ(line.error().code, ErrorCode::kInvalidArgument);
  // A figure eight with unequal lobes (non-zero signed area).
  auto bowtie = BuildSolid(Polygon2{{{0, 0}, {100, 100}, {100, 0}, {0, 160}}}, opt);
  ASSERT_FALSE(bowtie.ok());
  EXPECT_EQ(bowtie.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(bowtie.error().message.find("intersects itself"), std::string::npos)
      << bowtie.error().message;
  opt.resolution = -1;
  EXPECT_FALSE(BuildSolid(testing::Ellipse(100, 50, 30), opt).ok());
}

TEST(MeshSolid, PenJitterLoopsAreCutBigCrossingsRefused) {
  // An ellipse whose outline makes a tiny loop (a zigzag 1 px back) halfway round.
  Polygon2 p = testing::Ellipse(200, 120, 40);
  const Vec2 a = p.points[10], b = p.points[11];
  const Vec2 t = (b - a).normalized(), n(-t.y(), t.x());
  // a -> X1 -> X2 -> b with X1 ahead of X2: segments a-X1 and X2-b cross.
  p.points.insert(p.points.begin() + 11,
                  {a + 0.7 * (b - a) + 0.5 * n, a + 0.3 * (b - a) + 0.5 * n});
  ASSERT_FALSE(internal::IsSimplePolygon(p.points));
  MeshOptions opt;
  opt.resolution = 0.005;  // finer than the input spacing: the outline is used as drawn
  auto r = BuildSolid(p, opt);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_TRUE(r->quality.valid);
  EXPECT_EQ(r->contour.size(), 41u);  // the two loop points replaced by the crossing point
}

TEST(MeshSolid, LimitsAreNamed) {
  MeshOptions opt;
  opt.max_tets = 100;
  auto r = BuildSolid(testing::Ellipse(200, 120, 100), opt);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kResourceExhausted);
  EXPECT_NE(r.error().message.find("max_tets"), std::string::npos);
  opt = MeshOptions();
  opt.max_vertices = 50;
  r = BuildSolid(testing::Ellipse(200, 120, 100), opt);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("max_vertices"), std::string::npos);
  opt = MeshOptions();
  opt.max_contour_points = 10;
  r = BuildSolid(testing::Ellipse(200, 120, 100), opt);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("max_contour_points"), std::string::npos);
  opt = MeshOptions();
  opt.resolution = 1e-6;  // would be billions of tets: refused before meshing
  r = BuildSolid(testing::Ellipse(200, 120, 100), opt);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kResourceExhausted);
}

TEST(MeshSolid, ProgressAndCancellation) {
  MeshOptions opt;
  std::vector<std::string> stages;
  double last = -1;
  bool monotone = true;
  opt.progress = [&](std::string_view stage, double f) {
    stages.emplace_back(stage);
    monotone = monotone && f >= last;
    last = f;
    return true;
  };
  auto r = BuildSolid(testing::Ellipse(200, 120, 100), opt);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(monotone);
  EXPECT_EQ(last, 1.0);
  EXPECT_GE(stages.size(), 7u);
  EXPECT_EQ(r->timings.size(), stages.size() - 1);
  opt.progress = [](std::string_view stage, double) { return stage != "tetrahedra"; };
  r = BuildSolid(testing::Ellipse(200, 120, 100), opt);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kCancelled);
  EXPECT_NE(r.error().message.find("tetrahedra"), std::string::npos);
}

TEST(MeshSolid, ExportsAgreeWithTheMesh) {
  auto r = BuildSolid(testing::Ellipse(150, 100, 80), MeshOptions());
  ASSERT_TRUE(r.ok());
  const TetMesh& m = r->mesh;
  auto count_prefix = [](const std::string& s, const std::string& p) {
    std::istringstream is(s);
    std::string line;
    size_t n = 0;
    while (std::getline(is, line)) n += line.rfind(p, 0) == 0;
    return n;
  };
  const std::string obj = SurfaceToObj(m);
  EXPECT_EQ(count_prefix(obj, "v "), m.positions.size());
  EXPECT_EQ(count_prefix(obj, "f "), m.surface.size());
  const std::string ply = SurfaceToPly(m);
  EXPECT_NE(ply.find("element face " + std::to_string(m.surface.size())), std::string::npos);
  EXPECT_EQ(count_prefix(ply, "3 "), m.surface.size());
  const std::string stl = SurfaceToStl(m);
  EXPECT_EQ(count_prefix(stl, "  facet normal"), m.surface.size());
  auto back = ReadVtu(WriteVtu(m));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->tets, m.tets);
  EXPECT_EQ(back->surface.size(), m.surface.size());
  EXPECT_TRUE(CheckTetMesh(*back).valid);
  const std::string svg = TriangulationToSvg(*r);
  EXPECT_EQ(count_prefix(svg, "<polygon class="), r->cdt.triangles.size());
  EXPECT_NE(svg.find("class=\"terminal\""), std::string::npos);
  EXPECT_NE(svg.find("class=\"sleeve\""), std::string::npos);
}

// The sample sketches' truth contours (samples/, every case), by name.
std::vector<std::pair<std::string, Polygon2>> SampleContours() {
  std::vector<std::pair<std::string, Polygon2>> out;
  const std::string dir = RHEO_SKETCH_DIR;
  for (const char* name : testing::kSampleNames) {
    Polygon2 contour;
    EXPECT_TRUE(testing::ReadContour(dir + "/" + name + ".truth.json", contour)) << name;
    out.emplace_back(name, std::move(contour));
  }
  return out;
}

TEST(MeshSolid, SampleSketchesMeetTheTargets) {
  const auto samples = SampleContours();
  ASSERT_EQ(samples.size(), std::size(testing::kSampleNames));
  for (const auto& [name, contour] : samples) {
    SCOPED_TRACE(name);
    auto r = BuildSolid(contour, MeshOptions());
    ASSERT_TRUE(r.ok()) << r.error().message;
    const QualityReport& q = r->quality;
    EXPECT_TRUE(q.valid) << Failures(q);
    EXPECT_EQ(q.num_nonpositive_tets, 0);
    EXPECT_LE(q.volume_rel_error, 1e-9);
    EXPECT_GE(q.min_dihedral_deg, 5.0);
    EXPECT_GE(q.min_volume_ratio, 0.01);
    // 512 px drawings become objects of about 10-15 cm.
    Vec3 lo = r->mesh.positions[0], hi = lo;
    for (const Vec3& p : r->mesh.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const double span = std::max(hi.x() - lo.x(), hi.y() - lo.y());
    EXPECT_GT(span, 0.07);
    EXPECT_LT(span, 0.15);
  }
}

// The paper's division at the default resolution, and the default division at half of it.
TEST(MeshSolid, PaperDivisionAndHalfResolutionMeetTheTargets) {
  const auto samples = SampleContours();
  ASSERT_EQ(samples.size(), std::size(testing::kSampleNames));
  struct Case {
    const char* what;
    Division division;
    double resolution;        // [m]
    double min_volume_ratio;  // asked of the smallest tetrahedron
  };
  for (const Case& c : {Case{"paper division", Division::kPaper, 0.008, 0.01},
                        Case{"half resolution", Division::kQuality, 0.004, 0.0}}) {
    MeshOptions opt;
    opt.division = c.division;
    opt.resolution = c.resolution;
    for (const auto& [name, contour] : samples) {
      SCOPED_TRACE(std::string(c.what) + " " + name);
      auto r = BuildSolid(contour, opt);
      ASSERT_TRUE(r.ok()) << r.error().message;
      EXPECT_TRUE(r->quality.valid) << Failures(r->quality);
      EXPECT_GE(r->quality.min_dihedral_deg, 5.0);
      EXPECT_GE(r->quality.min_volume_ratio, c.min_volume_ratio);
      // Same Teddy surface sampled differently: volumes agree with the default.
      auto q = BuildSolid(contour, MeshOptions());
      ASSERT_TRUE(q.ok());
      EXPECT_NEAR(r->quality.surface_volume, q->quality.surface_volume,
                  0.1 * q->quality.surface_volume);
    }
  }
}

}  // namespace
}  // namespace rheo::mesh
