// BuildSolid refuses solids too small to simulate, and stops through its cancel token.
#include <gtest/gtest.h>

#include <atomic>
#include <set>

#include "mesh/mesh.h"
#include "test_polygons.h"

namespace rheo::mesh {
namespace {

TEST(MeshLimits, DegenerateContourIsRefusedWithItsSizeAndTheMinimum) {
  // A contour 1e-9 px across (2.5e-13 m at the default pixel size) used to become 24 tetrahedra
  // of about 1e-37 m^3.
  auto r = BuildSolid(testing::Ellipse(5e-10, 4e-10, 24), MeshOptions{});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument) << r.error().message;
  EXPECT_NE(r.error().message.find("the solid is 2.5e-13 m x 2e-13 m across"), std::string::npos)
      << r.error().message;
  EXPECT_NE(r.error().message.find("at least 0.001 m (1 mm)"), std::string::npos)
      << r.error().message;
  EXPECT_NE(r.error().message.find("min_object_size"), std::string::npos) << r.error().message;
  // A thin sliver is refused as well, naming its smaller side.
  Polygon2 sliver;
  sliver.points = {{0, 0}, {400, 0}, {400, 1e-3}, {0, 1e-3}};
  auto s = BuildSolid(sliver, MeshOptions{});
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument) << s.error().message;
  EXPECT_NE(s.error().message.find("2.5e-07 m across"), std::string::npos) << s.error().message;
}

TEST(MeshLimits, TetrahedraUnderTheMinimumVolumeAreRefusedWithTheNumbers) {
  MeshOptions o;
  o.min_tet_volume = 1e-3;  // larger than any tetrahedron of a 10 cm solid at 8 mm resolution
  auto r = BuildSolid(testing::Ellipse(200, 120, 200), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument) << r.error().message;
  EXPECT_NE(r.error().message.find("at least 0.001 m^3 (min_tet_volume)"), std::string::npos)
      << r.error().message;
  EXPECT_NE(r.error().message.find("lower the resolution (now 0.008 m)"), std::string::npos)
      << r.error().message;
  EXPECT_TRUE(BuildSolid(testing::Ellipse(200, 120, 200), MeshOptions{}).ok());
}

TEST(MeshLimits, CancelledTokenStopsTheBuild) {
  std::atomic<bool> cancelled{true};
  MeshOptions o;
  o.cancel = CancelToken(&cancelled);
  auto r = BuildSolid(testing::Ellipse(200, 120, 200), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kCancelled) << r.error().message;
}

// A deadline that passes at the k-th look: the build stops with kDeadlineExceeded in the stage
// it was in, for every k before the last look (which comes when all the work is done).
struct CountingDeadline {
  int64_t looks = 0;
  int64_t expire_at = 0;
  static bool Expired(const void* self) {
    auto* d = const_cast<CountingDeadline*>(static_cast<const CountingDeadline*>(self));
    return ++d->looks >= d->expire_at;
  }
};

TEST(MeshLimits, DeadlineStopsEveryStage) {
  const Polygon2 contour = testing::Ellipse(200, 120, 200);
  auto run = [&](CountingDeadline& d) {
    MeshOptions o;
    o.resolution = 0.004;
    o.cancel = CancelToken(nullptr, &CountingDeadline::Expired, &d);
    return BuildSolid(contour, o);
  };
  CountingDeadline never{0, int64_t(1) << 60};
  ASSERT_TRUE(run(never).ok());
  const int64_t total = never.looks;
  EXPECT_GE(total, 8) << "looks at the token in a whole build";
  std::set<std::string> stages;
  for (int64_t k = 1; k < total; ++k) {
    CountingDeadline d{0, k};
    auto r = run(d);
    ASSERT_FALSE(r.ok()) << "expired at look " << k << " of " << total;
    EXPECT_EQ(r.error().code, ErrorCode::kDeadlineExceeded) << r.error().message;
    stages.insert(r.error().message);
  }
  EXPECT_GE(stages.size(), 6u);
}

}  // namespace
}  // namespace rheo::mesh
