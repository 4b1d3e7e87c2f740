#include "daemon/api/auth.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>
#include <grpcpp/server_context.h>
#include <openssl/evp.h>
#include <openssl/rand.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "daemon/api/limits.h"

namespace rheo::daemon {
namespace {

constexpr std::string_view kBearer = "Bearer ";

std::string Hex(const unsigned char* p, size_t n) {
  static const char* digits = "0123456789abcdef";
  std::string s(2 * n, '0');
  for (size_t i = 0; i < n; ++i) {
    s[2 * i] = digits[p[i] >> 4];
    s[2 * i + 1] = digits[p[i] & 15];
  }
  return s;
}

bool ValidTokenName(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' ||
           c == '_' || c == '.' || c == '@';
  });
}

std::string Str(grpc::string_ref r) {
  return std::string(r.data(), r.size());
}

}  // namespace

const char* RoleName(Role role) {
  switch (role) {
    case Role::kViewer: return "viewer";
    case Role::kOperator: return "operator";
    case Role::kAdmin: return "admin";
    case Role::kNone: break;
  }
  return "none";
}

std::optional<Role> ParseRole(std::string_view name) {
  if (name == "viewer") return Role::kViewer;
  if (name == "operator") return Role::kOperator;
  if (name == "admin") return Role::kAdmin;
  return std::nullopt;
}

int64_t UnixMillis(std::chrono::system_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count();
}

const std::vector<MethodRule>& MethodTable() {
  constexpr Role V = Role::kViewer, O = Role::kOperator, A = Role::kAdmin, open = Role::kNone;
  constexpr bool metered = true;
  constexpr size_t sketch = kMaxSketchRequestBytes, small = 64 * 1024, pose = 4 * 1024;
  static const std::vector<MethodRule> table = {
      // Open: load balancers and tools must reach them without a token.
      {"/grpc.health.v1.Health/Check", open, false},
      {"/grpc.health.v1.Health/Watch", open, false},
      {"/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo", open, false},
      {"/grpc.reflection.v1.ServerReflection/ServerReflectionInfo", open, false},
      // Watching.
      {"/rheo.v1.DaemonService/GetStatus", V, false},
      {"/rheo.v1.FrameService/WatchFrames", V, false},
      {"/rheo.v1.ObjectService/ListObjects", V, false},
      {"/rheo.v1.ObjectService/GetObject", V, false},
      {"/rheo.v1.ObjectService/ExportObject", V, false, metered},
      {"/rheo.v1.SceneService/GetScene", V, false},
      {"/rheo.v1.SceneService/ListParameters", V, false},
      {"/rheo.v1.DeviceService/GetDeviceStatus", V, false},
      {"/rheo.v1.AuthService/WhoAmI", V, false},
      {"/rheo.v1.RecordingService/ListRecordings", V, false},
      // A recording's file can be large: each export counts against the calls per second.
      {"/rheo.v1.RecordingService/ExportRecording", V, false, metered},
      {"/rheo.v1.RecordingService/GetPlayback", V, false},
      // Anyone who can see the device may stop it (clearing it needs the lease: the handler).
      {"/rheo.v1.DeviceService/EmergencyStop", V, true},
      // Operating.
      {"/rheo.v1.ObjectService/CreateObject", O, true, metered, sketch},
      {"/rheo.v1.ObjectService/CancelJob", O, true},  // one's own jobs; an admin's any
      {"/rheo.v1.ObjectService/ExtractContour", O, false, metered, sketch},
      {"/rheo.v1.SceneService/AddToScene", O, true, metered},
      {"/rheo.v1.SceneService/RemoveFromScene", O, true},
      {"/rheo.v1.SceneService/SetParameters", O, true, false, small},
      {"/rheo.v1.SceneService/Control", O, true},
      {"/rheo.v1.DeviceService/Calibrate", O, true},
      {"/rheo.v1.DeviceService/AcquireLease", O, true},
      {"/rheo.v1.DeviceService/RenewLease", O, true},
      {"/rheo.v1.DeviceService/ReleaseLease", O, true},
      {"/rheo.v1.DeviceService/ToolStream", O, true, false, pose},
      {"/rheo.v1.DeviceService/SimulatedHand", O, true},
      {"/rheo.v1.RecordingService/StartRecording", O, true},
      {"/rheo.v1.RecordingService/StopRecording", O, true},
      {"/rheo.v1.RecordingService/DeleteRecording", O, true},
      {"/rheo.v1.RecordingService/ControlPlayback", O, true},
      // Administering.
      {"/rheo.v1.ObjectService/DeleteObject", A, true},
      {"/rheo.v1.DeviceService/RevokeLease", A, true},
      {"/rheo.v1.AuthService/CreateToken", A, true},
      {"/rheo.v1.AuthService/ListTokens", A, false},
      {"/rheo.v1.AuthService/RevokeToken", A, true},
      {"/rheo.v1.AuthService/ListAudit", A, false},
  };
  return table;
}

const MethodRule* FindMethod(std::string_view path) {
  for (const MethodRule& r : MethodTable())
    if (r.path == path) return &r;
  return nullptr;
}

namespace {
const TokenRegistry* g_caller_tokens = nullptr;
}  // namespace

void SetCallerTokens(const TokenRegistry* tokens) {
  g_caller_tokens = tokens;
}

// From the call's own authorization header: gRPC's auth context is shared by the calls of one
// connection (the gateway's carries many pages' calls), so it cannot say who made this one.
Caller CallerOf(const grpc::ServerContextBase* context) {
  Caller c;
  if (!context || !g_caller_tokens) return c;
  const auto& md = context->client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) return c;
  std::string_view value(it->second.data(), it->second.size());
  if (value.substr(0, kBearer.size()) != kBearer) return c;
  auto token = g_caller_tokens->Authenticate(value.substr(kBearer.size()));
  if (!token.ok()) return c;
  c.token_name = token->name;
  c.role = static_cast<Role>(token->role);
  return c;
}

// ---- tokens ----

TokenRegistry::TokenRegistry(Store* store, std::function<Clock::time_point()> now)
    : store_(store), now_(std::move(now)) {}

Status TokenRegistry::Load() {
  auto all = store_->ListTokens();
  if (!all.ok()) return all.error();
  std::lock_guard<std::mutex> lock(mutex_);
  by_hash_.clear();
  for (StoredToken& t : *all) by_hash_[t.hash] = std::move(t);
  return Status::Ok();
}

bool TokenRegistry::empty() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return by_hash_.empty();
}

std::string TokenRegistry::Hash(std::string_view token) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int n = 0;
  EVP_Digest(token.data(), token.size(), digest, &n, EVP_sha256(), nullptr);
  return Hex(digest, n);
}

Result<TokenRegistry::Created> TokenRegistry::Create(const std::string& name, Role role,
                                                     double expires_in_s) {
  if (!ValidTokenName(name))
    return InvalidArgument("token name " + QuoteForMessage(name) +
                           " is not 1 to 64 letters, digits, '-', '_', '.' or '@'");
  if (role == Role::kNone)
    return InvalidArgument("a token needs a role: viewer, operator or admin");
  if (!(expires_in_s >= 0.0) || !std::isfinite(expires_in_s) || expires_in_s > 10 * 365 * 86400.0)
    return InvalidArgument("expires_in_s must be 0 (never) or up to ten years, got " +
                           std::to_string(expires_in_s));
  unsigned char secret[32];
  if (RAND_bytes(secret, sizeof secret) != 1)
    return Internal("the system's random source failed; no token was made");
  Created c;
  c.token = "rheo_" + Hex(secret, sizeof secret);
  const auto now = now_();
  c.info.name = name;
  c.info.role = static_cast<int>(role);
  c.info.hash = Hash(c.token);
  c.info.created_unix_ms = UnixMillis(now);
  c.info.expires_unix_ms =
      expires_in_s > 0.0 ? c.info.created_unix_ms + static_cast<int64_t>(expires_in_s * 1e3) : 0;
  std::lock_guard<std::mutex> lock(mutex_);
  if (Status s = store_->PutToken(c.info); !s.ok()) return s.error();
  by_hash_[c.info.hash] = c.info;
  return c;
}

Result<StoredToken> TokenRegistry::Revoke(const std::string& name) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto t = store_->RevokeToken(name, UnixMillis(now_()));
  if (!t.ok()) return t.error();
  by_hash_[t->hash] = *t;
  return t;
}

std::vector<StoredToken> TokenRegistry::List() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<StoredToken> out;
  for (const auto& [h, t] : by_hash_) out.push_back(t);
  std::sort(out.begin(), out.end(), [](const StoredToken& a, const StoredToken& b) {
    return a.created_unix_ms != b.created_unix_ms ? a.created_unix_ms < b.created_unix_ms
                                                  : a.name < b.name;
  });
  return out;
}

Result<StoredToken> TokenRegistry::Authenticate(std::string_view token) const {
  const std::string hash = Hash(token);
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = by_hash_.find(hash);
  if (it == by_hash_.end())
    return Error{ErrorCode::kUnauthenticated,
                 "the token is not one this daemon issued; ask an admin for one (rheoctl token "
                 "create)"};
  const StoredToken& t = it->second;
  if (t.revoked_unix_ms != 0)
    return Error{ErrorCode::kUnauthenticated,
                 "token '" + t.name + "' was revoked; ask an admin for a new one"};
  if (t.expires_unix_ms != 0 && UnixMillis(now_()) >= t.expires_unix_ms)
    return Error{ErrorCode::kUnauthenticated,
                 "token '" + t.name + "' has expired; ask an admin for a new one"};
  return t;
}

// ---- the check ----

grpc::Status AuthProcessor::Process(const InputMetadata& md, grpc::AuthContext*, OutputMetadata*,
                                    OutputMetadata*) {
  auto path_it = md.find(":path");
  const std::string path = path_it == md.end() ? std::string() : Str(path_it->second);
  const MethodRule* rule = FindMethod(path);
  if (rule && rule->least == Role::kNone) return grpc::Status::OK;
  auto refuse = [&](grpc::StatusCode code, const std::string& token_name, std::string message) {
    if (rule && rule->audited && audit_) {
      AuditRow row;
      row.at_unix_ms = UnixMillis(std::chrono::system_clock::now());
      row.token_name = token_name;
      row.method = path;
      row.code = static_cast<int>(code);
      row.message = message;
      (void)audit_->AppendAudit(row);  // the refusal stands whether or not it could be recorded
    }
    return grpc::Status(code, std::move(message));
  };
  auto auth_it = md.find("authorization");
  if (auth_it == md.end())
    return refuse(grpc::StatusCode::UNAUTHENTICATED, "",
                  "this call needs an access token: send 'authorization: Bearer TOKEN' (rheoctl "
                  "--token-file FILE, or RHEO_TOKEN; the studio asks for it)");
  std::string_view value(auth_it->second.data(), auth_it->second.size());
  if (value.substr(0, kBearer.size()) != kBearer)
    return refuse(grpc::StatusCode::UNAUTHENTICATED, "",
                  "the authorization header must be 'Bearer TOKEN'");
  auto token = tokens_.Authenticate(value.substr(kBearer.size()));
  if (!token.ok()) return refuse(grpc::StatusCode::UNAUTHENTICATED, "", token.error().message);
  const Role role = static_cast<Role>(token->role);
  if (!rule)
    return refuse(grpc::StatusCode::PERMISSION_DENIED, token->name,
                  "method " + QuoteForMessage(path, 120) +
                      " has no entry in rheod's role table, so no role may call it");
  if (static_cast<int>(role) < static_cast<int>(rule->least))
    return refuse(grpc::StatusCode::PERMISSION_DENIED, token->name,
                  std::string(path.substr(path.rfind('/') + 1)) + " needs the " +
                      RoleName(rule->least) + " role; token '" + token->name + "' is a " +
                      RoleName(role) + " (ask an admin for a token with that role)");
  if (rule->metered && quotas_) {
    grpc::Status s = quotas_->Charge(token->name, path.substr(path.rfind('/') + 1));
    if (!s.ok()) return refuse(s.error_code(), token->name, s.error_message());
  }
  // The header stays on the call (not consumed): CallerOf reads who made it from there.
  return grpc::Status::OK;
}

// ---- the audit ----

namespace {

namespace pb = google::protobuf;

// "id=obj-1 name=pear": the request's top-level scalar fields that are set, secrets left out.
std::string TargetOf(const pb::Message& m) {
  const pb::Descriptor* d = m.GetDescriptor();
  const pb::Reflection* r = m.GetReflection();
  std::string out;
  for (int i = 0; i < d->field_count() && out.size() < 200; ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    if (f->is_repeated() || f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) continue;
    if (f->name() == "lease_id" || f->name() == "token") continue;
    if (!r->HasField(m, f)) continue;
    std::string v;
    switch (f->cpp_type()) {
      case pb::FieldDescriptor::CPPTYPE_STRING:
        if (f->type() == pb::FieldDescriptor::TYPE_BYTES) continue;
        v = QuoteForMessage(r->GetString(m, f), 64);
        break;
      case pb::FieldDescriptor::CPPTYPE_ENUM: v = r->GetEnum(m, f)->name(); break;
      case pb::FieldDescriptor::CPPTYPE_BOOL: v = r->GetBool(m, f) ? "true" : "false"; break;
      case pb::FieldDescriptor::CPPTYPE_UINT32: v = std::to_string(r->GetUInt32(m, f)); break;
      case pb::FieldDescriptor::CPPTYPE_INT32: v = std::to_string(r->GetInt32(m, f)); break;
      case pb::FieldDescriptor::CPPTYPE_UINT64: v = std::to_string(r->GetUInt64(m, f)); break;
      case pb::FieldDescriptor::CPPTYPE_INT64: v = std::to_string(r->GetInt64(m, f)); break;
      case pb::FieldDescriptor::CPPTYPE_DOUBLE: v = std::to_string(r->GetDouble(m, f)); break;
      case pb::FieldDescriptor::CPPTYPE_FLOAT: v = std::to_string(r->GetFloat(m, f)); break;
      default: continue;
    }
    if (!out.empty()) out += ' ';
    out += f->name() + "=" + v;
  }
  return out;
}

class AuditInterceptor final : public grpc::experimental::Interceptor {
 public:
  AuditInterceptor(grpc::experimental::ServerRpcInfo* info, Store* store)
      : info_(info), store_(store) {}

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    using grpc::experimental::InterceptionHookPoints;
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_MESSAGE) &&
        !have_target_) {
      if (const auto* m = static_cast<const pb::Message*>(methods->GetRecvMessage())) {
        target_ = TargetOf(*m);
        have_target_ = true;
      }
    }
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS)) {
      const grpc::Status s = methods->GetSendStatus();
      AuditRow row;
      row.at_unix_ms = UnixMillis(std::chrono::system_clock::now());
      row.token_name = CallerOf(info_->server_context()).token_name;
      row.method = info_->method() ? info_->method() : "";
      row.target = target_;
      row.code = static_cast<int>(s.error_code());
      row.message = s.error_message().substr(0, 500);
      (void)store_->AppendAudit(row);  // a full disk must not fail the call it records
    }
    methods->Proceed();
  }

 private:
  grpc::experimental::ServerRpcInfo* info_;
  Store* store_;
  std::string target_;
  bool have_target_ = false;
};

}  // namespace

grpc::experimental::Interceptor* AuditInterceptorFactory::CreateServerInterceptor(
    grpc::experimental::ServerRpcInfo* info) {
  const MethodRule* rule = FindMethod(info->method() ? info->method() : "");
  if (!rule || !rule->audited) return nullptr;
  return new AuditInterceptor(info, store_);
}

}  // namespace rheo::daemon
