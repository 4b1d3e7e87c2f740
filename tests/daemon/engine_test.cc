// The engine's loop, command queue and frame hub under concurrent clients (also run under TSan).
#include "daemon/loop/engine.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include "daemon/loop/frame_hub.h"
#include "sim/primitives.h"
#include "sim/sim.h"

namespace rheo::daemon {
namespace {

EngineOptions TestOptions() {
  EngineOptions o;
  o.loop.realtime_priority = false;
  o.loop.lock_memory = false;
  return o;
}

TEST(Engine, CommandsFromManyThreadsAreAllAppliedInOrderPerThread) {
  Engine engine(TestOptions());
  engine.Start();
  constexpr int kThreads = 4;
  constexpr int kEach = 50;
  std::vector<std::thread> threads;
  std::atomic<int> refused{0};
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      uint64_t last = 0;
      for (int i = 0; i < kEach; ++i) {
        Command c;
        c.type = (i % 2 == 0) ? Command::Type::kPause : Command::Type::kResume;
        uint64_t seq = engine.Submit(c);
        if (seq == 0) {
          refused.fetch_add(1);
          continue;
        }
        EXPECT_GT(seq, last);
        last = seq;
        EXPECT_TRUE(engine.WaitApplied(seq, 5'000'000'000)) << "thread " << t << " seq " << seq;
      }
    });
  }
  for (auto& th : threads) th.join();
  EXPECT_EQ(engine.commands_applied() + static_cast<uint64_t>(refused.load()),
            static_cast<uint64_t>(kThreads * kEach));
  engine.Stop();
}

TEST(Engine, PauseStopsTimeAndStepAdvancesOneTick) {
  Engine engine(TestOptions());
  engine.Start();
  Command pause;
  pause.type = Command::Type::kPause;
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(pause), 5'000'000'000));
  const double t0 = engine.sim_time();
  Command step;
  step.type = Command::Type::kStep;
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(step), 5'000'000'000));
  // The step takes effect in the tick that applied it; wait one more command round trip.
  Command none;
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(none), 5'000'000'000));
  EXPECT_NEAR(engine.sim_time() - t0, 1e-3, 1e-12);
  engine.Stop();
}

// Parameter changes are prepared on the caller's thread while the loop steps the same object
// (SimObject::Prepare is const and reads only what the loop never writes), then applied by the
// loop. Under TSan this is the check that the two do not race.
TEST(Engine, ParametersPreparedWhileTheLoopStepsTheObject) {
  Engine engine(TestOptions());
  engine.Start();
  auto mesh = sim::MakeBoxTetMesh(4, 3, 3, Vec3(0.04, 0.03, 0.03));
  ASSERT_TRUE(mesh.ok());
  sim::Parameters params = sim::FindPreset("organ")->params;
  auto made = sim::SimObject::Create(*mesh, params, sim::Integrator::kImplicitEuler);
  ASSERT_TRUE(made.ok());
  const sim::SimObject* object = made->get();
  Command add;
  add.type = Command::Type::kAddObject;
  add.instance_id = 1;
  add.object = made->release();
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(add), 5'000'000'000));
  for (int k = 0; k < 20; ++k) {
    params.k_v = 150.0 + 10.0 * k;
    params.tet_k = 0.1 * (1 + k % 4);
    params.density = 900.0 + 10.0 * k;
    auto prepared = object->Prepare(params, sim::Integrator::kImplicitEuler, 1e-3);
    ASSERT_TRUE(prepared.ok()) << prepared.error().message;
    Command c;
    c.type = Command::Type::kSetParameters;
    c.instance_id = 1;
    c.params = new sim::PreparedParameters(std::move(prepared).value());
    const uint64_t seq = engine.Submit(c);
    ASSERT_NE(seq, 0u);
    ASSERT_TRUE(engine.WaitApplied(seq, 5'000'000'000));
    engine.DrainRetired();
  }
  Command pause;
  pause.type = Command::Type::kPause;
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(pause), 5'000'000'000));
  EXPECT_EQ(object->parameters().k_v, params.k_v);
  EXPECT_EQ(object->parameters().density, params.density);
  for (const Vec3& x : object->positions()) ASSERT_TRUE(x.allFinite());
  engine.Stop();
}

TEST(FrameHub, ManyClientsEachSeeNewerFramesAndStopWakesThemAll) {
  Engine engine(TestOptions());
  engine.Start();
  FrameHub hub(engine);
  hub.Start();
  constexpr int kClients = 8;
  std::atomic<int> finished{0};
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&, c] {
      int h = hub.Register(50.0 + 100.0 * c);
      uint64_t seq = 0, tick = 0;
      int frames = 0;
      while (true) {
        auto snap = hub.WaitNewer(seq, std::chrono::steady_clock::now() + std::chrono::seconds(10),
                                  [&] { return false; });
        if (!snap) break;  // hub stopped
        EXPECT_GT(snap->seq, seq);
        EXPECT_GE(snap->frame.tick, tick);
        seq = snap->seq;
        tick = snap->frame.tick;
        ++frames;
        if (c % 2 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));  // slow client
      }
      EXPECT_GT(frames, 0);
      hub.Unregister(h);
      finished.fetch_add(1);
    });
  }
  // Let every client see a few frames, then stop: all must return promptly.
  auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(200);
  while (std::chrono::steady_clock::now() < until) std::this_thread::yield();
  EXPECT_EQ(hub.clients(), kClients);
  hub.Stop();
  for (auto& t : clients) t.join();
  EXPECT_EQ(finished.load(), kClients);
  EXPECT_EQ(hub.clients(), 0);
  EXPECT_GT(engine.loop().stats().ticks.load(), 0u);
  engine.Stop();
}

}  // namespace
}  // namespace rheo::daemon
