// The multi-rate scheme (sim/multirate.h): a patch's inner nodes feel what they feel in the
// whole, so with its boundary on the whole's trajectory it moves as the whole does; the coupled
// scheme follows the full solve under a tool load, closer the shorter the whole's period.
#include "sim/multirate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "sim/primitives.h"

namespace rheo::sim {
namespace {

// A 6 cm x 3 cm x 6 cm box of organ tissue resting on the floor, settled.
std::unique_ptr<SimObject> SettledBox() {
  auto mesh = MakeBoxTetMesh(8, 4, 8, Vec3(0.06, 0.03, 0.06));
  EXPECT_TRUE(mesh.ok());
  Result<Preset> preset = FindPreset("organ");
  EXPECT_TRUE(preset.ok());
  Parameters p = preset->params;
  p.sleep_time = 0.0;
  auto obj = SimObject::Create(*mesh, p, Integrator::kImplicitEuler);
  EXPECT_TRUE(obj.ok());
  for (int k = 0; k < 500; ++k) (*obj)->Step(1e-3);
  return std::move(*obj);
}

// The node nearest the middle of the top face.
int32_t TopMiddle(const SimObject& o) {
  int32_t best = 0;
  double best_d = 1e30;
  for (int32_t i = 0; i < o.model().num_nodes; ++i) {
    const Vec3& x = o.positions()[i];
    const double d = std::hypot(x.x() - 0.03, x.z() - 0.03) - 10.0 * x.y();
    if (d < best_d) best_d = d, best = i;
  }
  return best;
}

double MaxInnerDifference(const Patch& patch, const SimObject& whole) {
  double worst = 0.0;
  for (int32_t l = 0; l < patch.inner_nodes(); ++l) {
    worst = std::max(worst,
                     (patch.object().positions()[l] - whole.positions()[patch.nodes()[l]]).norm());
  }
  return worst;
}

TEST(Patch, RefusesABadRadiusOrNoNode) {
  auto whole = SettledBox();
  EXPECT_FALSE(Patch::Build(*whole, Vec3(0.03, 0.03, 0.03), PatchOptions{0.0}).ok());
  auto far = Patch::Build(*whole, Vec3(5.0, 5.0, 5.0), PatchOptions{0.01});
  ASSERT_FALSE(far.ok());
  EXPECT_NE(far.error().message.find("no free node"), std::string::npos);
}

TEST(Patch, InnerNodesMoveAsInTheWholeWhenTheBoundaryFollowsIt) {
  auto whole = SettledBox();
  const int32_t top = TopMiddle(*whole);
  // A load on the top middle node, in the whole and in the patch alike.
  auto patch = Patch::Build(*whole, whole->positions()[top], PatchOptions{0.012});
  ASSERT_TRUE(patch.ok()) << patch.error().message;
  EXPECT_GT(patch->inner_nodes(), 10);
  EXPECT_LT(patch->object().model().tets.size(), whole->model().tets.size() / 2);
  const Vec3 load(0.0, -0.5, 0.0);
  ASSERT_TRUE(patch->SetToolForce(top, load));
  whole->SetExternalForce(top, load);
  double worst = 0.0, moved = 0.0;
  const Vec3 x0 = whole->positions()[top];
  for (int k = 0; k < 100; ++k) {
    // The boundary takes the whole's state at the start of each tick, as with a period of one.
    patch->Follow(*whole);
    patch->Step(1e-3);
    whole->Step(1e-3);
    worst = std::max(worst, MaxInnerDifference(*patch, *whole));
    moved = std::max(moved, (whole->positions()[top] - x0).norm());
  }
  EXPECT_GT(moved, 1e-3);  // the load dents the top by millimetres
  // The patch's boundary moves linearly within a tick where the whole's does not: a difference of
  // a few micrometres against a dent of millimetres.
  EXPECT_LT(worst, 0.05 * moved) << "worst " << worst << " of " << moved;
}

TEST(Patch, ToolForcesOutsideTheInnerNodesAreRefused) {
  auto whole = SettledBox();
  auto patch = Patch::Build(*whole, whole->positions()[TopMiddle(*whole)], PatchOptions{0.01});
  ASSERT_TRUE(patch.ok());
  int32_t outside = -1;
  for (int32_t i = 0; i < whole->model().num_nodes && outside < 0; ++i)
    if (!patch->IsInner(i)) outside = i;
  ASSERT_GE(outside, 0);
  EXPECT_FALSE(patch->SetToolForce(outside, Vec3(0, -1, 0)));
  EXPECT_FALSE(patch->SetToolForce(-1, Vec3(0, -1, 0)));
}

TEST(ForceWindow, AveragesOverTheWindowAndCountsOverflow) {
  ForceWindow w(4);
  EXPECT_TRUE(w.Add(7, Vec3(1, 0, 0), 1e-3));
  EXPECT_TRUE(w.Add(7, Vec3(3, 0, 0), 1e-3));
  w.AddDuration(2e-3);
  for (int32_t n : {1, 2, 3}) EXPECT_TRUE(w.Add(n, Vec3(0, 1, 0), 1e-3));
  EXPECT_FALSE(w.Add(9, Vec3(0, 1, 0), 1e-3));  // a fifth node in a window of four
  EXPECT_EQ(w.overflowed(), 1);
  ASSERT_EQ(w.entries().size(), 4u);
  EXPECT_NEAR((w.entries()[0].impulse / w.duration()).x(), 2.0, 1e-12);
  w.Clear();
  EXPECT_TRUE(w.entries().empty());
  EXPECT_EQ(w.overflowed(), 0);
  EXPECT_TRUE(w.Add(9, Vec3(0, 1, 0), 1e-3));
}

// The coupled scheme against the full solve under a load on the top: the deepest point's
// trajectory, closer with a shorter period of the whole.
double TrajectoryError(int32_t period, double* dent) {
  auto full = SettledBox();
  auto copy = std::make_unique<SimObject>(*full);
  const int32_t top = TopMiddle(*full);
  auto mr = MultiRate::Create(std::move(copy), period, PatchOptions{0.012});
  EXPECT_TRUE(mr.ok());
  const Vec3 x0 = full->positions()[top];
  double err = 0.0;
  *dent = 0.0;
  for (int k = 0; k < 300; ++k) {
    const double ramp = std::min(1.0, k / 100.0);
    const NodeLoad load{top, Vec3(0.0, -0.6 * ramp, 0.0)};
    full->SetExternalForce(top, load.force);
    full->Step(1e-3);
    mr->Tick(std::span<const NodeLoad>(&load, 1), x0, 1e-3);
    err = std::max(err, (mr->positions()[top] - full->positions()[top]).norm());
    *dent = std::max(*dent, (full->positions()[top] - x0).norm());
  }
  EXPECT_EQ(mr->counts().rebuilds, 1);
  EXPECT_EQ(mr->counts().outside_loads, 0);
  EXPECT_EQ(mr->counts().patch_restores, 0);
  return err;
}

TEST(MultiRate, FollowsTheFullSolveCloserWithAShorterPeriod) {
  double dent = 0.0;
  const double e1 = TrajectoryError(1, &dent);
  const double e10 = TrajectoryError(10, &dent);
  EXPECT_GT(dent, 1e-3);
  EXPECT_LT(e1, 0.02 * dent) << e1 << " of " << dent;
  EXPECT_LT(e10, 0.15 * dent) << e10 << " of " << dent;  // measured: 0.34 of 3.3 mm
  EXPECT_LE(e1, e10);
}

TEST(MultiRate, RefusesABadPeriod) {
  EXPECT_FALSE(MultiRate::Create(SettledBox(), 0, PatchOptions{}).ok());
  EXPECT_FALSE(MultiRate::Create(nullptr, 5, PatchOptions{}).ok());
}

}  // namespace
}  // namespace rheo::sim
