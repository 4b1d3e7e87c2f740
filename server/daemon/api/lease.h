// The device's control lease: one holder at a time, expiring unless renewed. It belongs to the
// token that acquired it: only that token renews, releases or uses it (an admin may revoke it).
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
#include <random>
#include <string>

#include "common/format.h"
#include "common/status.h"
#include "daemon/api/limits.h"

namespace rheo::daemon {

/// Thread-safe; never touched by the loop.
class LeaseManager {
 public:
  using Clock = std::chrono::steady_clock;
  struct Lease {
    std::string id;
    std::string holder;  // shown to others: "client_name (token NAME)"
    std::string owner;   // the token's name
    Clock::time_point expires;
  };

  /// Grants the lease when free or expired; otherwise FAILED_PRECONDITION naming the holder and
  /// when it expires.
  Result<Lease> Acquire(const std::string& client_name, const std::string& owner,
                        double duration_s) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto now = Clock::now();
    if (Held(now))
      return FailedPrecondition("the device is leased to " + QuoteForMessage(lease_.holder) +
                                " for another " + Seconds(lease_.expires - now) +
                                " s; wait for it to expire or ask them to release it");
    lease_.id = NewId();
    lease_.owner = owner;
    lease_.holder = client_name.empty() || client_name == owner
                        ? "token " + owner
                        : client_name + " (token " + owner + ")";
    lease_.expires = now + Duration(duration_s);
    return lease_;
  }

  Result<Lease> Renew(const std::string& id, const std::string& owner, double duration_s) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (Status s = CheckLocked(id, owner); !s.ok()) return s.error();
    lease_.expires = Clock::now() + Duration(duration_s);
    return lease_;
  }

  Status Release(const std::string& id, const std::string& owner) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (Status s = CheckLocked(id, owner); !s.ok()) return s;
    lease_ = Lease();
    return Status::Ok();
  }

  /// Ends the live lease whoever holds it (an admin's call); the holder's name, or "" if none.
  std::string Revoke() {
    std::lock_guard<std::mutex> lock(mutex_);
    const bool held = Held(Clock::now());
    std::string holder = held ? lease_.holder : std::string();
    lease_ = Lease();
    return holder;
  }

  /// OK when `id` is the live lease and `owner` the token that holds it; else
  /// FAILED_PRECONDITION saying what to do (PERMISSION_DENIED for another token's lease id).
  Status Check(const std::string& id, const std::string& owner) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return CheckLocked(id, owner);
  }

  /// Holder's name and seconds left, or "" and 0 when free.
  std::pair<std::string, double> Holder() const {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto now = Clock::now();
    if (!Held(now)) return {"", 0.0};
    return {lease_.holder, std::chrono::duration<double>(lease_.expires - now).count()};
  }

  static double SecondsLeft(const Lease& l) {
    return std::chrono::duration<double>(l.expires - Clock::now()).count();
  }
  static constexpr double kDefaultSeconds = 10.0;
  static constexpr double kMaxSeconds = 3600.0;

 private:
  bool Held(Clock::time_point now) const { return !lease_.id.empty() && now < lease_.expires; }
  Status CheckLocked(const std::string& id, const std::string& owner) const {
    const auto now = Clock::now();
    if (id.empty())
      return FailedPrecondition(
          "this call needs the device's control lease: call AcquireLease (rheoctl device lease "
          "acquire) and pass its lease_id");
    if (!Held(now) || id != lease_.id) {
      if (Held(now))
        return FailedPrecondition("lease " + QuoteForMessage(id) +
                                  " is not the live lease; the device is leased to " +
                                  QuoteForMessage(lease_.holder) + " for another " +
                                  Seconds(lease_.expires - now) + " s");
      return FailedPrecondition("lease " + QuoteForMessage(id) +
                                " has expired or was released; acquire a new one (AcquireLease)");
    }
    if (owner != lease_.owner)
      return Error{ErrorCode::kPermissionDenied,
                   "the live lease belongs to token " + QuoteForMessage(lease_.owner) +
                       "; a lease is used only by the token that acquired it"};
    return Status::Ok();
  }
  static Clock::duration Duration(double s) {
    if (!(s > 0.0)) s = kDefaultSeconds;
    s = std::min(s, kMaxSeconds);
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
  }
  static std::string Seconds(Clock::duration d) {
    return Fixed(std::chrono::duration<double>(d).count(), 1);
  }
  std::string NewId() {
    std::uniform_int_distribution<uint64_t> u;
    char b[40];
    std::snprintf(b, sizeof b, "%016llx%016llx", (unsigned long long)u(rng_),
                  (unsigned long long)u(rng_));
    return b;
  }

  mutable std::mutex mutex_;
  Lease lease_;
  std::mt19937_64 rng_{std::random_device{}()};
};

}  // namespace rheo::daemon
