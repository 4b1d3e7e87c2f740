// The loop's side of session recording: a tick that hands its record to the tick ring allocates
// nothing, a full ring drops the record and counts it (the loop never waits), and an inactive
// ring costs no push at all. Own binary: rheo_test_alloc replaces the global operator new.
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "alloc_counter.h"
#include "daemon/loop/engine.h"
#include "daemon/loop/tick_ring.h"
#include "sim/primitives.h"
#include "sim/sim.h"

namespace rheo::daemon {
namespace {

TEST(TickRingAlloc, RecordedTicksAllocateNothingAndAFullRingCountsItsDrops) {
  EngineOptions eo;
  eo.loop.realtime_priority = false;
  eo.loop.lock_memory = false;
  eo.max_frame_vertices = 2000;
  Engine engine(eo);  // never Start()ed: the test thread runs every tick
  auto ring = std::make_unique<TickRing>();
  engine.AttachTickRing(ring.get());
  // An object in the scene, so the tick does its whole work.
  auto mesh = sim::MakeBoxTetMesh(3, 3, 3, Vec3(0.03, 0.03, 0.03));
  ASSERT_TRUE(mesh.ok());
  auto preset = sim::FindPreset("soft-jelly");
  ASSERT_TRUE(preset.ok());
  auto object = sim::SimObject::Create(*mesh, preset->params, sim::Integrator::kImplicitEuler);
  ASSERT_TRUE(object.ok()) << object.error().message;
  Command add;
  add.type = Command::Type::kAddObject;
  add.instance_id = 1;
  add.object = object->release();
  ASSERT_NE(engine.Submit(add), 0u);

  uint64_t tick = 0;
  long allocations = 0;
  auto run = [&](size_t ticks) {
    for (size_t i = 0; i < ticks; ++i, ++tick) {
      rt::TickInfo info;
      info.tick = tick;
      info.dt = 1e-3;
      info.deadline_ns = info.start_ns = rt::Loop::NowNs();
      testing::AllocationCounter count;
      engine.TickOnce(info);
      allocations += count.count();
    }
  };
  run(10);
  EXPECT_EQ(ring->waiting(), 0u) << "no recording: nothing is pushed";

  const uint32_t session = ring->Begin();
  run(TickRing::kCapacity + 100);
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(ring->waiting(), TickRing::kCapacity);
  EXPECT_EQ(ring->dropped(), 100u);
  ring->End();
  run(5);
  EXPECT_EQ(ring->waiting(), TickRing::kCapacity) << "ended: nothing more is pushed";

  std::vector<TickRecord> out(1024);
  uint64_t expect = 10, popped = 0;
  while (size_t n = ring->Pop(out.data(), out.size())) {
    for (size_t i = 0; i < n; ++i) {
      ASSERT_EQ(out[i].session, session);
      ASSERT_EQ(out[i].tick, expect) << "the ring keeps the oldest, drops the newest";
      EXPECT_EQ(out[i].tool.present, false);  // no device attached
      ++expect;
    }
    popped += n;
  }
  EXPECT_EQ(popped, TickRing::kCapacity);
  EXPECT_EQ(allocations, 0);
}

}  // namespace
}  // namespace rheo::daemon
