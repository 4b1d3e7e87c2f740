// A multi-rate object on the engine: the patch on the loop, the whole on its own thread (also run
// under TSan: the hand-over between the two is the point).
#include "daemon/loop/multirate_object.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "daemon/loop/engine.h"
#include "sim/primitives.h"
#include "sim/sim.h"

namespace rheo::daemon {
namespace {

using namespace std::chrono_literals;

// An organ-preset box, 8 x 4 x 6 cm, resting on the floor.
std::unique_ptr<sim::SimObject> Box() {
  auto mesh = sim::MakeBoxTetMesh(8, 4, 6, Vec3(0.08, 0.04, 0.06));
  EXPECT_TRUE(mesh.ok());
  auto preset = sim::FindPreset("organ");
  EXPECT_TRUE(preset.ok());
  auto o = sim::SimObject::Create(*mesh, preset->params, sim::Integrator::kImplicitEuler);
  EXPECT_TRUE(o.ok()) << o.error().message;
  (*o)->Translate(Vec3(-0.04, preset->params.floor_height, -0.03));
  return std::move(*o);
}

// The free node nearest the top centre of the box.
int32_t TopNode(const sim::SimObject& o) {
  int32_t best = -1;
  double best_d = 1e9;
  const auto x = o.positions();
  for (int32_t i = 0; i < static_cast<int32_t>(x.size()); ++i) {
    const double d = (x[i] - Vec3(0.0, 0.04 + o.parameters().floor_height, 0.0)).norm();
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return best;
}

TEST(MultiRateObject, RefusesTheExplicitIntegratorAndAFocusFarFromTheObject) {
  auto mesh = sim::MakeBoxTetMesh(3, 3, 3, Vec3(0.03, 0.03, 0.03));
  ASSERT_TRUE(mesh.ok());
  auto o = sim::SimObject::Create(*mesh, "soft-jelly");
  ASSERT_TRUE(o.ok());
  (*o)->SetIntegrator(sim::Integrator::kSymplecticEuler);
  auto refused = MultiRateObject::Create(std::move(*o), 10, {}, Vec3::Zero());
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("implicit integrator"), std::string::npos);
  auto far = MultiRateObject::Create(Box(), 10, {}, Vec3(1.0, 1.0, 1.0));
  ASSERT_FALSE(far.ok());
  EXPECT_NE(far.error().message.find("no free node"), std::string::npos);
  auto bad = MultiRateObject::Create(Box(), 0, {}, Vec3::Zero());
  ASSERT_FALSE(bad.ok());
}

// A load held on the top node: the multi-rate object, ticked from this thread with its whole on
// its own, settles where a full solve of the same box settles under the same load.
TEST(MultiRateObject, AHeldLoadDentsTheBoxAsTheFullSolveDoes) {
  const double dt = 1e-3;
  std::unique_ptr<sim::SimObject> full = Box();
  const int32_t top = TopNode(*full);
  const Vec3 load(0.0, -1.0, 0.0);  // 1 N down
  const Vec3 focus = full->positions()[top];
  auto made = MultiRateObject::Create(Box(), 10, {}, focus);
  ASSERT_TRUE(made.ok()) << made.error().message;
  MultiRateObject& mr = **made;
  full->SetExternalForce(top, load);
  // In real time, as the loop runs it: a tick a millisecond, so that the whole keeps up.
  auto next = std::chrono::steady_clock::now();
  for (int t = 0; t < 1500; ++t) {
    mr.ClearLoads();
    ASSERT_TRUE(mr.AddLoad({top, load, 0.0}));
    mr.SetFocus(focus);
    mr.Tick(dt);
    full->Step(dt);
    next += 1ms;
    std::this_thread::sleep_until(next);
  }
  const MultiRateStats st = mr.stats();
  EXPECT_GT(st.syncs, 100u);
  EXPECT_GE(st.rebuilds, 1u);
  EXPECT_GT(st.patch_inner_nodes, 0);
  EXPECT_EQ(st.whole_restores + st.patch_restores, 0u);
  const double dent_full = focus.y() - full->positions()[top].y();
  const double dent_mr = focus.y() - mr.positions()[top].y();
  std::printf("dent under 1 N: full solve %.3f mm, multi-rate %.3f mm; %llu syncs\n",
              dent_full * 1e3, dent_mr * 1e3, static_cast<unsigned long long>(st.syncs));
  EXPECT_GT(dent_full, 1e-3) << "1 N should dent the organ box by millimetres";
  EXPECT_NEAR(dent_mr, dent_full, 0.15 * dent_full) << "full " << dent_full << " m";
  for (const Vec3& x : mr.positions()) ASSERT_TRUE(x.allFinite());
}

// On a running engine: added, loaded, given new parameters, reset, removed, while the whole's
// thread steps (TSan checks the hand-over; the destructor joins the thread off the loop).
TEST(MultiRateObject, OnTheRunningEngineParametersResetAndRemoval) {
  EngineOptions eo;
  eo.loop.realtime_priority = false;
  eo.loop.lock_memory = false;
  Engine engine(eo);
  engine.Start();
  std::unique_ptr<sim::SimObject> box = Box();
  const int32_t top = TopNode(*box);
  const Vec3 focus = box->positions()[top];
  sim::Parameters params = box->parameters();
  auto made = MultiRateObject::Create(std::move(box), 10, {}, focus);
  ASSERT_TRUE(made.ok()) << made.error().message;
  const MultiRateObject* mr = made->get();
  Command add;
  add.type = Command::Type::kAddObject;
  add.instance_id = 7;
  add.multirate = made->release();
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(add), 5'000'000'000));
  std::this_thread::sleep_for(300ms);
  EXPECT_GT(mr->stats().syncs, 5u);

  params.k_v *= 2.0;
  Command set;
  set.type = Command::Type::kSetParameters;
  set.instance_id = 7;
  set.params = new sim::PreparedParameters{};
  set.params->params = params;
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(set), 5'000'000'000));
  const uint64_t rebuilds = mr->stats().rebuilds;
  std::this_thread::sleep_for(200ms);
  // Taken in at the whole's next step, the patch built again with them.
  EXPECT_GT(mr->stats().rebuilds, rebuilds);

  Command reset;
  reset.type = Command::Type::kReset;
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(reset), 5'000'000'000));
  std::this_thread::sleep_for(100ms);
  while (engine.AcquireFrame()) {
  }
  const LoopFrame& f = engine.frame();
  ASSERT_EQ(f.object_count, 1u);
  EXPECT_TRUE(f.objects[0].multi_rate);
  EXPECT_EQ(f.objects[0].restores, 0u);
  for (uint32_t k = 0; k < 3 * f.objects[0].vertex_count; ++k)
    ASSERT_TRUE(std::isfinite(f.positions[k]));

  Command remove;
  remove.type = Command::Type::kRemoveObject;
  remove.instance_id = 7;
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(remove), 5'000'000'000));
  engine.DrainRetired();  // joins the whole's thread, here
  EXPECT_EQ(engine.object_count(), 0);
  engine.Stop();
}

}  // namespace
}  // namespace rheo::daemon
