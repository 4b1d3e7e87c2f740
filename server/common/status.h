// Result-or-error type shared by the pure libraries. The daemon maps ErrorCode to a gRPC status.
#pragma once

#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace rheo {

/// Error categories; each maps one-to-one onto a gRPC status code in the daemon.
enum class ErrorCode {
  kInvalidArgument,    // the input is wrong; the message says what and where
  kResourceExhausted,  // the input or result is over a limit; the message names the limit
  kNotFound,
  kAlreadyExists,
  kFailedPrecondition,  // the state does not allow this now (e.g. no object in the scene)
  kCancelled,
  kDeadlineExceeded,
  kUnimplemented,
  kUnavailable,
  kPermissionDenied,
  kUnauthenticated,  // no valid credential
  kDataLoss,         // stored or transmitted data is corrupt
  kInternal,         // a bug or broken invariant
};

const char* ErrorCodeName(ErrorCode code);

struct Error {
  ErrorCode code = ErrorCode::kInternal;
  std::string message;
};

inline Error InvalidArgument(std::string m) {
  return {ErrorCode::kInvalidArgument, std::move(m)};
}
inline Error ResourceExhausted(std::string m) {
  return {ErrorCode::kResourceExhausted, std::move(m)};
}
inline Error NotFound(std::string m) {
  return {ErrorCode::kNotFound, std::move(m)};
}
inline Error FailedPrecondition(std::string m) {
  return {ErrorCode::kFailedPrecondition, std::move(m)};
}
inline Error Cancelled(std::string m) {
  return {ErrorCode::kCancelled, std::move(m)};
}
inline Error DataLoss(std::string m) {
  return {ErrorCode::kDataLoss, std::move(m)};
}
inline Error Internal(std::string m) {
  return {ErrorCode::kInternal, std::move(m)};
}

/// Holds either a value or an Error. Cheap to move; check ok() before value().
template <typename T>
class Result {
 public:
  Result(T value) : v_(std::move(value)) {}      // NOLINT: implicit by design
  Result(Error error) : v_(std::move(error)) {}  // NOLINT: implicit by design

  bool ok() const { return std::holds_alternative<T>(v_); }
  explicit operator bool() const { return ok(); }

  T& value() & {
    assert(ok());
    return std::get<T>(v_);
  }
  const T& value() const& {
    assert(ok());
    return std::get<T>(v_);
  }
  T&& value() && {
    assert(ok());
    return std::get<T>(std::move(v_));
  }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

  const Error& error() const {
    assert(!ok());
    return std::get<Error>(v_);
  }

 private:
  std::variant<T, Error> v_;
};

/// Result of an operation that produces no value.
class Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error)), ok_(false) {}  // NOLINT: implicit by design
  static Status Ok() { return {}; }
  bool ok() const { return ok_; }
  explicit operator bool() const { return ok_; }
  const Error& error() const { return error_; }

 private:
  Error error_;
  bool ok_ = true;
};

}  // namespace rheo
