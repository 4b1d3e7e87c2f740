// The 1 kHz path allocates nothing: the binary counts allocations (rheo_test_alloc), and Update
// runs through free motion, pressing, sliding with friction, a concave corner, a surface moving
// under the proxy and release inside a counted block.
#include <gtest/gtest.h>

#include "alloc_counter.h"
#include "haptics/haptics.h"
#include "test_surfaces.h"

namespace rheo::haptics {
namespace {

using rheo::testing::AllocationCounter;

TEST(HapticsAllocation, UpdateAllocatesNothing) {
  // L-shaped block with a concave corner, 2 mm voxels.
  std::set<std::array<int, 3>> vox;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      if (i < 5 || j < 5)
        for (int k = 0; k < 4; ++k) vox.insert({i, j, k});
  TriSurface s = testing::VoxelSurface(vox, 0.002, Vec3::Zero());
  const std::vector<Vec3> rest = s.positions;
  RendererConfig c;
  c.tool_radius = 0.002;
  c.static_friction = 0.4;
  c.dynamic_friction = 0.3;
  c.rebin_faces_per_tick = 64;  // round-robin re-binning on every tick
  Vec3 device(0.005, 0.005, 0.015);
  auto made = Renderer::Create(c, s.triangles, s.positions, device);
  ASSERT_TRUE(made.ok());
  Renderer r = std::move(made).value();

  // Waypoints: press the top, slide, lift over the empty quadrant, go down beside the walls,
  // press into the concave corner, hold while the surface moves, release.
  const Vec3 path[] = {{0.005, 0.005, 0.006},   {0.008, 0.004, 0.006},   {0.008, 0.004, 0.012},
                       {0.0115, 0.0115, 0.012}, {0.0115, 0.0115, 0.004}, {0.0095, 0.0095, 0.004},
                       {0.0095, 0.0095, 0.004}, {0.0115, 0.0115, 0.02}};
  long contact = 0, sliding = 0, multi = 0, ticks = 0;
  AllocationCounter guard;
  for (const Vec3& to : path) {
    for (int i = 0; i < 200; ++i, ++ticks) {
      device += 0.02 * (to - device);
      const double w = 1e-4 * std::sin(0.05 * ticks);
      for (size_t n = 0; n < rest.size(); ++n) s.positions[n] = rest[n] + Vec3(w, -w, 0.5 * w);
      auto out = r.Update({device, Vec3::Zero()}, s.positions, 1e-3);
      ASSERT_TRUE(out.ok());
      contact += out->in_contact;
      sliding += out->sliding;
      multi += out->contact_faces >= 2;
    }
  }
  const long allocations = guard.count();
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(contact, 300);
  EXPECT_GT(sliding, 10);
  EXPECT_GT(multi, 50);
}

}  // namespace
}  // namespace rheo::haptics
