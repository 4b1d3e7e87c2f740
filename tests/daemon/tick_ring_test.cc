// The tick ring between the running loop (producer) and a reader thread (consumer), as the
// recorder uses it: every tick of a session arrives once, in order, and nothing of an ended
// session leaks into the next one's records (label rt: also run under TSan).
#include "daemon/loop/tick_ring.h"

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <thread>
#include <vector>

#include "daemon/loop/engine.h"

namespace rheo::daemon {
namespace {

using namespace std::chrono_literals;

TEST(TickRing, TheRunningLoopHandsEveryTickOfASessionOverInOrder) {
  EngineOptions eo;
  eo.loop.realtime_priority = false;
  eo.loop.lock_memory = false;
  eo.max_frame_vertices = 100;
  Engine engine(eo);
  auto ring = std::make_unique<TickRing>();
  engine.AttachTickRing(ring.get());
  engine.Start();
  std::vector<TickRecord> batch(256);
  for (int round = 0; round < 2; ++round) {
    const uint32_t session = ring->Begin();
    uint64_t first = 0, last = 0, n = 0, gaps = 0, other = 0;
    const auto end = std::chrono::steady_clock::now() + 400ms;
    auto take = [&] {
      while (size_t k = ring->Pop(batch.data(), batch.size()))
        for (size_t i = 0; i < k; ++i) {
          if (batch[i].session != session) {
            ++other;  // the ended session's last tick, at most one
            continue;
          }
          if (n == 0) first = batch[i].tick;
          gaps += n > 0 && batch[i].tick != last + 1;
          last = batch[i].tick;
          ++n;
        }
    };
    while (std::chrono::steady_clock::now() < end) {
      take();
      std::this_thread::sleep_for(5ms);
    }
    ring->End();
    std::this_thread::sleep_for(10ms);  // the tick under way may still push one record
    take();
    EXPECT_GT(n, 100u) << "round " << round;
    EXPECT_EQ(gaps, 0u);
    EXPECT_EQ(n, last - first + 1);
    EXPECT_LE(other, 1u);
    EXPECT_EQ(ring->dropped(), 0u) << "a reader every 5 ms keeps the ring far from full";
  }
  engine.Stop();
}

}  // namespace
}  // namespace rheo::daemon
