// The whole loop tick allocates nothing: Engine::Tick with objects entering and leaving the
// scene, prepared parameter changes, run control, the device (the network tool pressing an
// object: exchange, contact, node forces, telemetry) and the frame it publishes. The commands,
// objects, renderers and parameters are made between ticks, as the services make them; only the
// ticks are counted. Own binary: rheo_test_alloc replaces the global operator new.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <thread>
#include <vector>

#include "alloc_counter.h"
#include "daemon/device/device_link.h"
#include "daemon/loop/engine.h"
#include "sim/primitives.h"
#include "sim/sim.h"

namespace rheo::daemon {
namespace {

struct Built {
  std::unique_ptr<sim::SimObject> object;
  std::unique_ptr<ObjectContact> contact;
};

// A 4 cm box of `preset` resting on the floor at x = `x`, with its renderer.
Built MakeBox(const DeviceLink& link, const ToolTelemetry& now, const char* preset,
              sim::Integrator integrator, double x, bool first) {
  Built b;
  auto mesh = sim::MakeBoxTetMesh(4, 3, 4, Vec3(0.04, 0.03, 0.04));
  EXPECT_TRUE(mesh.ok());
  auto p = sim::FindPreset(preset);
  EXPECT_TRUE(p.ok());
  auto obj = sim::SimObject::Create(*mesh, p->params, integrator);
  EXPECT_TRUE(obj.ok()) << obj.error().message;
  b.object = std::move(*obj);
  b.object->Translate(Vec3(x - 0.02, p->params.floor_height + 0.001, -0.02));
  std::vector<uint32_t> triangles;
  for (const auto& f : mesh->surface)
    for (int32_t v : f) triangles.push_back(static_cast<uint32_t>(v));
  auto attached = link.PrepareObject(mesh->surface, triangles, b.object->positions(),
                                     b.object->model().mass, first, now);
  EXPECT_TRUE(attached.ok()) << attached.error().message;
  b.contact = std::move(attached->contact);
  return b;
}

// The network tool (no hardware, no real-time priority) and an engine never Start()ed, whose
// ticks the test thread runs.
DeviceLinkOptions NetworkTool() {
  DeviceLinkOptions o;
  o.kind = DeviceKind::kNetwork;
  o.realtime = false;
  return o;
}
EngineOptions SmallEngine() {
  EngineOptions eo;
  eo.loop.realtime_priority = false;
  eo.loop.lock_memory = false;
  eo.max_frame_vertices = 2000;
  return eo;
}

TEST(EngineTickAlloc, TheWholeTickAllocatesNothing) {
  auto opened = DeviceLink::Open(NetworkTool());
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  DeviceLink& link = **opened;
  Engine engine(SmallEngine());
  engine.AttachDevice(&link);  // never Start()ed: the test thread runs every tick

  const double dt = 1e-3;
  uint64_t tick = 0;
  long allocations = 0;
  int contact_ticks = 0;
  double max_object_force = 0.0;
  auto run = [&](int ticks) {
    for (int i = 0; i < ticks; ++i, ++tick) {
      rt::TickInfo info;
      info.tick = tick;
      info.dt = dt;
      info.deadline_ns = info.start_ns = rt::Loop::NowNs();
      {
        testing::AllocationCounter count;
        engine.TickOnce(info);
        allocations += count.count();
      }
      // The frame hub's side, between ticks: take the frame, free what the loop retired.
      if (engine.AcquireFrame()) {
        const LoopFrame& f = engine.frame();
        if (f.tool.in_contact) ++contact_ticks;
        max_object_force = std::max(max_object_force, -f.tool.object_force[1]);
      }
      engine.DrainRetired();
    }
  };
  auto submit = [&](Command c) { ASSERT_NE(engine.Submit(c), 0u); };

  // An explicit soft box placed first (it places the workspace over itself), then an implicit
  // hard one beside it (shape springs in the linear system).
  Built soft = MakeBox(link, engine.tool(), "soft-jelly", sim::Integrator::kSymplecticEuler, 0.0,
                       /*first=*/true);
  Command origin;
  origin.type = Command::Type::kSetToolOrigin;
  const Vec3 above = soft.object->positions()[0];  // any point: the tool is moved below
  origin.vec = {0.0, above.y() + 0.05, 0.0};
  submit(origin);
  Command add;
  add.type = Command::Type::kAddObject;
  add.instance_id = 1;
  add.object = soft.object.release();
  add.contact = soft.contact.release();
  submit(add);
  Built hard = MakeBox(link, engine.tool(), "hard-jelly", sim::Integrator::kImplicitEuler, 0.08,
                       /*first=*/false);
  add.instance_id = 2;
  add.object = hard.object.get();
  add.contact = hard.contact.get();
  const sim::SimObject* hard_object = hard.object.get();
  submit(add);
  hard.object.release();
  hard.contact.release();
  run(50);
  ASSERT_EQ(engine.object_count(), 2);
  EXPECT_EQ(engine.frame().object_count, 2u);

  // The network tool comes down onto the soft box's top (0.05 m above to 0.01 m into it).
  NetworkDevice* net = link.network();
  ASSERT_NE(net, nullptr);
  for (int i = 0; i < 400; ++i) {
    drivers::Pose pose;
    pose.position = Vec3(0.0, -0.05 - 0.03 * std::min(1.0, i / 300.0), 0.0);
    net->Push(pose, 0);
    run(1);
  }
  EXPECT_GT(contact_ticks, 20) << "the tool should have pressed the soft box";
  EXPECT_GT(max_object_force, 0.01) << "the box should have been pushed down [N]";

  // A prepared parameter change of the hard box (made off the loop, copied in by the tick).
  sim::Parameters stiffer = hard_object->parameters();
  stiffer.k_v *= 2.0;
  auto prepared = hard_object->Prepare(stiffer, sim::Integrator::kImplicitEuler, dt);
  ASSERT_TRUE(prepared.ok()) << prepared.error().message;
  Command set;
  set.type = Command::Type::kSetParameters;
  set.instance_id = 2;
  set.params = new sim::PreparedParameters(std::move(*prepared));
  submit(set);
  run(20);
  EXPECT_DOUBLE_EQ(hard_object->parameters().k_v, stiffer.k_v);

  // Run control, device commands, then the soft box leaves the scene.
  for (Command::Type type : {Command::Type::kPause, Command::Type::kStep, Command::Type::kResume,
                             Command::Type::kReset, Command::Type::kDeviceClear}) {
    Command c;
    c.type = type;
    submit(c);
    run(5);
  }
  Command remove;
  remove.type = Command::Type::kRemoveObject;
  remove.instance_id = 1;
  submit(remove);
  run(50);
  EXPECT_EQ(engine.object_count(), 1);
  EXPECT_EQ(engine.frame().object_count, 1u);
  EXPECT_EQ(engine.commands_applied(), 10u);  // every command above

  EXPECT_EQ(allocations, 0) << "allocations in " << tick << " ticks";
  EXPECT_GT(tick, 500u);
}

// A multi-rate object pressed by the network tool: the loop's side (the patch's tick, the loads,
// the syncs taking the whole's results and the patches it built as the tool moved) allocates
// nothing on the ticking thread; the whole's thread does the allocating.
TEST(EngineTickAlloc, AMultiRateObjectPressedAllocatesNothingOnTheLoop) {
  auto opened = DeviceLink::Open(NetworkTool());
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  DeviceLink& link = **opened;
  Engine engine(SmallEngine());
  engine.AttachDevice(&link);

  Built box = MakeBox(link, engine.tool(), "organ", sim::Integrator::kImplicitEuler, 0.0, true);
  const Vec3 top = box.object->positions()[0];
  Command origin;
  origin.type = Command::Type::kSetToolOrigin;
  origin.vec = {0.0, top.y() + 0.05, 0.0};
  ASSERT_NE(engine.Submit(origin), 0u);
  double top_y = -1e9;
  for (const Vec3& x : box.object->positions()) top_y = std::max(top_y, x.y());
  auto mr = MultiRateObject::Create(std::move(box.object), 10, {}, Vec3(0.0, top_y, 0.0));
  ASSERT_TRUE(mr.ok()) << mr.error().message;
  const MultiRateObject* multirate = mr->get();
  Command add;
  add.type = Command::Type::kAddObject;
  add.instance_id = 1;
  add.multirate = mr->release();
  add.contact = box.contact.release();
  ASSERT_NE(engine.Submit(add), 0u);

  long allocations = 0;
  int contact_ticks = 0;
  auto next = std::chrono::steady_clock::now();
  for (uint64_t tick = 0; tick < 1200; ++tick) {
    if (tick >= 100) {
      // Down onto the box, then sideways 1.5 cm along its top (the patch is built again on the
      // way).
      const double s = std::min(1.0, (tick - 100) / 400.0);
      const double side = tick > 700 ? 0.015 * std::min(1.0, (tick - 700) / 300.0) : 0.0;
      drivers::Pose pose;
      pose.position = Vec3(side, (top_y - (origin.vec[1])) - 0.006 * s, 0.0);
      link.network()->Push(pose, 0);
    }
    rt::TickInfo info;
    info.tick = tick;
    info.dt = 1e-3;
    info.deadline_ns = info.start_ns = rt::Loop::NowNs();
    {
      testing::AllocationCounter count;
      engine.TickOnce(info);
      allocations += count.count();
    }
    if (engine.AcquireFrame() && engine.frame().tool.in_contact) ++contact_ticks;
    engine.DrainRetired();
    next += std::chrono::milliseconds(1);  // real time, so that the whole keeps pace
    std::this_thread::sleep_until(next);
  }
  EXPECT_GT(contact_ticks, 100) << "the tool should have pressed the box";
  const MultiRateStats st = multirate->stats();
  EXPECT_GT(st.syncs, 50u);
  EXPECT_GE(st.rebuilds, 2u) << "the tool moved 1.5 cm: the patch should have been built again";
  EXPECT_EQ(allocations, 0) << "allocations on the loop's thread";
  Command remove;
  remove.type = Command::Type::kRemoveObject;
  remove.instance_id = 1;
  ASSERT_NE(engine.Submit(remove), 0u);
  rt::TickInfo info;
  info.tick = 1200;
  info.dt = 1e-3;
  info.deadline_ns = info.start_ns = rt::Loop::NowNs();
  engine.TickOnce(info);
  engine.DrainRetired();
}

}  // namespace
}  // namespace rheo::daemon
