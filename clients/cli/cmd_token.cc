// `rheoctl token create|list|revoke`, `rheoctl audit`, `rheoctl whoami`: who may do what.
#include <ctime>
#include <iostream>

#include "rheo/v1/auth.grpc.pb.h"
#include "rheoctl.h"

namespace rheoctl {
namespace {

using AuthStub = rheo::v1::AuthService::Stub;

const char* RoleWord(rheo::v1::Role r) {
  switch (r) {
    case rheo::v1::ROLE_VIEWER: return "viewer";
    case rheo::v1::ROLE_OPERATOR: return "operator";
    case rheo::v1::ROLE_ADMIN: return "admin";
    default: return "none";
  }
}

std::string When(int64_t unix_ms) {
  if (unix_ms == 0) return "-";
  const std::time_t t = static_cast<std::time_t>(unix_ms / 1000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return b;
}

// "2026-12-01T10:00:00Z", "-3600" (seconds before now) or unix milliseconds.
bool ParseSince(const std::string& s, int64_t* out) {
  if (s.empty()) return *out = 0, true;
  std::tm tm{};
  if (const char* end = strptime(s.c_str(), "%Y-%m-%dT%H:%M:%S", &tm);
      end && (*end == '\0' || *end == 'Z')) {
    *out = static_cast<int64_t>(timegm(&tm)) * 1000;
    return true;
  }
  char* end = nullptr;
  const long long v = std::strtoll(s.c_str(), &end, 10);
  if (end == s.c_str() || *end != '\0') return false;
  *out = v < 0 ? (static_cast<int64_t>(std::time(nullptr)) + v) * 1000 : v;
  return true;
}

}  // namespace

void AddTokenCommands(CLI::App& app, const Global& g) {
  struct Args {
    std::string role = "viewer", name, since;
    double expires = 0;
    uint32_t limit = 100;
    bool json = false;
  };
  auto a = std::make_shared<Args>();
  auto* token = app.add_subcommand("token", "access tokens (admin): create, list, revoke");
  token->require_subcommand(1);
  auto* create = token->add_subcommand(
      "create", "make a token; prints it on stdout, once (the daemon keeps only its hash)");
  create->add_option("--role", a->role, "viewer, operator or admin")
      ->check(CLI::IsMember({"viewer", "operator", "admin"}))
      ->capture_default_str();
  create->add_option("--name", a->name, "unique name, shown in the audit (default: ROLE-N)");
  create->add_option("--expires", a->expires, "lifetime [s] (0: never)");
  create->callback([&g, a] {
    rheo::v1::CreateTokenRequest req;
    req.set_role(a->role == "admin"      ? rheo::v1::ROLE_ADMIN
                 : a->role == "operator" ? rheo::v1::ROLE_OPERATOR
                                         : rheo::v1::ROLE_VIEWER);
    req.set_name(a->name.empty() ? a->role + "-" + std::to_string(std::time(nullptr)) : a->name);
    req.set_expires_in_s(a->expires);
    rheo::v1::CreateTokenResponse r;
    grpc::Status s = Unary<rheo::v1::AuthService>(g, &AuthStub::CreateToken, req, &r);
    if (!s.ok()) return void(g_exit_code = Fail(s));
    std::cout << r.token() << "\n";
    std::cerr << "token '" << r.info().name() << "' (" << RoleWord(r.info().role()) << ", expires "
              << When(r.info().expires_unix_ms())
              << "): store it now, it is not shown again; revoke with: rheoctl token revoke "
              << r.info().name() << "\n";
    g_exit_code = 0;
  });
  auto* list = token->add_subcommand("list", "every token: name, role, created, expires, revoked");
  list->add_flag("--json", a->json, "print the ListTokensResponse as JSON");
  list->callback([&g, a] {
    rheo::v1::ListTokensResponse r;
    grpc::Status s =
        Unary<rheo::v1::AuthService>(g, &AuthStub::ListTokens, rheo::v1::ListTokensRequest(), &r);
    if (!s.ok()) return void(g_exit_code = Fail(s));
    if (a->json) {
      std::cout << ToJson(r, true);
    } else {
      std::printf("%-24s %-9s %-21s %-21s %s\n", "NAME", "ROLE", "CREATED", "EXPIRES", "REVOKED");
      for (const auto& t : r.tokens())
        std::printf("%-24s %-9s %-21s %-21s %s\n", t.name().c_str(), RoleWord(t.role()),
                    When(t.created_unix_ms()).c_str(), When(t.expires_unix_ms()).c_str(),
                    When(t.revoked_unix_ms()).c_str());
    }
    g_exit_code = 0;
  });
  auto* revoke = token->add_subcommand("revoke", "revoke a token by name: refused from then on");
  revoke->add_option("NAME", a->name)->required();
  revoke->callback([&g, a] {
    rheo::v1::RevokeTokenRequest req;
    req.set_name(a->name);
    rheo::v1::RevokeTokenResponse r;
    grpc::Status s = Unary<rheo::v1::AuthService>(g, &AuthStub::RevokeToken, req, &r);
    if (!s.ok()) return void(g_exit_code = Fail(s));
    std::printf("revoked token '%s'\n", r.info().name().c_str());
    g_exit_code = 0;
  });

  auto* audit = app.add_subcommand("audit", "admin: the state-changing calls, newest first");
  audit->add_option("--since", a->since,
                    "from this time on: 2026-12-01T10:00:00 (UTC), -3600 (seconds ago) or unix ms");
  audit->add_option("--limit", a->limit, "most entries")->capture_default_str();
  audit->add_flag("--json", a->json, "print the ListAuditResponse as JSON");
  audit->callback([&g, a] {
    rheo::v1::ListAuditRequest req;
    int64_t since = 0;
    if (!ParseSince(a->since, &since)) {
      std::cerr << "INVALID_ARGUMENT: --since '" << a->since
                << "' is not 2026-12-01T10:00:00, -SECONDS or unix milliseconds\n";
      return void(g_exit_code = 3);
    }
    req.set_since_unix_ms(since);
    req.set_limit(a->limit);
    rheo::v1::ListAuditResponse r;
    grpc::Status s = Unary<rheo::v1::AuthService>(g, &AuthStub::ListAudit, req, &r);
    if (!s.ok()) return void(g_exit_code = Fail(s));
    if (a->json) {
      std::cout << ToJson(r, true);
    } else {
      for (const auto& e : r.entries())
        std::printf("%s  %-16s %-40s %-24s %s%s%s\n", When(e.at_unix_ms()).c_str(),
                    e.token_name().empty() ? "(no token)" : e.token_name().c_str(),
                    e.method().c_str(), e.target().c_str(), e.code() == 0 ? "OK" : "refused ",
                    e.code() == 0 ? "" : std::to_string(e.code()).c_str(),
                    e.message().empty() ? "" : (": " + e.message()).c_str());
    }
    g_exit_code = 0;
  });

  app.add_subcommand("whoami", "the token's name and role")->callback([&g] {
    rheo::v1::Identity r;
    grpc::Status s =
        Unary<rheo::v1::AuthService>(g, &AuthStub::WhoAmI, rheo::v1::WhoAmIRequest(), &r);
    if (!s.ok()) return void(g_exit_code = Fail(s));
    std::printf("%s (%s)\n", r.token_name().c_str(), RoleWord(r.role()));
    g_exit_code = 0;
  });
}

}  // namespace rheoctl
