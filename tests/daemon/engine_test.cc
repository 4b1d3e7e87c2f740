// The engine's loop, command queue and frame hub under concurrent clients (also run under TSan).
#include "daemon/engine.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include "daemon/frame_hub.h"

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
