// Per-token limits: what one token may hold at once and how fast it may call the expensive
// methods, so that one client (a runaway script, a page left open in a loop) cannot take the
// daemon from everyone else. Every refusal is RESOURCE_EXHAUSTED naming the limit and its flag.
//
//  - calls per second to each metered method (the role table marks them), a token bucket per
//    token and method, charged in the AuthProcessor before any handler runs;
//  - open streams (every server, client and bidirectional stream of rheo.v1), taken by the
//    stream's handler for its lifetime;
//  - concurrent mesh jobs (CreateObject), taken by the handler for the job's lifetime;
//  - idle streams: a stream whose client neither reads nor writes for the idle timeout (a write
//    that cannot complete, a ToolStream that sends nothing) is cancelled by CancelIdle.
// The request size per method is the role table's (MethodRule::max_request_bytes), checked by
// CheckRequest (limits.h). Thread-safe; never touched by the loop.
#pragma once

#include <grpcpp/support/status.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>

namespace grpc {
class ServerContextBase;
}

namespace rheo::daemon {

struct QuotaLimits {
  double calls_per_s = 10.0;  // calls per token to each metered method, sustained (0: unlimited)
  double burst = 20.0;        // ... and in a burst
  int streams = 64;           // open streams per token (0: unlimited)
  int jobs = 2;               // mesh jobs per token at once (0: unlimited)
  std::chrono::milliseconds stream_idle{60'000};  // 0: streams never time out
};

struct QuotaStats {
  uint64_t refused_rate = 0;
  uint64_t refused_streams = 0;
  uint64_t refused_jobs = 0;
  uint64_t idle_cancelled = 0;
  int open_streams = 0;
  int running_jobs = 0;
};

class Quotas {
 public:
  using Clock = std::chrono::steady_clock;
  explicit Quotas(QuotaLimits limits) : limits_(limits) {}
  Quotas(const Quotas&) = delete;
  Quotas& operator=(const Quotas&) = delete;

  const QuotaLimits& limits() const { return limits_; }

  /// One metered call by `token` to `method` ("CreateObject"): OK, or RESOURCE_EXHAUSTED.
  grpc::Status Charge(const std::string& token, std::string_view method,
                      Clock::time_point now = Clock::now());

  /// A stream held open by a handler; released when destroyed. Touch() on every message read or
  /// written (and while the server itself waits), so only a client that stalls goes idle.
  class Stream {
   public:
    Stream() = default;
    Stream(Stream&& o) noexcept : owner_(o.owner_), id_(o.id_) { o.owner_ = nullptr; }
    Stream& operator=(Stream&&) = delete;
    ~Stream();
    void Touch();

   private:
    friend class Quotas;
    Quotas* owner_ = nullptr;
    uint64_t id_ = 0;
  };
  /// RESOURCE_EXHAUSTED when `token` holds as many streams as it may.
  grpc::Status OpenStream(grpc::ServerContextBase* context, const std::string& token,
                          std::string_view method, Stream* out);

  /// A mesh job counted against its token; released when destroyed.
  class Job {
   public:
    Job() = default;
    Job(Job&& o) noexcept : owner_(o.owner_), token_(std::move(o.token_)) { o.owner_ = nullptr; }
    Job& operator=(Job&&) = delete;
    ~Job();

   private:
    friend class Quotas;
    Quotas* owner_ = nullptr;
    std::string token_;
  };
  grpc::Status StartJob(const std::string& token, Job* out);

  /// Cancels every stream idle for longer than the limit (the handler's next read or write
  /// fails and it returns); returns how many. Called about once a second.
  int CancelIdle(Clock::time_point now = Clock::now());

  QuotaStats stats() const;

 private:
  struct Bucket {
    double tokens = 0.0;
    Clock::time_point at{};
  };
  struct OpenedStream {
    grpc::ServerContextBase* context;
    std::string token;
    std::string method;
    Clock::time_point last;
    bool cancelled = false;
  };
  void Close(uint64_t id);
  void EndJob(const std::string& token);

  const QuotaLimits limits_;
  mutable std::mutex mutex_;
  std::map<std::string, Bucket> buckets_;  // by token and method
  std::map<uint64_t, OpenedStream> streams_;
  std::map<std::string, int> streams_by_token_;
  std::map<std::string, int> jobs_by_token_;
  uint64_t next_stream_ = 1;
  QuotaStats stats_;
};

}  // namespace rheo::daemon
