// Who may call what: roles, access tokens, the one table of each method's least role, and the
// check of every call against it (gRPC and the studio's gateway alike: the gateway is a gRPC
// client of the same server ports).
//
// The check runs in gRPC's AuthMetadataProcessor, before any handler: a call without a valid
// token or with too little role never reaches a service. Handlers read who called (CallerOf) for
// what depends on identity: the device lease, cancelling one's own job.
#pragma once

#include <grpcpp/security/auth_metadata_processor.h>
#include <grpcpp/support/interceptor.h>
#include <grpcpp/support/server_interceptor.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "daemon/api/quota.h"
#include "daemon/store/store.h"

namespace grpc {
class ServerContextBase;
}

namespace rheo::daemon {

/// rheo.v1.Role's values; each role may do everything the ones below it may.
enum class Role : int { kNone = 0, kViewer = 1, kOperator = 2, kAdmin = 3 };
const char* RoleName(Role role);  // "viewer", "operator", "admin" ("none")
/// "viewer", "operator" or "admin" (as rheoctl takes them); nullopt otherwise.
std::optional<Role> ParseRole(std::string_view name);

/// One method's entry in the table.
struct MethodRule {
  std::string_view path;  // "/rheo.v1.ObjectService/DeleteObject"
  Role least;             // kNone: open to anyone (health, reflection)
  bool audited;           // it changes state: every call is recorded in the audit
  bool metered = false;   // expensive: counts against the token's calls per second (quota.h)
  size_t max_request_bytes = 64 * 1024;  // each request message, serialized (CheckRequest)
};
/// The largest request any method takes: a sketch and its photo (32 MB each).
inline constexpr size_t kMaxSketchRequestBytes = 64u << 20;
/// Every method of every service rheod serves, with its least role. A method missing from it
/// is refused to everyone (PERMISSION_DENIED), and a test walks the service descriptors so a new
/// method without an entry fails.
const std::vector<MethodRule>& MethodTable();
const MethodRule* FindMethod(std::string_view path);

/// Who made the call: its token, from its own authorization header (empty name and kNone when it
/// has none that is valid, which the processor lets through only to the open methods).
struct Caller {
  std::string token_name;
  Role role = Role::kNone;
  bool at_least(Role r) const { return static_cast<int>(role) >= static_cast<int>(r); }
};
Caller CallerOf(const grpc::ServerContextBase* context);
class TokenRegistry;
/// The tokens CallerOf checks against (set once at start, before the server starts).
void SetCallerTokens(const TokenRegistry* tokens);

/// The tokens: kept as SHA-256 hashes in the store and in memory for the per-call check.
/// Thread-safe; never touched by the loop.
class TokenRegistry {
 public:
  using Clock = std::chrono::system_clock;
  explicit TokenRegistry(Store* store, std::function<Clock::time_point()> now = Clock::now);

  /// Reads the stored tokens.
  Status Load();
  bool empty() const;

  struct Created {
    StoredToken info;
    std::string token;  // "rheo_" + 64 hex digits (256 random bits); shown once
  };
  /// INVALID_ARGUMENT for a bad name, role or expiry; ALREADY_EXISTS for a name in use.
  Result<Created> Create(const std::string& name, Role role, double expires_in_s);
  Result<StoredToken> Revoke(const std::string& name);
  std::vector<StoredToken> List() const;

  /// The token's entry, or UNAUTHENTICATED saying why (unknown, expired, revoked).
  Result<StoredToken> Authenticate(std::string_view token) const;

  static std::string Hash(std::string_view token);  // SHA-256, hex

 private:
  Store* store_;
  std::function<Clock::time_point()> now_;
  mutable std::mutex mutex_;
  std::map<std::string, StoredToken> by_hash_;
};

/// The check of every call: the token from `authorization: Bearer TOKEN`, the method's least
/// role from the table. UNAUTHENTICATED or PERMISSION_DENIED (naming the role needed) refuse the
/// call before any handler runs; a refused state-changing call is recorded in the audit.
class AuthProcessor final : public grpc::AuthMetadataProcessor {
 public:
  /// `quotas` (may be null): metered methods are charged to the caller's token here.
  AuthProcessor(const TokenRegistry& tokens, Store* audit, Quotas* quotas = nullptr)
      : tokens_(tokens), audit_(audit), quotas_(quotas) {}
  bool IsBlocking() const override { return true; }  // it may write an audit row
  grpc::Status Process(const InputMetadata& auth_metadata, grpc::AuthContext* context,
                       OutputMetadata* consumed_auth_metadata,
                       OutputMetadata* response_metadata) override;

 private:
  const TokenRegistry& tokens_;
  Store* audit_;
  Quotas* quotas_;
};

/// Records every state-changing call that reached a handler: when, which token, the method, the
/// target it named, and the status it ended with.
class AuditInterceptorFactory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  explicit AuditInterceptorFactory(Store* store) : store_(store) {}
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override;

 private:
  Store* store_;
};

int64_t UnixMillis(std::chrono::system_clock::time_point t);

}  // namespace rheo::daemon
