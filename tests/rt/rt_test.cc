// The real-time primitives under concurrency (this binary also runs under TSan).
#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include "rt/command_queue.h"
#include "rt/histogram.h"
#include "rt/loop.h"
#include "rt/triple_buffer.h"

namespace rheo::rt {
namespace {

struct Payload {
  uint64_t seq = 0;
  uint64_t copies[8] = {};  // every copy equals seq: a torn read would show
};

TEST(TripleBuffer, ReaderSeesOnlyWholeValuesInOrder) {
  TripleBuffer<Payload> tb;
  constexpr uint64_t kN = 200000;
  std::thread writer([&] {
    for (uint64_t i = 1; i <= kN; ++i) {
      Payload& p = tb.back();
      p.seq = i;
      for (auto& c : p.copies) c = i;
      tb.Publish();
    }
  });
  uint64_t last = 0;
  uint64_t seen = 0;
  while (last < kN) {
    if (!tb.Acquire()) continue;
    const Payload& p = tb.front();
    for (auto c : p.copies) ASSERT_EQ(c, p.seq);
    ASSERT_GT(p.seq, last) << "values must arrive newest-first, never repeat";
    last = p.seq;
    ++seen;
  }
  writer.join();
  EXPECT_EQ(last, kN);
  EXPECT_GT(seen, 0u);
  EXPECT_FALSE(tb.Acquire()) << "nothing new after the last value was taken";
}

TEST(CommandQueue, ManyProducersOneConsumerLoseNothingAndRefuseWhenFull) {
  CommandQueue<uint64_t, 64> q;
  constexpr int kProducers = 4;
  constexpr uint64_t kEach = 20000;
  std::atomic<uint64_t> refused{0};
  std::vector<std::thread> producers;
  for (int p = 0; p < kProducers; ++p) {
    producers.emplace_back([&, p] {
      for (uint64_t i = 0; i < kEach; ++i) {
        uint64_t v = (static_cast<uint64_t>(p) << 32) | i;
        while (!q.Push(v)) refused.fetch_add(1, std::memory_order_relaxed);
      }
    });
  }
  std::vector<uint64_t> next(kProducers, 0);
  uint64_t got = 0;
  while (got < kProducers * kEach) {
    uint64_t v;
    if (!q.Pop(v)) continue;
    int p = static_cast<int>(v >> 32);
    ASSERT_EQ(v & 0xffffffffu, next[p]) << "per-producer order must hold";
    ++next[p];
    ++got;
  }
  for (auto& t : producers) t.join();
  uint64_t v;
  EXPECT_FALSE(q.Pop(v));
  // A full queue refuses rather than blocking.
  for (int i = 0; i < 64; ++i) q.Push(1);
  EXPECT_FALSE(q.Push(2));
}

TEST(Histogram, QuantilesOfAKnownDistribution) {
  Histogram h;
  for (int us = 1; us <= 1000; ++us) h.Add(static_cast<int64_t>(us) * 1000 + 100);
  EXPECT_EQ(h.count(), 1000u);
  EXPECT_NEAR(h.Quantile(0.5) / 1e3, 500.5, 1.0);
  EXPECT_NEAR(h.Quantile(0.99) / 1e3, 990.5, 1.0);
  EXPECT_EQ(h.Quantile(1.0), 1000100);
  EXPECT_EQ(h.max_ns(), 1000100);
  h.Add(50'000'000);  // beyond the bins: overflow, exact max kept
  EXPECT_EQ(h.Quantile(1.0), 50'000'000);
  h.Reset();
  EXPECT_EQ(h.count(), 0u);
  EXPECT_EQ(h.Quantile(0.5), 0);
}

TEST(Loop, TicksAtItsRateAndCountsOverruns) {
  std::atomic<uint64_t> calls{0};
  std::atomic<bool> stall{false};
  LoopOptions o;
  o.period_ns = 1'000'000;
  o.realtime_priority = false;
  o.lock_memory = false;
  Loop loop(o, [&](const TickInfo& info) {
    EXPECT_DOUBLE_EQ(info.dt, 1e-3);
    calls.fetch_add(1);
    if (stall.exchange(false)) {
      // Simulate a 5 ms stall inside one tick.
      int64_t end = Loop::NowNs() + 5'000'000;
      while (Loop::NowNs() < end) {
      }
    }
  });
  loop.Start();
  while (calls.load() < 50) std::this_thread::yield();
  stall.store(true);
  while (calls.load() < 100) std::this_thread::yield();
  loop.Stop();
  const LoopStats& s = loop.stats();
  EXPECT_EQ(s.ticks.load(), calls.load());
  EXPECT_GE(s.overruns.load(), 1u);
  EXPECT_GE(s.skipped_ticks.load(), 3u) << "a 5 ms stall drops about 4 periods";
  EXPECT_EQ(s.period.count(), s.ticks.load() - 1);
  // The median period is the nominal one (the clock is absolute, not drifting).
  EXPECT_NEAR(s.period.Quantile(0.5) / 1e6, 1.0, 0.5);
  EXPECT_FALSE(loop.running());
}

TEST(Loop, StopIsIdempotentAndRestartWorks) {
  std::atomic<int> n{0};
  LoopOptions o;
  o.realtime_priority = false;
  o.lock_memory = false;
  Loop loop(o, [&](const TickInfo&) { n.fetch_add(1); });
  loop.Start();
  while (n.load() < 3) std::this_thread::yield();
  loop.Stop();
  loop.Stop();
  int after = n.load();
  loop.Start();
  while (n.load() < after + 3) std::this_thread::yield();
  loop.Stop();
  EXPECT_GE(n.load(), after + 3);
}

}  // namespace
}  // namespace rheo::rt
