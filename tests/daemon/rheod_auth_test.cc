// Who may do what, against a real rheod: every method of every service it serves x every role
// (plus no token, a wrong, an expired and a revoked one), the lease across two operators and an
// admin, the audit, the first admin token, the refusal of plaintext on a non-loopback address,
// and TLS with a CA made here (plaintext, wrong CA, right CA, mutual TLS).
#include <google/protobuf/descriptor.h>
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <thread>

#include "grpc/reflection/v1alpha/reflection.grpc.pb.h"
#include "rheo/client/channel.h"
#include "rheo/v1/auth.grpc.pb.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/device.grpc.pb.h"
#include "rheo/v1/frames.pb.h"
#include "rheo/v1/objects.pb.h"
#include "rheo/v1/recording.pb.h"
#include "rheo/v1/scene.pb.h"
#include "rheod_fixture.h"

namespace rheo::testing {
namespace {

using namespace std::chrono_literals;
namespace pb = google::protobuf;

enum Least { kOpen = 0, kViewer = 1, kOperator = 2, kAdmin = 3 };
const char* kRoleWord[] = {"open", "viewer", "operator", "admin"};

// The specification (the words), independent of the daemon's own table: a method the
// daemon serves that is not listed here fails the test until someone decides its role.
const std::map<std::string, Least>& Spec() {
  static const std::map<std::string, Least> spec = {
      {"/grpc.health.v1.Health/Check", kOpen},
      {"/grpc.health.v1.Health/Watch", kOpen},
      {"/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo", kOpen},
      {"/rheo.v1.DaemonService/GetStatus", kViewer},
      {"/rheo.v1.FrameService/WatchFrames", kViewer},
      {"/rheo.v1.ObjectService/ListObjects", kViewer},
      {"/rheo.v1.ObjectService/GetObject", kViewer},
      {"/rheo.v1.ObjectService/ExportObject", kViewer},
      {"/rheo.v1.SceneService/GetScene", kViewer},
      {"/rheo.v1.SceneService/ListParameters", kViewer},
      {"/rheo.v1.DeviceService/GetDeviceStatus", kViewer},
      {"/rheo.v1.DeviceService/EmergencyStop", kViewer},
      {"/rheo.v1.AuthService/WhoAmI", kViewer},
      {"/rheo.v1.RecordingService/ListRecordings", kViewer},
      {"/rheo.v1.RecordingService/ExportRecording", kViewer},
      {"/rheo.v1.RecordingService/GetPlayback", kViewer},
      {"/rheo.v1.ObjectService/CreateObject", kOperator},
      {"/rheo.v1.ObjectService/CancelJob", kOperator},
      {"/rheo.v1.ObjectService/ExtractContour", kOperator},
      {"/rheo.v1.SceneService/AddToScene", kOperator},
      {"/rheo.v1.SceneService/RemoveFromScene", kOperator},
      {"/rheo.v1.SceneService/SetParameters", kOperator},
      {"/rheo.v1.SceneService/Control", kOperator},
      {"/rheo.v1.DeviceService/Calibrate", kOperator},
      {"/rheo.v1.DeviceService/AcquireLease", kOperator},
      {"/rheo.v1.DeviceService/RenewLease", kOperator},
      {"/rheo.v1.DeviceService/ReleaseLease", kOperator},
      {"/rheo.v1.DeviceService/ToolStream", kOperator},
      {"/rheo.v1.DeviceService/SimulatedHand", kOperator},
      {"/rheo.v1.RecordingService/StartRecording", kOperator},
      {"/rheo.v1.RecordingService/StopRecording", kOperator},
      {"/rheo.v1.RecordingService/DeleteRecording", kOperator},
      {"/rheo.v1.RecordingService/ControlPlayback", kOperator},
      {"/rheo.v1.ObjectService/DeleteObject", kAdmin},
      {"/rheo.v1.DeviceService/RevokeLease", kAdmin},
      {"/rheo.v1.AuthService/CreateToken", kAdmin},
      {"/rheo.v1.AuthService/ListTokens", kAdmin},
      {"/rheo.v1.AuthService/RevokeToken", kAdmin},
      {"/rheo.v1.AuthService/ListAudit", kAdmin},
  };
  return spec;
}

// The services the daemon really serves, from its reflection service.
std::vector<std::string> ServedServices(const std::shared_ptr<grpc::Channel>& channel) {
  auto stub = grpc::reflection::v1alpha::ServerReflection::NewStub(channel);
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  auto stream = stub->ServerReflectionInfo(&ctx);
  grpc::reflection::v1alpha::ServerReflectionRequest req;
  req.set_list_services("");
  EXPECT_TRUE(stream->Write(req));
  stream->WritesDone();
  grpc::reflection::v1alpha::ServerReflectionResponse resp;
  std::vector<std::string> out;
  while (stream->Read(&resp))
    for (const auto& s : resp.list_services_response().service()) out.push_back(s.name());
  EXPECT_TRUE(stream->Finish().ok());
  return out;
}

std::string MakeToken(const RheodProcess& d, const std::string& name, v1::Role role,
                      double expires_s = 0) {
  v1::CreateTokenRequest req;
  req.set_name(name);
  req.set_role(role);
  req.set_expires_in_s(expires_s);
  v1::CreateTokenResponse out;
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  grpc::Status s = v1::AuthService::NewStub(d.channel())->CreateToken(&ctx, req, &out);
  EXPECT_TRUE(s.ok()) << s.error_message();
  return out.token();
}

TEST(RheodAuth, EveryMethodTimesEveryRole) {
  RheodProcess d({"--http", "off"});
  ASSERT_TRUE(d.started()) << d.log();
  std::map<Least, std::string> tokens = {
      {kViewer, MakeToken(d, "vera", v1::ROLE_VIEWER)},
      {kOperator, MakeToken(d, "otto", v1::ROLE_OPERATOR)},
      {kAdmin, d.admin_token()},
  };
  // Every method of every served service is in the specification. (Touching one message of each
  // file links its descriptors into this test's pool.)
  for (const pb::Descriptor* m :
       {v1::DaemonStatus::descriptor(), v1::Frame::descriptor(), v1::Scene::descriptor(),
        v1::Object::descriptor(), v1::DeviceStatus::descriptor(), v1::Identity::descriptor(),
        v1::Recording::descriptor()})
    ASSERT_NE(m, nullptr);
  std::vector<std::string> methods;
  for (const std::string& service : ServedServices(d.channel(""))) {
    const pb::ServiceDescriptor* s =
        pb::DescriptorPool::generated_pool()->FindServiceByName(service);
    if (!s && service.rfind("grpc.", 0) == 0) {
      // gRPC's own services (health): their descriptors are not linked here; the spec's entries.
      for (const auto& [path, least] : Spec())
        if (path.rfind("/" + service + "/", 0) == 0) methods.push_back(path);
      continue;
    }
    ASSERT_NE(s, nullptr) << "the daemon serves " << service << ", which this test does not know";
    for (int i = 0; i < s->method_count(); ++i) {
      const std::string path = "/" + service + "/" + s->method(i)->name();
      EXPECT_TRUE(Spec().count(path)) << path << " has no role in the specification";
      methods.push_back(path);
    }
  }
  EXPECT_GE(methods.size(), Spec().size() - 1);  // v1 reflection may be absent
  int checked = 0;
  for (const std::string& path : methods) {
    auto it = Spec().find(path);
    if (it == Spec().end()) continue;
    const Least least = it->second;
    // No token: open methods pass, every other is UNAUTHENTICATED.
    grpc::Status none = CallEmpty(d.channel(""), path);
    if (least == kOpen)
      EXPECT_NE(none.error_code(), grpc::StatusCode::UNAUTHENTICATED) << path;
    else
      EXPECT_EQ(none.error_code(), grpc::StatusCode::UNAUTHENTICATED) << path;
    for (const auto& [role, token] : tokens) {
      grpc::Status s = CallEmpty(d.channel(token), path);
      ++checked;
      if (role >= least) {
        EXPECT_NE(s.error_code(), grpc::StatusCode::UNAUTHENTICATED) << path;
        // Past the check: whatever the handler says of an empty request, never the role refusal.
        EXPECT_EQ(s.error_message().find(" role; token '"), std::string::npos)
            << path << " as " << kRoleWord[role] << ": " << s.error_message();
      } else {
        EXPECT_EQ(s.error_code(), grpc::StatusCode::PERMISSION_DENIED)
            << path << " as " << kRoleWord[role] << ": " << s.error_message();
        EXPECT_NE(s.error_message().find(std::string("needs the ") + kRoleWord[least] + " role"),
                  std::string::npos)
            << s.error_message();
      }
    }
  }
  EXPECT_GE(checked, 3 * 30);
  ASSERT_TRUE(d.Terminate(10s) == 0) << d.log();
}

TEST(RheodAuth, WrongExpiredAndRevokedTokensAreRefusedInWords) {
  RheodProcess d({"--http", "off"});
  ASSERT_TRUE(d.started()) << d.log();
  auto status = [&](const std::string& token) {
    v1::DaemonStatus out;
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    return v1::DaemonService::NewStub(d.channel(token))
        ->GetStatus(&ctx, v1::GetStatusRequest(), &out);
  };
  const std::string viewer = MakeToken(d, "vera", v1::ROLE_VIEWER);
  EXPECT_TRUE(status(viewer).ok());
  // Who a call is comes from its own token, also when calls of several tokens share one
  // connection (channels to one address share it; the gateway's carries every page's calls).
  for (int i = 0; i < 3; ++i)
    for (const auto& [token, name] :
         {std::pair<std::string, std::string>{viewer, "vera"}, {d.admin_token(), "admin"}}) {
      v1::Identity me;
      grpc::ClientContext ctx;
      SetDeadline(ctx);
      ASSERT_TRUE(
          v1::AuthService::NewStub(d.channel(token))->WhoAmI(&ctx, v1::WhoAmIRequest(), &me).ok());
      EXPECT_EQ(me.token_name(), name);
    }
  grpc::Status none = status("");
  EXPECT_EQ(none.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_NE(none.error_message().find("needs an access token"), std::string::npos);
  grpc::Status wrong = status("rheo_" + std::string(64, '0'));
  EXPECT_EQ(wrong.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_NE(wrong.error_message().find("not one this daemon issued"), std::string::npos);

  const std::string brief = MakeToken(d, "brief", v1::ROLE_OPERATOR, 0.2);
  EXPECT_TRUE(status(brief).ok());
  std::this_thread::sleep_for(400ms);
  grpc::Status expired = status(brief);
  EXPECT_EQ(expired.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_NE(expired.error_message().find("token 'brief' has expired"), std::string::npos)
      << expired.error_message();

  {
    v1::RevokeTokenRequest req;
    req.set_name("vera");
    v1::RevokeTokenResponse out;
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(v1::AuthService::NewStub(d.channel())->RevokeToken(&ctx, req, &out).ok());
    EXPECT_GT(out.info().revoked_unix_ms(), 0);
  }
  grpc::Status revoked = status(viewer);
  EXPECT_EQ(revoked.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_NE(revoked.error_message().find("token 'vera' was revoked"), std::string::npos);

  // The list shows every token, never a secret; names are not reused.
  v1::ListTokensResponse list;
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(v1::AuthService::NewStub(d.channel())
                    ->ListTokens(&ctx, v1::ListTokensRequest(), &list)
                    .ok());
  }
  std::set<std::string> names;
  for (const auto& t : list.tokens()) names.insert(t.name());
  EXPECT_EQ(names, (std::set<std::string>{"admin", "vera", "brief"}));
  EXPECT_EQ(list.DebugString().find(viewer), std::string::npos);
  {
    v1::CreateTokenRequest req;
    req.set_name("vera");
    req.set_role(v1::ROLE_VIEWER);
    v1::CreateTokenResponse out;
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    EXPECT_EQ(v1::AuthService::NewStub(d.channel())->CreateToken(&ctx, req, &out).error_code(),
              grpc::StatusCode::ALREADY_EXISTS);
  }
  // Restarted on the same data: the same tokens hold, the admin token file is not rewritten.
  const std::string dir = d.data_dir();
  const std::string admin = d.admin_token();
  struct stat st {};
  ASSERT_EQ(stat((dir + "/admin.token").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_NE(d.log().find("wrote the admin token to " + dir + "/admin.token"), std::string::npos);
  ASSERT_EQ(d.Terminate(10s), 0);
  RheodProcess again({"--http", "off", "--data-dir", dir});
  ASSERT_TRUE(again.started()) << again.log();
  EXPECT_EQ(again.admin_token(), admin);
  EXPECT_EQ(again.log().find("wrote the admin token"), std::string::npos);
  v1::DaemonStatus out;
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  EXPECT_EQ(v1::DaemonService::NewStub(again.channel(viewer))
                ->GetStatus(&ctx, v1::GetStatusRequest(), &out)
                .error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  std::filesystem::remove_all(dir);
}

TEST(RheodAuth, TheLeaseBelongsToItsTokenAndAnAdminCanRevokeIt) {
  RheodProcess d({"--http", "off", "--device", "sim-spidar-g"});
  ASSERT_TRUE(d.started()) << d.log();
  const std::string ann = MakeToken(d, "ann", v1::ROLE_OPERATOR);
  const std::string bob = MakeToken(d, "bob", v1::ROLE_OPERATOR);
  const std::string vera = MakeToken(d, "vera", v1::ROLE_VIEWER);
  auto acquire = [&](const std::string& token, v1::Lease* out) {
    v1::AcquireLeaseRequest req;
    req.set_client_name("bench 2");
    req.set_duration_s(30);
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    return v1::DeviceService::NewStub(d.channel(token))->AcquireLease(&ctx, req, out);
  };
  auto renew = [&](const std::string& token, const std::string& id) {
    v1::RenewLeaseRequest req;
    req.set_lease_id(id);
    v1::Lease out;
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    return v1::DeviceService::NewStub(d.channel(token))->RenewLease(&ctx, req, &out);
  };
  v1::Lease lease;
  ASSERT_TRUE(acquire(ann, &lease).ok());
  EXPECT_EQ(lease.holder(), "bench 2 (token ann)");
  v1::Lease other;
  grpc::Status taken = acquire(bob, &other);
  EXPECT_EQ(taken.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(taken.error_message().find("bench 2 (token ann)"), std::string::npos);
  // Bob with Ann's lease id: refused, the id alone is not the lease.
  grpc::Status stolen = renew(bob, lease.lease_id());
  EXPECT_EQ(stolen.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_NE(stolen.error_message().find("belongs to token 'ann'"), std::string::npos);
  {
    v1::SimulatedHandRequest req;
    req.set_lease_id(lease.lease_id());
    req.set_release(true);
    v1::SimulatedHandResponse out;
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    EXPECT_EQ(
        v1::DeviceService::NewStub(d.channel(bob))->SimulatedHand(&ctx, req, &out).error_code(),
        grpc::StatusCode::PERMISSION_DENIED);
  }
  EXPECT_EQ(acquire(vera, &other).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_TRUE(renew(ann, lease.lease_id()).ok());
  // The admin ends it; Ann's id is dead, Bob may take the device.
  {
    v1::RevokeLeaseResponse out;
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(v1::DeviceService::NewStub(d.channel())
                    ->RevokeLease(&ctx, v1::RevokeLeaseRequest(), &out)
                    .ok());
    EXPECT_EQ(out.holder(), "bench 2 (token ann)");
  }
  EXPECT_EQ(renew(ann, lease.lease_id()).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_TRUE(acquire(bob, &other).ok());
  EXPECT_EQ(other.holder(), "bench 2 (token bob)");

  // The audit has the session: who, what, on what, how it ended.
  v1::ListAuditResponse audit;
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(v1::AuthService::NewStub(d.channel())
                    ->ListAudit(&ctx, v1::ListAuditRequest(), &audit)
                    .ok());
  }
  std::vector<std::string> rows;
  for (const auto& e : audit.entries())
    rows.push_back(e.token_name() + " " + e.method().substr(e.method().rfind('/') + 1) + " " +
                   std::to_string(e.code()) + " " + e.target());
  auto has = [&](const std::string& row) {
    return std::find(rows.begin(), rows.end(), row) != rows.end();
  };
  EXPECT_TRUE(has("ann AcquireLease 0 client_name='bench 2' duration_s=30.000000"))
      << ::testing::PrintToString(rows);
  EXPECT_TRUE(has("bob AcquireLease 9 client_name='bench 2' duration_s=30.000000"));
  EXPECT_TRUE(has("bob RenewLease 7 "));
  EXPECT_TRUE(has("vera AcquireLease 7 "));  // refused before any handler: no target read
  EXPECT_TRUE(has("admin RevokeLease 0 "));
  EXPECT_TRUE(has("admin CreateToken 0 name='vera' role=ROLE_VIEWER"));
  for (const auto& e : audit.entries()) {
    EXPECT_EQ(e.target().find(lease.lease_id()), std::string::npos) << "a lease id is a secret";
    EXPECT_GT(e.at_unix_ms(), 0);
  }
  // Reads are not audited.
  EXPECT_FALSE(std::any_of(rows.begin(), rows.end(), [](const std::string& r) {
    return r.find("ListAudit") != std::string::npos;
  }));
  ASSERT_EQ(d.Terminate(10s), 0) << d.log();
}

TEST(RheodAuth, PlaintextOnANonLoopbackAddressIsRefusedUnlessInsecure) {
  const std::string dir = std::filesystem::temp_directory_path() / "rheod-auth-refusal";
  std::filesystem::remove_all(dir);
  RunResult r = RunProgram(
      {RHEOD_PATH, "--listen", "0.0.0.0:0", "--http", "off", "--data-dir", dir, "--no-realtime"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("is not a loopback address and there is no TLS"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("--tls-cert"), std::string::npos);
  RunResult h = RunProgram({RHEOD_PATH, "--listen", "127.0.0.1:0", "--http", "0.0.0.0:0",
                            "--data-dir", dir, "--no-realtime"});
  EXPECT_EQ(h.exit_code, 1);
  EXPECT_NE(h.err.find("--http 0.0.0.0:0 is not a loopback address"), std::string::npos) << h.err;

  // --insecure: served (through the relay onto the checked port), tokens still checked, warned.
  RheodProcess d({"--listen", "0.0.0.0:0", "--http", "off", "--insecure", "--data-dir", dir});
  ASSERT_TRUE(d.WaitForLog("PLAINTEXT (--insecure)", 30s)) << d.log();
  EXPECT_TRUE(d.WaitForLog("--insecure: --listen 0.0.0.0:0 serve plaintext", 10s)) << d.log();
  const std::string l = d.log();
  const size_t at = l.find("listening on 0.0.0.0:");
  ASSERT_NE(at, std::string::npos);
  const int port = std::atoi(l.c_str() + at + std::string("listening on 0.0.0.0:").size());
  rheo::client::ChannelOptions o;
  o.target = "127.0.0.1:" + std::to_string(port);
  auto status = [&](const std::string& token) {
    o.token = token;
    v1::DaemonStatus out;
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    return v1::DaemonService::NewStub(rheo::client::Connect(o, nullptr))
        ->GetStatus(&ctx, v1::GetStatusRequest(), &out);
  };
  EXPECT_EQ(status("").error_code(), grpc::StatusCode::UNAUTHENTICATED);
  grpc::Status ok = status(rheo::client::ReadTokenFile(dir + "/admin.token", nullptr));
  EXPECT_TRUE(ok.ok()) << ok.error_message();
  EXPECT_EQ(d.Terminate(10s), 0) << d.log();
  std::filesystem::remove_all(dir);
}

// ---- TLS, with a CA made here ----

grpc::Status TlsStatus(const RheodProcess& d, const std::string& ca, const std::string& cert = "",
                       const std::string& key = "") {
  rheo::client::ChannelOptions o;
  o.target = d.address();
  o.token = d.admin_token();
  o.tls_ca_file = ca;
  o.tls_cert_file = cert;
  o.tls_key_file = key;
  v1::DaemonStatus out;
  grpc::ClientContext ctx;
  SetDeadline(ctx, 5s);
  return v1::DaemonService::NewStub(rheo::client::Connect(o, nullptr))
      ->GetStatus(&ctx, v1::GetStatusRequest(), &out);
}

TEST(RheodAuth, TlsAndMutualTls) {
  Pki pki;
  ASSERT_TRUE(pki.ok());
  {
    RheodProcess d(
        {"--http", "off", "--tls-cert", pki("server.pem"), "--tls-key", pki("server.key")});
    ASSERT_TRUE(d.started()) << d.log();
    EXPECT_NE(d.log().find(", TLS)"), std::string::npos) << d.log();
    grpc::Status plain = [&] {
      v1::DaemonStatus out;
      grpc::ClientContext ctx;
      SetDeadline(ctx, 3s);
      return v1::DaemonService::NewStub(d.channel())->GetStatus(&ctx, v1::GetStatusRequest(), &out);
    }();
    EXPECT_FALSE(plain.ok()) << "a plaintext client of a TLS server";
    EXPECT_FALSE(TlsStatus(d, pki("other-ca.pem")).ok()) << "a CA that did not sign the server";
    grpc::Status right = TlsStatus(d, pki("ca.pem"));
    EXPECT_TRUE(right.ok()) << right.error_message();
    EXPECT_EQ(d.Terminate(10s), 0);
  }
  {
    RheodProcess d({"--http", "off", "--tls-cert", pki("server.pem"), "--tls-key",
                    pki("server.key"), "--tls-client-ca", pki("ca.pem")});
    ASSERT_TRUE(d.started()) << d.log();
    EXPECT_NE(d.log().find("mutual TLS"), std::string::npos);
    EXPECT_FALSE(TlsStatus(d, pki("ca.pem")).ok()) << "no client certificate";
    EXPECT_FALSE(TlsStatus(d, pki("ca.pem"), pki("stranger.pem"), pki("stranger.key")).ok())
        << "a client certificate another CA signed";
    grpc::Status mutual = TlsStatus(d, pki("ca.pem"), pki("client.pem"), pki("client.key"));
    EXPECT_TRUE(mutual.ok()) << mutual.error_message();
    EXPECT_EQ(d.Terminate(10s), 0);
  }
}

}  // namespace
}  // namespace rheo::testing
