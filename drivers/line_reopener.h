// Reopens a serial line that went away (a USB serial adapter pulled out and plugged in again), on
// a thread of its own with a growing backoff, and hands the new line to the link lock-free.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "common/status.h"
#include "drivers/transport.h"

namespace rheo::drivers {

struct ReopenOptions {
  int64_t first_backoff_ns = 100'000'000;  // wait after the loss before the first attempt [ns]
  int64_t max_backoff_ns = 2'000'000'000;  // the wait doubles after each failure, up to this [ns]
  /// Called on the reopener's thread with a line for the log: the loss, each failed attempt and
  /// the reopen (null: nothing is said).
  std::function<void(const std::string&)> log;
};

/// A LineSource. The link's thread (the 1 kHz loop) only swaps pointers and sets flags; open(),
/// tcsetattr and identifying the boards (`reopen`) run on this object's thread, which also
/// destroys the lost line. After a loss it waits first_backoff_ns, tries `reopen`, and doubles the
/// wait after each failure up to max_backoff_ns; a line that reopens resets the wait. At most one
/// line is with the link at a time: the lost one is destroyed before a new one is offered.
class LineReopener final : public LineSource {
 public:
  /// Opens the port again and checks the boards on it; the same boards as before, or an error
  /// that says what answered.
  using ReopenFn = std::function<Result<std::unique_ptr<ByteTransport>>()>;

  explicit LineReopener(ReopenFn reopen, const ReopenOptions& options = {});
  /// Stops the thread (an attempt under way finishes first) and destroys any line it holds.
  ~LineReopener() override;
  LineReopener(const LineReopener&) = delete;
  LineReopener& operator=(const LineReopener&) = delete;

  // LineSource (the link's thread; lock-free, no allocation).
  void Lost(std::unique_ptr<ByteTransport> line) override;
  std::unique_ptr<ByteTransport> Take() override;
  LineStats stats() const override;

  /// Why the last attempt failed ("" before any failure), for logs. Any thread but the link's.
  std::string last_error() const;

 private:
  void Run();
  // Sleeps up to `ns` on the reopener's own condition variable; false when stopping.
  bool Sleep(int64_t ns);
  void Say(const std::string& line) const;

  const ReopenFn reopen_;
  const ReopenOptions options_;

  // Between the link's thread and this one.
  std::atomic<bool> lost_{false};                 // a line was lost and none is offered yet
  std::atomic<ByteTransport*> retired_{nullptr};  // the lost line, for this thread to destroy
  std::atomic<ByteTransport*> ready_{nullptr};    // a reopened line for the link to take
  std::atomic<uint64_t> losses_{0};
  std::atomic<uint64_t> attempts_{0};
  std::atomic<uint64_t> reopens_{0};
  std::atomic<int64_t> backoff_ns_{0};
  std::atomic<int64_t> down_since_ns_{0};
  std::atomic<int64_t> last_attempt_ns_{0};

  // This thread and the destructor only: the link's thread never touches them.
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::string last_error_;
  std::thread thread_;
};

}  // namespace rheo::drivers
