// Proxy (god-object) behaviour against closed forms on flat, edged, concave and moving surfaces.
#include <gtest/gtest.h>

#include <cmath>

#include "haptics/haptics.h"
#include "test_surfaces.h"

namespace rheo::haptics {
namespace {

using testing::BoxSurface;
using testing::VoxelSurface;

constexpr double kH = 0.01;   // voxel edge [m]
constexpr double kR = 0.003;  // tool radius [m]
constexpr double kDt = 1e-3;  // tick [s]

RendererConfig StiffConfig() {
  RendererConfig c;
  c.tool_radius = kR;
  c.device.max_force = 100.0;
  c.device.max_stiffness = 5000.0;
  c.device.damping = 2.0;
  c.device.max_force_rate = 1e6;  // out of the way of the closed forms
  c.coupling_stiffness = 1e6;
  c.coupling_damping = 0.0;  // closed forms below are for the spring alone
  return c;
}

Renderer Make(const RendererConfig& c, const TriSurface& s, const Vec3& tool) {
  auto r = Renderer::Create(c, s.triangles, s.positions, tool);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
  return std::move(r).value();
}

// Moves the device in steps of at most `step` [m] to `to`, then holds it for `hold` ticks.
ContactOutput MoveTo(Renderer& r, const TriSurface& s, Vec3& device, const Vec3& to, int hold = 5,
                     double step = 5e-4) {
  ContactOutput out;
  for (;;) {
    const Vec3 d = to - device;
    const double len = d.norm();
    device += len > step ? Vec3(d * (step / len)) : d;
    auto res = r.Update({device, Vec3::Zero()}, s.positions, kDt);
    EXPECT_TRUE(res.ok());
    out = *res;
    if (len <= step) break;
  }
  for (int i = 0; i < hold; ++i) out = *r.Update({device, Vec3::Zero()}, s.positions, kDt);
  return out;
}

Vec3 SumNodeForces(const ContactOutput& out) {
  Vec3 sum = Vec3::Zero();
  for (const NodeForce& nf : out.node_forces) sum += nf.force;
  return sum;
}

TEST(HapticsConfig, RejectsEachFieldOutOfRangeByName) {
  struct Case {
    const char* field;
    void (*spoil)(RendererConfig&);
  };
  const Case cases[] = {
      {"device.max_force", [](RendererConfig& c) { c.device.max_force = 0.0; }},
      {"device.max_stiffness", [](RendererConfig& c) { c.device.max_stiffness = -1.0; }},
      {"device.max_force_rate", [](RendererConfig& c) { c.device.max_force_rate = 1e9; }},
      {"device.damping", [](RendererConfig& c) { c.device.damping = NAN; }},
      {"device.tick", [](RendererConfig& c) { c.device.tick = 1.0; }},
      {"tool_radius", [](RendererConfig& c) { c.tool_radius = 0.0; }},
      {"coupling_stiffness", [](RendererConfig& c) { c.coupling_stiffness = -5.0; }},
      {"coupling_damping", [](RendererConfig& c) { c.coupling_damping = c.device.damping; }},
      {"stability_margin", [](RendererConfig& c) { c.stability_margin = 1.5; }},
      {"static_friction", [](RendererConfig& c) { c.static_friction = 3.0; }},
      {"dynamic_friction",
       [](RendererConfig& c) {
         c.static_friction = 0.2;
         c.dynamic_friction = 0.3;
       }},
      {"max_step", [](RendererConfig& c) { c.max_step = 0.0; }},
      {"max_surface_speed", [](RendererConfig& c) { c.max_surface_speed = -1.0; }},
      {"rebin_faces_per_tick", [](RendererConfig& c) { c.rebin_faces_per_tick = 0; }},
      {"cell_size", [](RendererConfig& c) { c.cell_size = -0.1; }},
  };
  EXPECT_TRUE(RendererConfig{}.Validate().ok());
  for (const Case& k : cases) {
    RendererConfig c;
    k.spoil(c);
    const Status s = c.Validate();
    ASSERT_FALSE(s.ok()) << k.field;
    EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(s.error().message.find(std::string("RendererConfig.") + k.field + " ="),
              std::string::npos)
        << s.error().message;
    EXPECT_NE(s.error().message.find("outside"), std::string::npos) << s.error().message;
  }
}

TEST(HapticsConfig, RejectsOpenOrBrokenSurfacesAndBadInputs) {
  TriSurface box = BoxSurface(2, 2, 2, kH, Vec3::Zero());
  const Vec3 tool(0.05, 0.05, 0.05);
  TriSurface open = box;
  open.triangles.pop_back();
  auto r = Renderer::Create(StiffConfig(), open.triangles, open.positions, tool);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("not closed"), std::string::npos) << r.error().message;

  TriSurface flipped = box;
  std::swap(flipped.triangles[0][1], flipped.triangles[0][2]);
  r = Renderer::Create(StiffConfig(), flipped.triangles, flipped.positions, tool);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("triangle"), std::string::npos);

  TriSurface bad = box;
  bad.triangles[3][2] = static_cast<int32_t>(bad.positions.size());
  r = Renderer::Create(StiffConfig(), bad.triangles, bad.positions, tool);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("triangle 3"), std::string::npos) << r.error().message;

  Renderer ok = Make(StiffConfig(), box, tool);
  std::vector<Vec3> fewer(box.positions.begin(), box.positions.end() - 1);
  auto u = ok.Update({tool, Vec3::Zero()}, fewer, kDt);
  ASSERT_FALSE(u.ok());
  EXPECT_EQ(u.error().code, ErrorCode::kInvalidArgument);
  u = ok.Update({tool, Vec3::Zero()}, box.positions, 0.0);
  ASSERT_FALSE(u.ok());
  EXPECT_NE(u.error().message.find("dt"), std::string::npos);
}

TEST(HapticsCoupling, StiffnessIsClampedToDeviceAndPassivityLimits) {
  TriSurface box = BoxSurface(2, 2, 2, kH, Vec3::Zero());
  struct Case {
    double k_req, k_dev, b_dev, b_c, tick;
  };
  for (const Case& k : {Case{1e6, 5000, 2.0, 0.0, 1e-3}, Case{1e6, 3000, 2.0, 0.0, 1e-3},
                        Case{1000, 5000, 2.0, 0.5, 1e-3}, Case{1e6, 1e5, 2.0, 0.5, 1e-3},
                        Case{1e6, 1e5, 2.0, 0.0, 5e-4}}) {
    RendererConfig c = StiffConfig();
    c.coupling_stiffness = k.k_req;
    c.device.max_stiffness = k.k_dev;
    c.device.damping = k.b_dev;
    c.coupling_damping = k.b_c;
    c.device.tick = k.tick;
    Renderer r = Make(c, box, Vec3(0.05, 0.05, 0.05));
    const double bound = 2.0 * (k.b_dev - k.b_c) / k.tick;  // Colgate: b > K T / 2 + |B|
    EXPECT_DOUBLE_EQ(r.stability_bound(), bound);
    EXPECT_DOUBLE_EQ(r.effective_stiffness(), std::min({k.k_req, k.k_dev, bound}));
  }
}

TEST(HapticsProxy, FlatFacePressHoldsProxyOnOffsetSurfaceWithSpringForce) {
  const TriSurface box = BoxSurface(4, 4, 2, kH, Vec3::Zero());  // top at z = 0.02
  const RendererConfig c = StiffConfig();
  Vec3 device(0.013, 0.021, 0.03);
  Renderer r = Make(c, box, device);
  const double k = r.effective_stiffness();
  ASSERT_DOUBLE_EQ(k, 4000.0);
  ContactOutput out = MoveTo(r, box, device, Vec3(0.013, 0.021, 0.02 + kR - 0.002));
  EXPECT_TRUE(out.in_contact);
  EXPECT_NEAR(out.proxy.z(), 0.02 + kR, 1e-12);
  EXPECT_NEAR(out.proxy.x(), device.x(), 1e-12);
  EXPECT_NEAR(out.proxy.y(), device.y(), 1e-12);
  EXPECT_NEAR(out.wrench.force.z(), k * 0.002, 1e-9);
  EXPECT_NEAR(out.wrench.force.x(), 0.0, 1e-9);
  EXPECT_NEAR(out.contact_normal.z(), 1.0, 1e-12);
  EXPECT_LE((SumNodeForces(out) + out.wrench.force).norm(), 1e-9 * out.wrench.force.norm());
  // Every contact node lies on the top face.
  for (const NodeForce& nf : out.node_forces) EXPECT_NEAR(box.positions[nf.node].z(), 0.02, 1e-15);
}

TEST(HapticsProxy, FrictionlessProxyFollowsDeviceTangentially) {
  const TriSurface box = BoxSurface(4, 4, 2, kH, Vec3::Zero());
  Vec3 device(0.005, 0.02, 0.03);
  Renderer r = Make(StiffConfig(), box, device);
  MoveTo(r, box, device, Vec3(0.005, 0.02, 0.02 + kR - 0.003));
  // Slide across several faces, 0.5 mm per tick.
  ContactOutput out = MoveTo(r, box, device, Vec3(0.035, 0.03, 0.02 + kR - 0.003), 1);
  EXPECT_TRUE(out.in_contact);
  EXPECT_NEAR(out.proxy.x(), 0.035, 1e-12);
  EXPECT_NEAR(out.proxy.y(), 0.03, 1e-12);
  EXPECT_NEAR(out.proxy.z(), 0.02 + kR, 1e-12);
}

TEST(HapticsProxy, FrictionConeSticksThenSlidesAtDynamicCoefficient) {
  const TriSurface box = BoxSurface(4, 4, 2, kH, Vec3::Zero());
  RendererConfig c = StiffConfig();
  c.static_friction = 0.5;
  c.dynamic_friction = 0.3;
  const double depth = 0.002;
  Vec3 device(0.01, 0.02, 0.03);
  Renderer r = Make(c, box, device);
  ContactOutput out = MoveTo(r, box, device, Vec3(0.01, 0.02, 0.02 + kR - depth));
  const Vec3 stuck = out.proxy;
  // Within the static cone (0.8 mm < 0.5 x 2 mm): the proxy does not move.
  out = MoveTo(r, box, device, device + Vec3(0.0008, 0, 0), 3, 1e-4);
  EXPECT_FALSE(out.sliding);
  EXPECT_NEAR((out.proxy - stuck).norm(), 0.0, 1e-12);
  EXPECT_NEAR(out.wrench.force.x(), -r.effective_stiffness() * 0.0008, 1e-9);
  // Past it: the proxy slides and trails the device by mu_d x depth.
  out = MoveTo(r, box, device, device + Vec3(0.01, 0, 0), 0, 1e-4);
  EXPECT_TRUE(out.sliding);
  EXPECT_NEAR(device.x() - out.proxy.x(), 0.3 * depth, 1e-9);
  EXPECT_NEAR(out.proxy.z(), 0.02 + kR, 1e-12);
  // Tangential / normal force ratio equals mu_d while sliding.
  EXPECT_NEAR(-out.wrench.force.x() / out.wrench.force.z(), 0.3, 1e-6);
}

TEST(HapticsProxy, ConvexEdgeProxyRestsOnRoundedEdge) {
  const TriSurface box = BoxSurface(4, 4, 2, kH, Vec3::Zero());  // edge x = 0.04, z = 0.02
  Vec3 device(0.042, 0.02, 0.04);
  Renderer r = Make(StiffConfig(), box, device);
  ContactOutput out = MoveTo(r, box, device, Vec3(0.042, 0.02, 0.021), 50, 2e-4);
  const Vec3 edge(0.04, 0.02, 0.02);
  const Vec3 expect = edge + kR * (device - edge).normalized();
  EXPECT_TRUE(out.in_contact);
  EXPECT_NEAR((out.proxy - expect).norm(), 0.0, 1e-7);
  EXPECT_NEAR((out.proxy - edge).norm(), kR, 1e-9);
}

TEST(HapticsProxy, ConcaveCornerTouchesBothWalls) {
  // L-shaped prism: voxels (0,0), (1,0), (0,1) in x-y, 1 high; inner corner at x = y = h.
  std::set<std::array<int, 3>> v;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      if (i < 2 || j < 2)
        for (int k = 0; k < 2; ++k) v.insert({i, j, k});
  const TriSurface l = VoxelSurface(v, 0.5 * kH, Vec3::Zero());  // corner at x = y = 0.01
  Vec3 device(0.017, 0.015, 0.005);
  Renderer r = Make(StiffConfig(), l, device);
  ContactOutput out = MoveTo(r, l, device, Vec3(0.0105, 0.0095, 0.005), 20, 2e-4);
  EXPECT_TRUE(out.in_contact);
  EXPECT_GE(out.contact_faces, 2);
  EXPECT_NEAR(out.proxy.x(), 0.01 + kR, 1e-9);
  EXPECT_NEAR(out.proxy.y(), 0.01 + kR, 1e-9);
  EXPECT_NEAR(out.proxy.z(), 0.005, 1e-9);
  const Vec3 f = r.effective_stiffness() * (out.proxy - device);
  EXPECT_NEAR((out.wrench.force - f).norm(), 0.0, 1e-6);
  EXPECT_LE((SumNodeForces(out) + out.wrench.force).norm(), 1e-9 * out.wrench.force.norm());
}

TEST(HapticsProxy, SurfaceMovingUnderTheProxyCarriesIt) {
  TriSurface box = BoxSurface(4, 4, 2, kH, Vec3::Zero());
  const std::vector<Vec3> rest = box.positions;
  RendererConfig c = StiffConfig();
  c.static_friction = 1.0;
  c.dynamic_friction = 0.8;
  Vec3 device(0.02, 0.02, 0.03);
  Renderer r = Make(c, box, device);
  ContactOutput out = MoveTo(r, box, device, Vec3(0.02, 0.02, 0.02 + kR - 0.002));
  // The object rises 0.05 mm and shifts 0.02 mm per tick; the device stays put.
  for (int i = 1; i <= 40; ++i) {
    const Vec3 shift(2e-5 * i, 0.0, 5e-5 * i);
    for (size_t n = 0; n < rest.size(); ++n) box.positions[n] = rest[n] + shift;
    out = *r.Update({device, Vec3::Zero()}, box.positions, kDt);
    EXPECT_NEAR(out.proxy.z(), 0.02 + shift.z() + kR, 1e-12) << i;
    // Static friction (depth 2-4 mm, lateral 0.8 mm at most) carries the proxy sideways.
    EXPECT_NEAR(out.proxy.x(), 0.02 + shift.x(), 1e-12) << i;
    EXPECT_NEAR(out.wrench.force.z(), r.effective_stiffness() * (out.proxy.z() - device.z()), 1e-9);
  }
}

TEST(HapticsProxy, ReleaseRampsForceDownWithinRateLimit) {
  const TriSurface box = BoxSurface(4, 4, 2, kH, Vec3::Zero());
  RendererConfig c = StiffConfig();
  c.device.max_force_rate = 1000.0;  // 1 N per tick
  Vec3 device(0.02, 0.02, 0.03);
  Renderer r = Make(c, box, device);
  ContactOutput out = MoveTo(r, box, device, Vec3(0.02, 0.02, 0.02 + kR - 0.002), 20);
  ASSERT_NEAR(out.wrench.force.z(), 8.0, 1e-9);
  Vec3 last = out.wrench.force;
  // Jump the device out of contact in one tick.
  device = Vec3(0.02, 0.02, 0.03);
  int ticks = 0;
  for (; ticks < 20; ++ticks) {
    out = *r.Update({device, Vec3::Zero()}, box.positions, kDt);
    EXPECT_FALSE(out.in_contact);
    EXPECT_LE((out.wrench.force - last).norm(), 1000.0 * kDt + 1e-12);
    EXPECT_LE((SumNodeForces(out) + out.wrench.force).norm(),
              1e-9 * std::max(out.wrench.force.norm(), 1e-300));
    last = out.wrench.force;
    if (out.wrench.force.isZero(0.0)) break;
  }
  EXPECT_EQ(ticks, 7);  // 8 N at 1 N per tick
  EXPECT_TRUE(out.node_forces.empty());
  EXPECT_NEAR((out.proxy - device).norm(), 0.0, 1e-12);
}

TEST(HapticsProxy, ForceIsClampedToDeviceMaximum) {
  const TriSurface box = BoxSurface(4, 4, 2, kH, Vec3::Zero());
  RendererConfig c = StiffConfig();
  c.device.max_force = 5.0;
  Vec3 device(0.02, 0.02, 0.03);
  Renderer r = Make(c, box, device);
  ContactOutput out = MoveTo(r, box, device, Vec3(0.02, 0.02, 0.02 + kR - 0.005));
  EXPECT_NEAR(out.wrench.force.norm(), 5.0, 1e-12);
  EXPECT_NEAR(out.wrench.force.z(), 5.0, 1e-12);
}

TEST(HapticsProxy, ToolStartingInsideIsPlacedOnTheSurface) {
  const TriSurface box = BoxSurface(4, 4, 2, kH, Vec3::Zero());
  const Vec3 inside(0.02, 0.02, 0.018);  // 2 mm under the top face, 18 mm above the bottom
  Renderer r = Make(StiffConfig(), box, inside);
  auto out = r.Update({inside, Vec3::Zero()}, box.positions, kDt);
  ASSERT_TRUE(out.ok());
  EXPECT_NEAR(out->proxy.z(), 0.02 + kR, 1e-12);
  EXPECT_TRUE(out->in_contact);
  EXPECT_GT(out->wrench.force.z(), 0.0);
}

TEST(HapticsProxy, SurfaceSweepingIntoARestingToolPushesTheProxyAhead) {
  // The block rises 0.4 mm per tick (0.4 m/s) into a device held still above it; the proxy is
  // pushed ahead of the top face and never ends inside, and the force grows as k x overlap.
  TriSurface box = BoxSurface(4, 4, 2, kH, Vec3::Zero());
  const std::vector<Vec3> rest = box.positions;
  RendererConfig c = StiffConfig();
  c.max_surface_speed = 0.5;
  const Vec3 device(0.021, 0.019, 0.026);  // 3 mm above the tool's contact height
  Renderer r = Make(c, box, device);
  int contact = 0;
  for (int i = 1; i <= 25; ++i) {
    const double lift = 4e-4 * i;
    for (size_t n = 0; n < rest.size(); ++n) box.positions[n] = rest[n] + Vec3(0, 0, lift);
    auto out = r.Update({device, Vec3::Zero()}, box.positions, kDt);
    ASSERT_TRUE(out.ok());
    const double top = 0.02 + lift;
    EXPECT_GE(out->proxy.z(), top + kR - 1e-12) << i;
    const double overlap = top + kR - device.z();
    if (overlap > 1e-9) {
      ++contact;
      EXPECT_TRUE(out->in_contact) << i;
      EXPECT_NEAR(out->proxy.z(), top + kR, 1e-12) << i;
      EXPECT_NEAR(out->wrench.force.z(), r.effective_stiffness() * overlap, 1e-9) << i;
    } else {
      EXPECT_FALSE(out->in_contact) << i;
      EXPECT_NEAR((out->proxy - device).norm(), 0.0, 1e-12) << i;
    }
  }
  EXPECT_GT(contact, 10);
}

}  // namespace
}  // namespace rheo::haptics
