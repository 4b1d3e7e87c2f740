#include "drivers/line_reopener.h"

#include <algorithm>
#include <chrono>

#include "common/clock.h"
#include "common/format.h"

namespace rheo::drivers {
namespace {

// How often the thread looks for a loss while the line is up [ns]: a few milliseconds on top of
// the first backoff, and a negligible wake-up rate.
constexpr int64_t kWatchPeriodNs = 5'000'000;

}  // namespace

LineReopener::LineReopener(ReopenFn reopen, const ReopenOptions& options)
    : reopen_(std::move(reopen)), options_(options) {
  thread_ = std::thread([this] { Run(); });
}

LineReopener::~LineReopener() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  delete retired_.exchange(nullptr);
  delete ready_.exchange(nullptr);
}

void LineReopener::Lost(std::unique_ptr<ByteTransport> line) {
  down_since_ns_.store(MonotonicNowNs(), std::memory_order_relaxed);
  losses_.fetch_add(1, std::memory_order_relaxed);
  // The slot is empty: the thread destroys a lost line before it offers the next one, and the
  // link loses only a line it took.
  ByteTransport* before = retired_.exchange(line.release(), std::memory_order_acq_rel);
  delete before;  // never reached (see above); a leak would be worse than a late free
  lost_.store(true, std::memory_order_release);
}

std::unique_ptr<ByteTransport> LineReopener::Take() {
  if (ready_.load(std::memory_order_relaxed) == nullptr) return nullptr;
  std::unique_ptr<ByteTransport> line(ready_.exchange(nullptr, std::memory_order_acq_rel));
  if (line) down_since_ns_.store(0, std::memory_order_relaxed);
  return line;
}

LineStats LineReopener::stats() const {
  LineStats s;
  s.losses = losses_.load(std::memory_order_relaxed);
  s.attempts = attempts_.load(std::memory_order_acquire);
  s.last_attempt_ns = last_attempt_ns_.load(std::memory_order_relaxed);
  s.reopens = reopens_.load(std::memory_order_relaxed);
  s.backoff_ns = backoff_ns_.load(std::memory_order_relaxed);
  s.down_since_ns = down_since_ns_.load(std::memory_order_relaxed);
  return s;
}

std::string LineReopener::last_error() const {
  std::lock_guard lock(mutex_);
  return last_error_;
}

void LineReopener::Say(const std::string& line) const {
  if (options_.log) options_.log(line);
}

bool LineReopener::Sleep(int64_t ns) {
  std::unique_lock lock(mutex_);
  wake_.wait_for(lock, std::chrono::nanoseconds(ns), [this] { return stop_; });
  return !stop_;
}

void LineReopener::Run() {
  for (;;) {
    if (!lost_.load(std::memory_order_acquire)) {
      if (!Sleep(kWatchPeriodNs)) return;
      continue;
    }
    // The lost line is closed here, not on the link's thread (close() on a hung-up tty may
    // wait for the driver).
    delete retired_.exchange(nullptr, std::memory_order_acq_rel);
    int64_t backoff = options_.first_backoff_ns;
    const int64_t lost_at = down_since_ns_.load(std::memory_order_relaxed);
    Say(Format("the serial line went away; reopening in %.1f s", backoff * 1e-9));
    for (int attempt = 1;; ++attempt) {
      backoff_ns_.store(backoff, std::memory_order_relaxed);
      if (!Sleep(backoff)) return;
      // The time first: a reader that sees the new count sees its time.
      last_attempt_ns_.store(MonotonicNowNs(), std::memory_order_relaxed);
      attempts_.fetch_add(1, std::memory_order_release);
      auto line = reopen_();
      if (line.ok()) {
        Say(Format("the serial line is back: reopened at attempt %d, %.2f s after it went away",
                   attempt, (MonotonicNowNs() - lost_at) * 1e-9));
        backoff_ns_.store(0, std::memory_order_relaxed);
        reopens_.fetch_add(1, std::memory_order_relaxed);
        // lost_ first: a loss of the new line, once the link has taken it, sets it again.
        lost_.store(false, std::memory_order_release);
        ready_.store(line.value().release(), std::memory_order_release);
        break;
      }
      {
        std::lock_guard lock(mutex_);
        last_error_ = line.error().message;
      }
      backoff = std::min(2 * backoff, options_.max_backoff_ns);
      Say(Format("reopening the serial line failed (attempt %d): %s; next in %.1f s", attempt,
                 line.error().message.c_str(), backoff * 1e-9));
    }
  }
}

}  // namespace rheo::drivers
