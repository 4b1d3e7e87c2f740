// Parameter changes prepared off the stepping thread (SimObject::Prepare) give exactly what the
// direct path gives, and applying them allocates nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "alloc_counter.h"
#include "sim/primitives.h"
#include "sim/sim.h"

namespace rheo::sim {
namespace {

// A 4 x 3 x 3 box with one interior node pushed towards a neighbour: slivers around it, so a
// stiff tet_k puts some tets, not all, in the implicit system (kSplit).
TetMesh SliverBox() {
  TetMesh mesh = *MakeBoxTetMesh(4, 3, 3, Vec3(0.04, 0.03, 0.03));
  for (Vec3& x : mesh.positions) {
    if ((x - Vec3(0.02, 0.01, 0.01)).norm() < 1e-9) x += Vec3(0.0085, 0.0085, 0.0);
  }
  return mesh;
}

TEST(PreparedParameters, MatchTheDirectPathStepForStep) {
  const TetMesh mesh = SliverBox();
  const Parameters start = FindPreset("organ")->params;
  // Explicit shape springs, a split, all implicit; a density change; the explicit integrator.
  struct Case {
    double tet_k_scale, density;
    Integrator integrator;
  };
  for (const Case& c : {Case{1.0, 1000.0, Integrator::kImplicitEuler},
                        Case{3.0, 1200.0, Integrator::kImplicitEuler},
                        Case{100.0, 900.0, Integrator::kImplicitEuler},
                        Case{2.0, 1100.0, Integrator::kSymplecticEuler}}) {
    auto direct = std::move(SimObject::Create(mesh, start, c.integrator).value());
    auto prepared = std::move(SimObject::Create(mesh, start, c.integrator).value());
    for (int k = 0; k < 20; ++k) {
      direct->Step(1e-3);
      prepared->Step(1e-3);
    }
    Parameters next = start;
    next.tet_k *= c.tet_k_scale;
    next.density = c.density;
    next.k_v *= 1.3;
    ASSERT_TRUE(direct->SetParameters(next).ok());
    // Prepared on another thread while nothing else touches the object.
    Result<PreparedParameters> p = InvalidArgument("not run");
    std::thread([&] { p = prepared->Prepare(next, c.integrator, 1e-3); }).join();
    ASSERT_TRUE(p.ok()) << p.error().message;
    ASSERT_TRUE(prepared->SetParameters(*p).ok());
    EXPECT_EQ(prepared->RequiredSubsteps(1e-3), direct->RequiredSubsteps(1e-3));
    if (c.integrator == Integrator::kImplicitEuler) {
      EXPECT_EQ(prepared->ShapeSpringsTreatment(1e-3), direct->ShapeSpringsTreatment(1e-3));
      EXPECT_EQ(prepared->shape_implicit_tets(), direct->shape_implicit_tets());
    }
    for (int k = 0; k < 50; ++k) {
      direct->Step(1e-3);
      prepared->Step(1e-3);
    }
    for (int32_t i = 0; i < direct->model().num_nodes; ++i) {
      ASSERT_EQ(prepared->positions()[i], direct->positions()[i]) << "node " << i;
      ASSERT_EQ(prepared->model().mass[i], direct->model().mass[i]);
    }
  }
  // The cases above cover the three treatments.
  auto probe = std::move(SimObject::Create(mesh, start, Integrator::kImplicitEuler).value());
  Parameters split = start;
  split.tet_k *= 3.0;
  auto p = probe->Prepare(split, Integrator::kImplicitEuler, 1e-3);
  ASSERT_TRUE(p.ok());
  EXPECT_EQ(p->shape, ShapeTreatment::kSplit);
  EXPECT_GT(p->implicit_tets, 0);
  EXPECT_LT(p->implicit_tets, static_cast<int32_t>(mesh.tets.size()));
}

TEST(PreparedParameters, ApplyingDoesNotAllocateAndBadOnesAreRefused) {
  const TetMesh mesh = SliverBox();
  Parameters p = FindPreset("organ")->params;
  auto obj = std::move(SimObject::Create(mesh, p, Integrator::kImplicitEuler).value());
  obj->Step(1e-3);
  p.tet_k *= 3.0;
  auto prepared = obj->Prepare(p, Integrator::kImplicitEuler, 1e-3);
  ASSERT_TRUE(prepared.ok());
  long count = 0;
  {
    rheo::testing::AllocationCounter guard;
    const bool ok = obj->SetParameters(*prepared).ok();
    for (int k = 0; k < 10; ++k) obj->Step(1e-3);
    count = guard.count();
    EXPECT_TRUE(ok);
  }
  EXPECT_EQ(count, 0);
  EXPECT_EQ(obj->ShapeSpringsTreatment(1e-3), ShapeTreatment::kSplit);
  Parameters bad = p;
  bad.k_v = -1.0;
  auto refused = obj->Prepare(bad, Integrator::kImplicitEuler, 1e-3);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(refused.error().message.find("k_v"), std::string::npos) << refused.error().message;
}

}  // namespace
}  // namespace rheo::sim
