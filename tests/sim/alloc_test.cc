// Step, the force input, parameter changes, recovery and diagnostics never touch the heap:
// the binary counts allocations per thread (rheo_test_alloc) inside a counted block.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "alloc_counter.h"
#include "sim/multirate.h"
#include "sim/primitives.h"
#include "sim/sim.h"

namespace rheo::sim {
namespace {

using rheo::testing::AllocationCounter;

TEST(NoAllocation, StepAndInputsOnEveryPresetAndIntegrator) {
  auto mesh = MakeEllipsoidTetMesh(3, Vec3(0.05, 0.04, 0.05), Vec3(0, 0.06, 0));
  ASSERT_TRUE(mesh.ok());
  for (const Preset& preset : Presets()) {
    for (Integrator integrator : {Integrator::kSymplecticEuler, Integrator::kImplicitEuler}) {
      auto obj = SimObject::Create(*mesh, preset.params, integrator);
      ASSERT_TRUE(obj.ok());
      SimObject& s = **obj;
      s.Step(1e-3);  // nothing lazily allocated on first use either, but warm anyway
      long allocations = 0;
      {
        AllocationCounter guard;
        for (int k = 0; k < 60; ++k) {
          s.SetExternalForce(k % s.model().num_nodes, Vec3(0, -0.2, 0));
          const StepResult r = s.Step(1e-3);
          (void)r;
        }
        (void)s.SetParameter("k_v", preset.params.k_v * 1.5);
        (void)s.SetParameter("density", 1100.0);
        (void)s.SetParameter("k_v", -1.0);  // rejected: the error path may allocate its message
        allocations += guard.count();
      }
      {
        AllocationCounter guard;
        s.ClearExternalForces();
        for (int k = 0; k < 30; ++k) s.Step(1e-3);
        // Inject an explosion: detection and restore must not allocate either.
        const bool injected = s.SetNodeState(0, s.positions()[0], Vec3(1e7, 0, 0));
        const StepResult r = s.Step(1e-3);
        const Diagnostics d = s.ComputeDiagnostics();
        s.Translate(Vec3(0, 0.01, 0));
        s.Reset();
        for (int k = 0; k < 10; ++k) s.Step(1e-3);
        const long count = guard.count();
        EXPECT_TRUE(injected);
        EXPECT_TRUE(r.restored);
        EXPECT_TRUE(d.finite);
        EXPECT_EQ(count, 0) << preset.name << " " << IntegratorName(integrator);
      }
      // The rejected SetParameter builds an error string; everything else must be free.
      EXPECT_LE(allocations, 8) << preset.name << " " << IntegratorName(integrator);
    }
  }
}

TEST(NoAllocation, ValidSetParameterDoesNotAllocate) {
  auto mesh = MakeBoxTetMesh(3, 3, 3, Vec3(0.05, 0.05, 0.05));
  ASSERT_TRUE(mesh.ok());
  auto obj = SimObject::Create(*mesh, "organ");
  ASSERT_TRUE(obj.ok());
  bool ok = true;
  AllocationCounter guard;
  for (const ParameterInfo& info : ParameterTable()) {
    const double value = (**obj).parameters().*(info.field);
    ok &= (**obj).SetParameter(info.name, value).ok();
  }
  (**obj).Step(1e-3);
  const long count = guard.count();
  EXPECT_TRUE(ok);
  EXPECT_EQ(count, 0);
}

// The multi-rate scheme's per-tick half (tool loads, the patch's step) and a sync that keeps its
// patch (Follow, the window swap, the whole's step) never allocate.
TEST(NoAllocation, MultiRateTicksAndSyncsWithoutARebuild) {
  auto mesh = MakeBoxTetMesh(4, 3, 4, Vec3(0.06, 0.03, 0.06));
  ASSERT_TRUE(mesh.ok());
  auto obj = SimObject::Create(*mesh, "organ");
  ASSERT_TRUE(obj.ok());
  (**obj).SetIntegrator(Integrator::kImplicitEuler);
  auto mr = MultiRate::Create(std::move(*obj), 5, PatchOptions{0.02});
  ASSERT_TRUE(mr.ok()) << mr.error().message;
  const Vec3 focus(0.03, 0.03, 0.03);
  NodeLoad loads[3];
  auto tick = [&](int k) {
    int32_t n = 0;
    for (int32_t i = 0; i < mr->whole().model().num_nodes && n < 3; ++i)
      if (mr->patch() && mr->patch()->IsInner(i)) loads[n++] = {i, Vec3(0, -0.1 * (k % 3), 0)};
    mr->Tick(std::span<const NodeLoad>(loads, n), focus, 1e-3);
  };
  tick(0);  // builds the patch (allocates)
  ASSERT_NE(mr->patch(), nullptr);
  AllocationCounter guard;
  for (int k = 1; k < 40; ++k) tick(k);
  const long count = guard.count();
  EXPECT_EQ(count, 0);
  EXPECT_EQ(mr->counts().rebuilds, 1);
  EXPECT_EQ(mr->counts().syncs, 8);
}

}  // namespace
}  // namespace rheo::sim
