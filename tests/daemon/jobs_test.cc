// The mesh-job pool alone: bounded admission, cancellation, deadlines, and that every job ends
// with a word to its watcher, also when it never got to run.
#include "daemon/jobs.h"

#include <gtest/gtest.h>

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

TEST(JobPool, WorkRunsAndItsEventsArriveInOrder) {
  auto pool = MakePool(2, 4);
  auto job = pool.Submit(std::chrono::steady_clock::now() + 10s, [](Job<Ev>& j) {
    for (int i = 1; i <= 3; ++i) j.Push(Ev{i, std::nullopt});
  });
  ASSERT_TRUE(job.ok());
  auto events = Drain(**job);
  ASSERT_EQ(events.size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(events[i].value, i + 1);
}

TEST(JobPool, AJobThatExpiresWhileQueuedReportsItsDeadline) {
  auto pool = MakePool(1, 4);
  std::promise<void> release;
  auto gate = release.get_future().share();
  auto blocker =
      pool.Submit(std::chrono::steady_clock::now() + 10s, [gate](Job<Ev>&) { gate.wait(); });
  ASSERT_TRUE(blocker.ok());
  auto late = pool.Submit(std::chrono::steady_clock::now() + 1ms, [](Job<Ev>& j) {
    j.Push(Ev{42, std::nullopt});
  });
  ASSERT_TRUE(late.ok());
  std::this_thread::sleep_for(5ms);
  release.set_value();
  auto events = Drain(**late);
  ASSERT_EQ(events.size(), 1u);
  ASSERT_TRUE(events[0].error.has_value());
  EXPECT_EQ(events[0].error->code, ErrorCode::kDeadlineExceeded);
  EXPECT_NE(events[0].error->message.find((*late)->id()), std::string::npos);
  Drain(**blocker);
}

TEST(JobPool, CancelWhileQueuedReportsCancelledAndUnknownIdsAreRefused) {
  auto pool = MakePool(1, 4);
  std::promise<void> release;
  auto gate = release.get_future().share();
  auto blocker =
      pool.Submit(std::chrono::steady_clock::now() + 10s, [gate](Job<Ev>&) { gate.wait(); });
  auto queued = pool.Submit(std::chrono::steady_clock::now() + 10s, [](Job<Ev>& j) {
    j.Push(Ev{42, std::nullopt});
  });
  ASSERT_TRUE(blocker.ok() && queued.ok());
  EXPECT_TRUE(pool.Cancel((*queued)->id()));
  EXPECT_FALSE(pool.Cancel("job-does-not-exist"));
  release.set_value();
  auto events = Drain(**queued);
  ASSERT_EQ(events.size(), 1u);
  ASSERT_TRUE(events[0].error.has_value());
  EXPECT_EQ(events[0].error->code, ErrorCode::kCancelled);
  Drain(**blocker);
}

TEST(JobPool, AdmissionIsBoundedAndNamesTheLimit) {
  auto pool = MakePool(1, 2);
  std::promise<void> release;
  auto gate = release.get_future().share();
  auto a = pool.Submit(std::chrono::steady_clock::now() + 10s, [gate](Job<Ev>&) { gate.wait(); });
  auto b = pool.Submit(std::chrono::steady_clock::now() + 10s, [gate](Job<Ev>&) { gate.wait(); });
  auto c = pool.Submit(std::chrono::steady_clock::now() + 10s, [](Job<Ev>&) {});
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_FALSE(c.ok());
  EXPECT_EQ(c.error().code, ErrorCode::kResourceExhausted);
  EXPECT_NE(c.error().message.find("--max-jobs"), std::string::npos);
  release.set_value();
  Drain(**a);
  Drain(**b);
  // Slots come back once jobs end.
  for (int i = 0; i < 100 && pool.in_flight() > 0; ++i) std::this_thread::sleep_for(1ms);
  EXPECT_TRUE(pool.Submit(std::chrono::steady_clock::now() + 10s, [](Job<Ev>&) {}).ok());
}

}  // namespace
}  // namespace rheo::daemon
