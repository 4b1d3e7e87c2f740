// Where the tool goes: the press point of an object and the plan of an emulated-hand press.
#include "daemon/device/tool_placement.h"

#include <gtest/gtest.h>

#include <vector>

#include "sim/primitives.h"

namespace rheo::daemon {
namespace {

std::vector<uint32_t> Triangles(const TetMesh& m) {
  std::vector<uint32_t> t;
  for (const auto& f : m.surface)
    for (int32_t v : f) t.push_back(static_cast<uint32_t>(v));
  return t;
}

TEST(ToolPlacement, PressPointIsTheHighestUpFacingVertex) {
  auto box = sim::MakeBoxTetMesh(2, 2, 2, Vec3(0.04, 0.02, 0.04));
  ASSERT_TRUE(box.ok());
  const Vec3 p = PressPoint(Triangles(*box), box->positions);
  EXPECT_NEAR(p.y(), 0.02, 1e-12);  // on the top face
  const Vec3 o = WorkspaceOriginOver(Triangles(*box), box->positions, 0.003);
  EXPECT_NEAR(o.y(), 0.02 + 0.003 + kToolClearance, 1e-12);
}

TEST(ToolPlacement, PressPointPrefersTheBodyOverAThinRaisedLobe) {
  // A 2 cm thick body and, beside it, a 3 mm thin lobe lifted above the body's top.
  auto body = sim::MakeBoxTetMesh(3, 2, 3, Vec3(0.04, 0.02, 0.04));
  auto lobe = sim::MakeBoxTetMesh(3, 1, 3, Vec3(0.03, 0.003, 0.03));
  ASSERT_TRUE(body.ok() && lobe.ok());
  TetMesh both = *body;
  const int32_t base = static_cast<int32_t>(both.positions.size());
  for (const Vec3& x : lobe->positions) both.positions.push_back(x + Vec3(0.06, 0.025, 0.0));
  for (auto f : lobe->surface) {
    for (int32_t& v : f) v += base;
    both.surface.push_back(f);
  }
  const Vec3 p = PressPoint(Triangles(both), both.positions);
  EXPECT_NEAR(p.y(), 0.02, 1e-12) << "pressed the lobe at x = " << p.x();
  EXPECT_LE(p.x(), 0.04);
}

TEST(ToolPlacement, TheSurfaceOnALineIsWhereItCrossesATriangle) {
  auto box = sim::MakeBoxTetMesh(2, 2, 2, Vec3(0.04, 0.02, 0.04));
  ASSERT_TRUE(box.ok());
  std::vector<float> xyz;
  for (const Vec3& x : box->positions)
    for (int k = 0; k < 3; ++k) xyz.push_back(static_cast<float>(x[k]));
  const auto tri = Triangles(*box);
  const auto n = static_cast<uint32_t>(box->positions.size());
  double y = 0.0;
  ASSERT_TRUE(SurfaceTopOnLine(tri, xyz.data(), n, 0.013, 0.027, &y));
  EXPECT_NEAR(y, 0.02, 1e-6);  // the top face, not the bottom one
  ASSERT_TRUE(SurfaceTopOnLine(tri, xyz.data(), n, 0.02, 0.02, &y));  // through a vertex
  EXPECT_NEAR(y, 0.02, 1e-6);
  EXPECT_FALSE(SurfaceTopOnLine(tri, xyz.data(), n, 0.05, 0.02, &y));  // beside the box
}

PressRequest Request() {
  PressRequest r;
  r.line = Vec3(0.0, 0.0, 0.0);
  r.surface_y = 0.04;
  r.highest_y = 0.045;
  r.depth = 0.01;
  r.seconds = 1.0;
  r.grip = Vec3(0.0, 0.0, 0.0);
  r.origin = Vec3(0.0, 0.048, 0.0);
  r.half_extent = Vec3(0.06, 0.06, 0.06);
  r.tip_radius = 0.003;
  return r;
}

// Every sideways segment of the plan stays above every object (tool height in the scene).
void ExpectSidewaysMovesClear(const PressRequest& r, const PressPlan& plan) {
  const double safe = r.highest_y + r.tip_radius + kToolClearance - 1e-12;
  Vec3 at = r.grip;
  Vec3 origin = r.origin;
  auto check = [&](const std::vector<PressPlan::Waypoint>& points) {
    for (const auto& w : points) {
      const bool sideways =
          (w.grip - at).head<1>().norm() > 1e-9 || std::abs(w.grip.z() - at.z()) > 1e-9;
      if (sideways) {
        EXPECT_GE(origin.y() + at.y(), safe);
        EXPECT_GE(origin.y() + w.grip.y(), safe);
      }
      at = w.grip;
    }
  };
  check(plan.before);
  if (plan.replace_origin) {
    EXPECT_GE(origin.y() + at.y(), safe);  // the jump starts above every object...
    origin = plan.new_origin;
    EXPECT_GE(origin.y() + at.y(), safe);  // ...and ends above them, over the line
    EXPECT_NEAR(origin.x() + at.x(), r.line.x(), 1e-12);
    EXPECT_NEAR(origin.z() + at.z(), r.line.z(), 1e-12);
  }
  check(plan.after);
  EXPECT_NEAR(origin.y() + plan.goal.y(), r.surface_y + r.tip_radius - r.depth, 1e-12);
  EXPECT_NEAR(origin.x() + plan.goal.x(), r.line.x(), 1e-12);
}

TEST(ToolPlacement, APressUnderTheToolGoesStraightDown) {
  const PressRequest r = Request();
  auto plan = PlanPress(r);
  ASSERT_TRUE(plan.ok()) << plan.error().message;
  EXPECT_FALSE(plan->replace_origin);
  ASSERT_EQ(plan->before.size(), 1u);
  EXPECT_NEAR(plan->goal.y(), 0.04 + 0.003 - 0.01 - 0.048, 1e-12);
  ExpectSidewaysMovesClear(r, *plan);
}

TEST(ToolPlacement, APressBesideTheToolRisesAndMovesOverFirst) {
  PressRequest r = Request();
  r.line = Vec3(0.03, 0.0, -0.02);
  r.grip = Vec3(0.0, -0.03, 0.0);  // low, beside the object
  auto plan = PlanPress(r);
  ASSERT_TRUE(plan.ok()) << plan.error().message;
  EXPECT_FALSE(plan->replace_origin);
  EXPECT_EQ(plan->before.size(), 3u);  // rise, move over, press
  ExpectSidewaysMovesClear(r, *plan);
}

TEST(ToolPlacement, AnObjectOutOfReachMovesTheWorkspaceOverIt) {
  PressRequest r = Request();
  // The object fell over: its top is 9 cm lower and 8 cm to the side of the workspace centre.
  r.line = Vec3(0.08, 0.0, 0.01);
  r.surface_y = 0.02;
  r.highest_y = 0.022;
  r.origin = Vec3(0.0, 0.12, 0.0);
  auto plan = PlanPress(r);
  ASSERT_TRUE(plan.ok()) << plan.error().message;
  EXPECT_TRUE(plan->replace_origin);
  EXPECT_TRUE((plan->goal.array().abs() <= r.half_extent.array()).all());
  ExpectSidewaysMovesClear(r, *plan);
}

TEST(ToolPlacement, AnUnreachableSurfaceIsRefusedWithAReason) {
  PressRequest r = Request();
  r.highest_y = 0.3;  // something towers over the workspace
  auto plan = PlanPress(r);
  ASSERT_FALSE(plan.ok());
  EXPECT_EQ(plan.error().code, ErrorCode::kFailedPrecondition);
  EXPECT_NE(plan.error().message.find("workspace"), std::string::npos);
}

}  // namespace
}  // namespace rheo::daemon
