// Step, the force input, parameter changes, recovery and diagnostics never touch the heap:
// this binary replaces the global operator new and counts calls inside a guarded block.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>

#include "sim/primitives.h"
#include "sim/sim.h"

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
}  // namespace

void* operator new(std::size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  return operator new(n);
}
void* operator new(std::size_t n, std::align_val_t al) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  const std::size_t a = static_cast<std::size_t>(al);
  if (void* p = std::aligned_alloc(a, (n + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t al) {
  return operator new(n, al);
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}

namespace rheo::sim {
namespace {

// Counts heap allocations between construction and count().
class AllocationGuard {
 public:
  AllocationGuard() {
    g_allocations = 0;
    g_counting = true;
  }
  ~AllocationGuard() { g_counting = false; }
  long count() const { return g_allocations.load(); }
};

TEST(NoAllocation, GuardSeesAllocations) {
  AllocationGuard guard;
  auto* p = new std::vector<int>(10);
  const long n = guard.count();
  delete p;
  EXPECT_GE(n, 2);  // the vector and its buffer: the guard can fail
}

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
        AllocationGuard guard;
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
        AllocationGuard guard;
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
        g_counting = false;
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
  AllocationGuard guard;
  for (const ParameterInfo& info : ParameterTable()) {
    const double value = (**obj).parameters().*(info.field);
    ok &= (**obj).SetParameter(info.name, value).ok();
  }
  (**obj).Step(1e-3);
  const long count = guard.count();
  g_counting = false;
  EXPECT_TRUE(ok);
  EXPECT_EQ(count, 0);
}

}  // namespace
}  // namespace rheo::sim
