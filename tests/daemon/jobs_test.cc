// The mesh-job pool alone: bounded admission, cancellation, deadlines, and that every job ends
// with a word to its watcher, also when it never got to run.
#include "daemon/jobs/jobs.h"

#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <future>

namespace rheo::daemon {
namespace {

using namespace std::chrono_literals;

struct Ev {
  int value = 0;
  std::optional<Error> error;
};

JobPool<Ev> MakePool(int workers, int max_in_flight) {
  return JobPool<Ev>(workers, max_in_flight, [](Error e) { return Ev{-1, std::move(e)}; });
}

// Drains a job: every event until done.
std::vector<Ev> Drain(Job<Ev>& job) {
  std::vector<Ev> out;
  bool done = false;
  Ev ev;
  while (!done)
    if (job.Pop(ev, 20ms, done)) out.push_back(ev);
  return out;
}

// Work that holds a worker until the test opens the gate.
struct Gate {
  std::promise<void> release;
  std::shared_future<void> open = release.get_future().share();
  std::function<void(Job<Ev>&)> Work() const {
    return [f = open](Job<Ev>&) { f.wait(); };
  }
};

std::chrono::steady_clock::time_point In(std::chrono::milliseconds d) {
  return std::chrono::steady_clock::now() + d;
}

void Push42(Job<Ev>& j) {
  j.Push(Ev{42, std::nullopt});
}

TEST(JobPool, WorkRunsAndItsEventsArriveInOrder) {
  auto pool = MakePool(2, 4);
  auto job = pool.Submit(In(10s), [](Job<Ev>& j) {
    for (int i = 1; i <= 3; ++i) j.Push(Ev{i, std::nullopt});
  });
  ASSERT_TRUE(job.ok());
  auto events = Drain(**job);
  ASSERT_EQ(events.size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(events[i].value, i + 1);
}

// A job that never gets a worker (it expired or was cancelled while queued) still ends with
// one event saying why and naming the job.
TEST(JobPool, AJobStoppedWhileQueuedSaysWhy) {
  for (ErrorCode why : {ErrorCode::kDeadlineExceeded, ErrorCode::kCancelled}) {
    auto pool = MakePool(1, 4);
    Gate gate;
    auto blocker = pool.Submit(In(10s), gate.Work());
    auto queued = pool.Submit(In(why == ErrorCode::kDeadlineExceeded ? 1ms : 10s), Push42);
    ASSERT_TRUE(blocker.ok() && queued.ok());
    if (why == ErrorCode::kCancelled) {
      EXPECT_TRUE(pool.Cancel((*queued)->id()));
      EXPECT_FALSE(pool.Cancel("job-does-not-exist"));
    } else {
      std::this_thread::sleep_for(5ms);
    }
    gate.release.set_value();
    auto events = Drain(**queued);
    ASSERT_EQ(events.size(), 1u);
    ASSERT_TRUE(events[0].error.has_value());
    EXPECT_EQ(events[0].error->code, why);
    EXPECT_NE(events[0].error->message.find((*queued)->id()), std::string::npos);
    Drain(**blocker);
  }
}

TEST(JobPool, AdmissionIsBoundedAndNamesTheLimit) {
  auto pool = MakePool(1, 2);
  Gate gate;
  auto a = pool.Submit(In(10s), gate.Work());
  auto b = pool.Submit(In(10s), gate.Work());
  auto c = pool.Submit(In(10s), Push42);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_FALSE(c.ok());
  EXPECT_EQ(c.error().code, ErrorCode::kResourceExhausted);
  EXPECT_NE(c.error().message.find("--max-jobs"), std::string::npos);
  gate.release.set_value();
  Drain(**a);
  Drain(**b);
  // Slots come back once jobs end.
  for (int i = 0; i < 100 && pool.in_flight() > 0; ++i) std::this_thread::sleep_for(1ms);
  EXPECT_TRUE(pool.Submit(In(10s), Push42).ok());
}

TEST(JobPool, ShutdownWithADeadlineJoinsJobsThatStop) {
  auto pool = MakePool(2, 4);
  auto job = pool.Submit(In(10s), [](Job<Ev>& j) {
    while (!j.ShouldStop()) std::this_thread::sleep_for(1ms);
  });
  ASSERT_TRUE(job.ok());
  while (pool.in_flight() == 0) std::this_thread::sleep_for(1ms);
  EXPECT_TRUE(pool.Shutdown(std::chrono::steady_clock::now() + 2s));
  EXPECT_EQ(pool.in_flight(), 0);
}

TEST(JobPool, ShutdownWithADeadlineDoesNotWaitForWorkThatIgnoresTheCancel) {
  auto pool = MakePool(1, 4);
  std::atomic<bool> release{false};
  std::atomic<bool> started{false};
  auto stuck = pool.Submit(In(10s), [&](Job<Ev>&) {
    started = true;
    while (!release) std::this_thread::sleep_for(1ms);  // never looks at ShouldStop
  });
  ASSERT_TRUE(stuck.ok());
  while (!started) std::this_thread::sleep_for(1ms);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(pool.Shutdown(t0 + 100ms));
  const auto took = std::chrono::steady_clock::now() - t0;
  EXPECT_LT(took, 1s) << std::chrono::duration<double>(took).count() << " s";
  EXPECT_TRUE((*stuck)->cancelled());
  release = true;  // lets the pool's destructor join
}

}  // namespace
}  // namespace rheo::daemon
