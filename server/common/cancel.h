// Cooperative cancellation for the pure libraries: a flag and an optional deadline, both owned by
// the caller. The library reads the flag and asks the caller's function whether the deadline has
// passed; it keeps no clock of its own.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>

#include "common/status.h"

namespace rheo {

class CancelToken {
 public:
  /// Returns true once the caller's deadline has passed; `context` is the caller's.
  using ExpiredFn = bool (*)(const void* context);

  /// A token that never stops anything.
  CancelToken() = default;
  explicit CancelToken(const std::atomic<bool>* cancelled, ExpiredFn expired = nullptr,
                       const void* context = nullptr)
      : cancelled_(cancelled), expired_(expired), context_(context) {}

  bool cancelled() const { return cancelled_ && cancelled_->load(std::memory_order_relaxed); }
  bool expired() const { return expired_ && expired_(context_); }
  bool stop_requested() const { return cancelled() || expired(); }

  /// Ok, or kCancelled / kDeadlineExceeded naming `where` the work stopped.
  Status Check(std::string_view where) const {
    if (cancelled()) return Cancelled("cancelled during " + std::string(where));
    if (expired())
      return Error{ErrorCode::kDeadlineExceeded,
                   "ran past its deadline during " + std::string(where)};
    return Status::Ok();
  }

 private:
  const std::atomic<bool>* cancelled_ = nullptr;
  ExpiredFn expired_ = nullptr;
  const void* context_ = nullptr;
};

/// Polls a token every `every` calls of Stop(), so a tight loop pays one increment per pass.
class CancelPoll {
 public:
  CancelPoll(const CancelToken& token, std::string_view where, int every = 256)
      : token_(token), where_(where), every_(every) {}
  /// True when the work must stop; error() then says why.
  bool Stop() {
    if (++count_ < every_) return false;
    count_ = 0;
    status_ = token_.Check(where_);
    return !status_.ok();
  }
  /// Checks now, whatever the count.
  bool StopNow() {
    count_ = 0;
    status_ = token_.Check(where_);
    return !status_.ok();
  }
  const Error& error() const { return status_.error(); }

 private:
  const CancelToken& token_;
  std::string_view where_;
  int every_;
  int count_ = 0;
  Status status_;
};

}  // namespace rheo
