// AuthService: who the caller is, the tokens (admin), and the audit (admin). The role check
// itself is not here: AuthProcessor ran before any of these handlers.
#include "daemon/api/grpc_status.h"
#include "daemon/api/limits.h"
#include "daemon/api/services.h"

namespace rheo::daemon {
namespace {

void FillToken(const StoredToken& t, v1::TokenInfo* out) {
  out->set_name(t.name);
  out->set_role(static_cast<v1::Role>(t.role));
  out->set_created_unix_ms(t.created_unix_ms);
  out->set_expires_unix_ms(t.expires_unix_ms);
  out->set_revoked_unix_ms(t.revoked_unix_ms);
}

}  // namespace

grpc::Status AuthServiceImpl::WhoAmI(grpc::ServerContext* context, const v1::WhoAmIRequest* req,
                                     v1::Identity* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  const Caller caller = CallerOf(context);
  out->set_token_name(caller.token_name);
  out->set_role(static_cast<v1::Role>(caller.role));
  for (const StoredToken& t : ctx_.tokens->List())
    if (t.name == caller.token_name) out->set_expires_unix_ms(t.expires_unix_ms);
  return grpc::Status::OK;
}

grpc::Status AuthServiceImpl::CreateToken(grpc::ServerContext*, const v1::CreateTokenRequest* req,
                                          v1::CreateTokenResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (req->role() < v1::ROLE_VIEWER || req->role() > v1::ROLE_ADMIN)
    return ToGrpc(InvalidArgument("role must be ROLE_VIEWER, ROLE_OPERATOR or ROLE_ADMIN"));
  auto made = ctx_.tokens->Create(req->name(), static_cast<Role>(req->role()), req->expires_in_s());
  if (!made.ok()) return ToGrpc(made.error());
  FillToken(made->info, out->mutable_info());
  out->set_token(made->token);
  return grpc::Status::OK;
}

grpc::Status AuthServiceImpl::ListTokens(grpc::ServerContext*, const v1::ListTokensRequest* req,
                                         v1::ListTokensResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  for (const StoredToken& t : ctx_.tokens->List()) FillToken(t, out->add_tokens());
  return grpc::Status::OK;
}

grpc::Status AuthServiceImpl::RevokeToken(grpc::ServerContext*, const v1::RevokeTokenRequest* req,
                                          v1::RevokeTokenResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (req->name().empty()) return ToGrpc(InvalidArgument("name is empty: which token to revoke"));
  auto t = ctx_.tokens->Revoke(req->name());
  if (!t.ok()) return ToGrpc(t.error());
  FillToken(*t, out->mutable_info());
  return grpc::Status::OK;
}

grpc::Status AuthServiceImpl::ListAudit(grpc::ServerContext*, const v1::ListAuditRequest* req,
                                        v1::ListAuditResponse* out) {
  if (grpc::Status s = CheckRequest(*req); !s.ok()) return s;
  if (req->limit() > 10000)
    return ToGrpc(InvalidArgument("limit is at most 10000, got " + std::to_string(req->limit())));
  auto rows = ctx_.store->ListAudit(req->since_unix_ms(), req->limit() == 0 ? 100 : req->limit());
  if (!rows.ok()) return ToGrpc(rows.error());
  for (const AuditRow& r : *rows) {
    v1::AuditEntry* e = out->add_entries();
    e->set_at_unix_ms(r.at_unix_ms);
    e->set_token_name(r.token_name);
    e->set_method(r.method);
    e->set_target(r.target);
    e->set_code(r.code);
    e->set_message(r.message);
  }
  return grpc::Status::OK;
}

}  // namespace rheo::daemon
