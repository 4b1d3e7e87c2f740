// Worker pool for heavy, cancellable work (sketch -> solid), never on the loop thread.
#pragma once

#include <atomic>
#include <boost/asio/post.hpp>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "common/cancel.h"
#include "common/status.h"

namespace rheo::daemon {

/// One job's progress channel: the worker pushes events, one watcher pops them. Cancellation and
/// the deadline are checked by the worker through ShouldStop().
template <typename Event>
class Job {
 public:
  Job(std::string id, std::chrono::steady_clock::time_point deadline)
      : id_(std::move(id)), deadline_(deadline) {}

  const std::string& id() const { return id_; }
  void Cancel() { cancelled_.store(true, std::memory_order_release); }
  bool cancelled() const { return cancelled_.load(std::memory_order_acquire); }
  bool expired() const { return std::chrono::steady_clock::now() > deadline_; }
  /// Worker side: the token the pure libraries poll inside their loops (this job's cancel flag
  /// and deadline). Valid while the job lives.
  CancelToken token() const { return CancelToken(&cancelled_, &Job::Expired, this); }
  /// Worker side: stop as soon as convenient when this returns an error.
  std::optional<Error> ShouldStop() const {
    if (cancelled()) return Error{ErrorCode::kCancelled, "job " + id_ + " was cancelled"};
    if (expired())
      return Error{ErrorCode::kDeadlineExceeded, "job " + id_ + " ran past its deadline"};
    return std::nullopt;
  }

  void Push(Event e) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      events_.push_back(std::move(e));
    }
    cv_.notify_all();
  }
  void Finish() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
  }
  /// Watcher side: waits up to `wait` for the next event. Returns false with `done` set when the
  /// job finished and every event was taken.
  bool Pop(Event& out, std::chrono::milliseconds wait, bool& done) {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, wait, [&] { return !events_.empty() || done_; });
    done = events_.empty() && done_;
    if (events_.empty()) return false;
    out = std::move(events_.front());
    events_.pop_front();
    return true;
  }

 private:
  static bool Expired(const void* self) { return static_cast<const Job*>(self)->expired(); }

  std::string id_;
  std::chrono::steady_clock::time_point deadline_;
  std::atomic<bool> cancelled_{false};
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Event> events_;
  bool done_ = false;
};

/// A fixed number of workers and a bounded number of jobs in flight (queued + running): past the
/// bound Submit refuses with RESOURCE_EXHAUSTED naming it, so heavy requests degrade gracefully.
template <typename Event>
class JobPool {
 public:
  using JobPtr = std::shared_ptr<Job<Event>>;

  /// `stopped` turns the reason a job never ran (cancelled or expired while queued) into the
  /// event its watcher receives, so no watcher sees a job end without a word.
  JobPool(int workers, int max_in_flight, std::function<Event(Error)> stopped)
      : pool_(workers), max_in_flight_(max_in_flight), stop_event_(std::move(stopped)) {}
  ~JobPool() { Shutdown(); }

  Result<JobPtr> Submit(std::chrono::steady_clock::time_point deadline,
                        std::function<void(Job<Event>&)> work) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (static_cast<int>(jobs_.size()) >= max_in_flight_)
      return ResourceExhausted("the daemon already has " + std::to_string(max_in_flight_) +
                               " mesh jobs in flight (limit --max-jobs); retry when one ends");
    auto job = std::make_shared<Job<Event>>("job-" + std::to_string(++next_id_), deadline);
    jobs_[job->id()] = job;
    boost::asio::post(pool_, [this, job, work = std::move(work)] {
      // A job that was cancelled or expired while queued still tells its watcher why.
      if (auto stop = job->ShouldStop(); !stop)
        work(*job);
      else
        job->Push(stop_event_(*stop));
      job->Finish();
      {
        std::lock_guard<std::mutex> l(mutex_);
        jobs_.erase(job->id());
      }
      idle_.notify_all();
    });
    return job;
  }

  /// Returns false when no such job is in flight.
  bool Cancel(const std::string& id) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = jobs_.find(id);
    if (it == jobs_.end()) return false;
    it->second->Cancel();
    return true;
  }

  int in_flight() {
    std::lock_guard<std::mutex> lock(mutex_);
    return static_cast<int>(jobs_.size());
  }

  /// Asks every job in flight to stop; does not wait.
  void CancelAll() {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& [id, job] : jobs_) job->Cancel();
  }

  /// Cancels everything and joins the workers.
  void Shutdown() {
    CancelAll();
    pool_.join();
  }

  /// Cancels everything and waits until `deadline` for the jobs in flight to end. Returns true
  /// with the workers joined; false when some job still runs at the deadline (work that does not
  /// check ShouldStop often enough). Then the workers are not joined, and the pool must not be
  /// destroyed while that job runs: the caller leaves the process instead (std::_Exit), which
  /// is safe for the store because each object is one transaction.
  bool Shutdown(std::chrono::steady_clock::time_point deadline) {
    CancelAll();
    {
      std::unique_lock<std::mutex> lock(mutex_);
      if (!idle_.wait_until(lock, deadline, [&] { return jobs_.empty(); })) return false;
    }
    pool_.join();
    return true;
  }

 private:
  boost::asio::thread_pool pool_;
  int max_in_flight_;
  std::function<Event(Error)> stop_event_;
  std::mutex mutex_;
  std::condition_variable idle_;  // a job left jobs_
  std::map<std::string, JobPtr> jobs_;
  uint64_t next_id_ = 0;
};

}  // namespace rheo::daemon
