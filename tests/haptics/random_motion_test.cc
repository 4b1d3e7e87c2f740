// Invariants over long random motions of the device against a deforming, moving sphere: the proxy
// never ends inside, force continuity and limits, equal and opposite reaction, local search.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "haptics/haptics.h"
#include "haptics/surface_grid.h"
#include "test_surfaces.h"

namespace rheo::haptics {
namespace {

using testing::DistanceToSurface;
using testing::SphereSurface;
using testing::WindingNumber;

constexpr double kDt = 1e-3;  // [s]
constexpr double kR0 = 0.03;  // sphere radius at rest [m]

// Breathing, wobbling, drifting sphere at time t [s].
void Deform(const std::vector<Vec3>& rest, double t, std::vector<Vec3>& x) {
  const double pi = std::numbers::pi;
  const Vec3 c(0.008 * std::sin(2 * pi * 0.7 * t), 0.006 * std::cos(2 * pi * 0.5 * t),
               0.005 * std::sin(2 * pi * 0.3 * t));
  for (size_t i = 0; i < rest.size(); ++i) {
    const Vec3& p = rest[i];
    const double s = 1.0 + 0.12 * std::sin(2 * pi * 1.3 * t + 4.0 * p.z() / kR0) +
                     0.05 * std::sin(2 * pi * 2.1 * t + 3.0 * p.x() / kR0);
    x[i] = c + s * p;
  }
}

// Largest vertex speed over the run, from per-tick displacements [m/s].
double MaxSpeed(const std::vector<Vec3>& rest, int ticks) {
  std::vector<Vec3> a(rest.size()), b(rest.size());
  Deform(rest, 0.0, a);
  double vmax = 0.0;
  for (int i = 1; i <= ticks; ++i) {
    Deform(rest, i * kDt, b);
    for (size_t n = 0; n < rest.size(); ++n) vmax = std::max(vmax, (b[n] - a[n]).norm() / kDt);
    std::swap(a, b);
  }
  return vmax;
}

struct Params {
  double mu_s, mu_d;
  int32_t rebin;
  double tool_radius;
  uint32_t seed;
};

class RandomMotion : public ::testing::TestWithParam<Params> {};

TEST_P(RandomMotion, ProxyStaysOutsideAndForcesStayLimitedAndBalanced) {
  const Params prm = GetParam();
  const TriSurface s = SphereSurface(Vec3::Zero(), kR0, 16, 30);  // 900 triangles
  constexpr int kTicks = 3000;
  RendererConfig c;
  c.tool_radius = prm.tool_radius;
  c.static_friction = prm.mu_s;
  c.dynamic_friction = prm.mu_d;
  c.rebin_faces_per_tick = prm.rebin;
  c.max_surface_speed = 1.05 * MaxSpeed(s.positions, kTicks);
  c.device.max_force = 8.0;
  c.device.max_force_rate = 3000.0;
  std::vector<Vec3> x(s.positions.size());
  Deform(s.positions, 0.0, x);

  std::mt19937 rng(prm.seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vec3 device(0.0, 0.0, 0.06);
  auto made = Renderer::Create(c, s.triangles, x, device);
  ASSERT_TRUE(made.ok()) << made.error().message;
  Renderer r = std::move(made).value();

  Vec3 goal = device, last_force = Vec3::Zero();
  double speed = 0.2;
  int contact = 0, sliding = 0, deep = 0;
  double max_candidates = 0;
  for (int i = 1; i <= kTicks; ++i) {
    if (i % 250 == 1) {  // a new goal, often deep inside the object
      do {
        goal = Vec3(u(rng), u(rng), u(rng)) * 0.05;
      } while (goal.norm() > 0.05);
      if (u(rng) < 0.0) goal *= 0.3;
      speed = 0.1 + 0.4 * (u(rng) + 1.0) / 2.0;
    }
    const Vec3 d = goal - device;
    const Vec3 step = d.norm() > speed * kDt ? Vec3(d.normalized() * speed * kDt) : d;
    device += step;
    Deform(s.positions, i * kDt, x);
    auto res = r.Update({device, step / kDt}, x, kDt);
    ASSERT_TRUE(res.ok()) << res.error().message;
    const ContactOutput& out = *res;

    const double dist = DistanceToSurface(s.triangles, x, out.proxy);
    ASSERT_GE(dist, c.tool_radius - 1e-9) << "tick " << i;
    ASSERT_LT(WindingNumber(s.triangles, x, out.proxy), 0.5) << "tick " << i;
    const Vec3 f = out.wrench.force;
    ASSERT_LE(f.norm(), c.device.max_force * (1 + 1e-12)) << "tick " << i;
    ASSERT_LE((f - last_force).norm(), c.device.max_force_rate * kDt * (1 + 1e-9)) << "tick " << i;
    Vec3 sum = Vec3::Zero();
    for (const NodeForce& nf : out.node_forces) sum += nf.force;
    ASSERT_LE((sum + f).norm(), 1e-9 * f.norm()) << "tick " << i;
    ASSERT_EQ(out.node_forces.empty(), f.isZero(0.0)) << "tick " << i;
    last_force = f;
    contact += out.in_contact;
    sliding += out.sliding;
    // A device inside the object always has the proxy resting on the surface, pushing back.
    const bool inside = WindingNumber(s.triangles, x, device) > 0.5;
    ASSERT_TRUE(!inside || (out.in_contact && f.dot(out.contact_normal) >= 0.0)) << "tick " << i;
    deep += inside;
    max_candidates = std::max<double>(max_candidates, out.candidate_faces);
  }
  // The run exercised what it claims to.
  EXPECT_GT(contact, kTicks / 5);
  EXPECT_GT(deep, kTicks / 5);
  if (prm.mu_s < 0.5) {
    EXPECT_GT(sliding, 100);
  }
  EXPECT_LT(max_candidates, static_cast<double>(s.triangles.size()));
}

INSTANTIATE_TEST_SUITE_P(Haptics, RandomMotion,
                         ::testing::Values(Params{0.0, 0.0, 4096, 0.003, 1},
                                           Params{0.4, 0.3, 4096, 0.003, 2},
                                           Params{0.2, 0.1, 40, 0.002, 3},
                                           Params{1.5, 1.0, 97, 0.005, 4}),
                         [](const ::testing::TestParamInfo<Params>& info) {
                           const Params& p = info.param;
                           return "mu" + std::to_string(static_cast<int>(p.mu_s * 10)) + "_rebin" +
                                  std::to_string(p.rebin) + "_seed" + std::to_string(p.seed);
                         });

// The grid returns every face within a distance of the query point, however stale its bins, as
// long as the caller widens the radius by reach + max speed x staleness.
TEST(HapticsGrid, QueryIsSupersetOfNearFacesUnderStaleBins) {
  const TriSurface s = SphereSurface(Vec3::Zero(), kR0, 16, 30);
  constexpr int kTicks = 400;
  const double vmax = MaxSpeed(s.positions, kTicks);
  std::vector<Vec3> x(s.positions.size());
  Deform(s.positions, 0.0, x);
  internal::SurfaceGrid grid;
  grid.Build(s.triangles, x, 0.004, 0.0);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<int32_t> out;
  out.reserve(s.triangles.size());
  size_t checked = 0;
  for (int i = 1; i <= kTicks; ++i) {
    const double t = i * kDt;
    Deform(s.positions, t, x);
    grid.Rebin(s.triangles, x, 13, t);
    EXPECT_LE(grid.staleness(t), kDt * grid.SweepTicks(13) + 1e-12);
    const Vec3 center = Vec3(u(rng), u(rng), u(rng)) * 0.04;
    const double radius = 0.002 + 0.006 * (u(rng) + 1.0);
    out.clear();
    grid.Query(center, radius + grid.reach_bound() + vmax * grid.staleness(t), out);
    std::vector<char> hit(s.triangles.size(), 0);
    for (int32_t f : out) {
      ASSERT_EQ(hit[f], 0) << "face returned twice";
      hit[f] = 1;
    }
    for (size_t f = 0; f < s.triangles.size(); ++f) {
      const std::vector<std::array<int32_t, 3>> one = {s.triangles[f]};
      if (DistanceToSurface(one, x, center) <= radius) {
        ++checked;
        EXPECT_TRUE(hit[f]) << "face " << f << " missed at tick " << i;
      }
    }
    EXPECT_LT(out.size(), s.triangles.size());
  }
  EXPECT_GT(checked, 1000u);
}

}  // namespace
}  // namespace rheo::haptics
