// Per-token limits against a real rheod, each hit once: the request size of every method,
// expensive calls per second, open streams, concurrent mesh jobs (and cancelling only one's own),
// and a stalled stream ended after the idle timeout. Every refusal is RESOURCE_EXHAUSTED naming
// the limit and the flag that sets it, and one token's use never limits another's.
#include <google/protobuf/descriptor.h>
#include <gtest/gtest.h>

#include <thread>

#include "rheo/v1/auth.grpc.pb.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/device.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheo/v1/scene.grpc.pb.h"
#include "rheod_fixture.h"

namespace rheo::testing {
namespace {

using namespace std::chrono_literals;
namespace pb = google::protobuf;

std::string MakeToken(const RheodProcess& d, const std::string& name, v1::Role role) {
  v1::CreateTokenRequest req;
  req.set_name(name);
  req.set_role(role);
  v1::CreateTokenResponse out;
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  grpc::Status s = v1::AuthService::NewStub(d.channel())->CreateToken(&ctx, req, &out);
  EXPECT_TRUE(s.ok()) << s.error_message();
  return out.token();
}

// An empty request padded with one unknown length-delimited field (number 4000) to `size` bytes:
// every message type parses it, and its size counts.
std::string Padded(size_t size) {
  const std::string tag = "\x82\xfa\x01";  // (4000 << 3) | 2 as a varint
  std::string len;
  size_t body = size - tag.size() - 4;
  for (size_t v = body, i = 0; i < 4; ++i, v >>= 7)
    len += static_cast<char>((v & 0x7f) | (i < 3 ? 0x80 : 0));
  return tag + len + std::string(body, 'x');
}

v1::Limits Limits(const RheodProcess& d) {
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::DaemonStatus st;
  EXPECT_TRUE(v1::DaemonService::NewStub(d.channel())->GetStatus(&ctx, {}, &st).ok());
  return st.limits();
}

TEST(RheodLimits, EveryMethodRefusesARequestOverItsSize) {
  RheodProcess d({"--http", "off", "--device", "network"});
  ASSERT_TRUE(d.started()) << d.log();
  ASSERT_EQ(Padded(1000).size(), 1000u);
  for (const pb::Descriptor* m :
       {v1::DaemonStatus::descriptor(), v1::Frame::descriptor(), v1::Scene::descriptor(),
        v1::Object::descriptor(), v1::DeviceStatus::descriptor(), v1::Identity::descriptor()})
    ASSERT_NE(m, nullptr);  // links each file's descriptors into this test's pool
  int checked = 0;
  for (const char* service :
       {"rheo.v1.DaemonService", "rheo.v1.FrameService", "rheo.v1.SceneService",
        "rheo.v1.ObjectService", "rheo.v1.DeviceService", "rheo.v1.AuthService"}) {
    const pb::ServiceDescriptor* s =
        pb::DescriptorPool::generated_pool()->FindServiceByName(service);
    ASSERT_NE(s, nullptr) << service;
    for (int i = 0; i < s->method_count(); ++i) {
      const std::string name = s->method(i)->name();
      const std::string path = "/" + std::string(service) + "/" + name;
      // Sketches (and their photos) may be 64 MB; every other request 64 KB; a tool pose 4 KB.
      const bool sketch = name == "CreateObject" || name == "ExtractContour";
      const size_t limit = sketch ? 64u << 20 : name == "ToolStream" ? 4096 : 65536;
      grpc::Status over = CallRaw(d.channel(), path, Padded(limit + 1024), 30s);
      EXPECT_EQ(over.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED)
          << path << ": " << over.error_message();
      if (!sketch) {
        EXPECT_NE(over.error_message().find(name + ": the request is"), std::string::npos)
            << over.error_message();
        EXPECT_NE(over.error_message().find("the limit for this method is " +
                                            std::string(limit == 4096 ? "4.0 KB" : "64.0 KB")),
                  std::string::npos)
            << over.error_message();
        // Just under the limit passes this check (whatever the handler then says).
        grpc::Status under = CallRaw(d.channel(), path, Padded(limit - 64), 30s);
        EXPECT_EQ(under.error_message().find("the limit for this method"), std::string::npos)
            << path << ": " << under.error_message();
      }
      ++checked;
    }
  }
  EXPECT_GE(checked, 27);
  ASSERT_EQ(d.Terminate(10s), 0) << d.log();
}

TEST(RheodLimits, ExpensiveCallsPerSecondPerToken) {
  RheodProcess d({"--http", "off", "--limit-calls", "2"});  // a burst of 4, then 2 per second
  ASSERT_TRUE(d.started()) << d.log();
  const std::string rita = MakeToken(d, "rita", v1::ROLE_VIEWER);
  const std::string sam = MakeToken(d, "sam", v1::ROLE_VIEWER);
  auto export_missing = [&](const std::string& token) {
    v1::ExportObjectRequest req;
    req.set_id("no-such-object");
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    auto reader = v1::ObjectService::NewStub(d.channel(token))->ExportObject(&ctx, req);
    v1::ExportChunk c;
    while (reader->Read(&c)) {
    }
    return reader->Finish();
  };
  int served = 0;
  grpc::Status refused;
  for (int i = 0; i < 8; ++i) {
    grpc::Status s = export_missing(rita);
    if (s.error_code() == grpc::StatusCode::NOT_FOUND)
      ++served;
    else
      refused = s;
  }
  EXPECT_GE(served, 4);
  EXPECT_LE(served, 6);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << refused.error_message();
  for (const char* words : {"ExportObject: token 'rita'", "2 calls per second to this method",
                            "--limit-calls", "retry in"})
    EXPECT_NE(refused.error_message().find(words), std::string::npos) << refused.error_message();
  // Another token is not limited by rita's calls; rita is served again once the bucket refills.
  EXPECT_EQ(export_missing(sam).error_code(), grpc::StatusCode::NOT_FOUND);
  std::this_thread::sleep_for(700ms);
  EXPECT_EQ(export_missing(rita).error_code(), grpc::StatusCode::NOT_FOUND);
  const v1::Limits lim = Limits(d);
  EXPECT_EQ(lim.calls_per_s(), 2.0);
  EXPECT_GE(lim.refused_calls(), 2u);
  ASSERT_EQ(d.Terminate(10s), 0) << d.log();
}

TEST(RheodLimits, OpenStreamsPerToken) {
  RheodProcess d({"--http", "off", "--limit-streams", "2"});
  ASSERT_TRUE(d.started()) << d.log();
  const std::string sue = MakeToken(d, "sue", v1::ROLE_VIEWER);
  const std::string tom = MakeToken(d, "tom", v1::ROLE_VIEWER);
  struct Watch {
    grpc::ClientContext ctx;
    std::unique_ptr<grpc::ClientReader<v1::Frame>> reader;
    v1::Frame first;
    bool got = false;
  };
  auto watch = [&](const std::string& token) {
    auto w = std::make_unique<Watch>();
    SetDeadline(w->ctx, 60s);
    v1::WatchFramesRequest req;
    req.set_rate_hz(10);
    w->reader = v1::FrameService::NewStub(d.channel(token))->WatchFrames(&w->ctx, req);
    w->got = w->reader->Read(&w->first);
    return w;
  };
  auto a = watch(sue), b = watch(sue);
  ASSERT_TRUE(a->got && b->got);
  auto c = watch(sue);
  EXPECT_FALSE(c->got);
  grpc::Status s = c->reader->Finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  for (const char* words : {"WatchFrames: token 'sue' has 2 streams open", "--limit-streams"})
    EXPECT_NE(s.error_message().find(words), std::string::npos) << s.error_message();
  auto t = watch(tom);
  EXPECT_TRUE(t->got);
  // Closing one of sue's streams gives its place back.
  a->ctx.TryCancel();
  a->reader->Finish();
  bool again = false;
  for (int i = 0; i < 50 && !again; ++i) {
    auto e = watch(sue);
    again = e->got;
    e->ctx.TryCancel();
    e->reader->Finish();
    if (!again) std::this_thread::sleep_for(100ms);
  }
  EXPECT_TRUE(again);
  EXPECT_GE(Limits(d).refused_streams(), 1u);
  for (Watch* w : {b.get(), t.get()}) {
    w->ctx.TryCancel();
    w->reader->Finish();
  }
  ASSERT_EQ(d.Terminate(10s), 0) << d.log();
}

TEST(RheodLimits, MeshJobsPerTokenAndOnlyTheOwnerOrAnAdminCancels) {
  RheodProcess d({"--http", "off", "--limit-jobs", "1", "--max-jobs", "8"});
  ASSERT_TRUE(d.started()) << d.log();
  const std::string ann = MakeToken(d, "ann", v1::ROLE_OPERATOR);
  const std::string bob = MakeToken(d, "bob", v1::ROLE_OPERATOR);
  v1::CreateObjectRequest bomb;
  bomb.mutable_sketch()->set_strokes_json(DenseStrokeBomb());
  struct Build {
    grpc::ClientContext ctx;
    std::unique_ptr<grpc::ClientReader<v1::CreateObjectProgress>> reader;
    v1::CreateObjectProgress first;
    bool got = false;
  };
  auto build = [&](const std::string& token) {
    auto b = std::make_unique<Build>();
    SetDeadline(b->ctx, 120s);
    b->reader = v1::ObjectService::NewStub(d.channel(token))->CreateObject(&b->ctx, bomb);
    b->got = b->reader->Read(&b->first);
    return b;
  };
  auto cancel = [&](const std::string& token, const std::string& job) {
    v1::CancelJobRequest req;
    req.set_job_id(job);
    v1::CancelJobResponse out;
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    return v1::ObjectService::NewStub(d.channel(token))->CancelJob(&ctx, req, &out);
  };
  auto finish = [](Build& b) {
    v1::CreateObjectProgress p;
    while (b.reader->Read(&p)) {
    }
    return b.reader->Finish();
  };
  auto first = build(ann);
  ASSERT_TRUE(first->got);
  ASSERT_EQ(first->first.stage(), "queued");
  // A second build by ann while the first runs: refused, naming the limit.
  auto second = build(ann);
  EXPECT_FALSE(second->got);
  grpc::Status s = second->reader->Finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  for (const char* words : {"token 'ann' has 1 mesh jobs running", "--limit-jobs"})
    EXPECT_NE(s.error_message().find(words), std::string::npos) << s.error_message();
  // bob may build beside her, but not cancel her job; she may, and an admin may cancel bob's.
  auto bobs = build(bob);
  ASSERT_TRUE(bobs->got);
  grpc::Status denied = cancel(bob, first->first.job_id());
  EXPECT_EQ(denied.error_code(), grpc::StatusCode::PERMISSION_DENIED) << denied.error_message();
  EXPECT_NE(denied.error_message().find("belongs to token 'ann'"), std::string::npos)
      << denied.error_message();
  EXPECT_TRUE(cancel(ann, first->first.job_id()).ok());
  EXPECT_TRUE(cancel(d.admin_token(), bobs->first.job_id()).ok());
  EXPECT_EQ(finish(*first).error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_EQ(finish(*bobs).error_code(), grpc::StatusCode::CANCELLED);
  // Her slot is free again once her build ended.
  bool again = false;
  for (int i = 0; i < 50 && !again; ++i) {
    auto b = build(ann);
    again = b->got;
    if (again) {
      EXPECT_TRUE(cancel(ann, b->first.job_id()).ok());
    }
    finish(*b);
    if (!again) std::this_thread::sleep_for(100ms);
  }
  EXPECT_TRUE(again);
  EXPECT_GE(Limits(d).refused_jobs(), 1u);
  ASSERT_EQ(d.Terminate(10s), 0) << d.log();
}

TEST(RheodLimits, AStalledStreamEndsAfterTheIdleTimeoutAndABusyOneStays) {
  RheodProcess d(
      {"--http", "off", "--device", "network", "--stream-idle", "1", "--watchdog-timeout", "100"});
  ASSERT_TRUE(d.started()) << d.log();
  auto dev = v1::DeviceService::NewStub(d.channel());
  v1::Lease lease;
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::AcquireLeaseRequest req;
    req.set_client_name("idle-test");
    req.set_duration_s(120);
    ASSERT_TRUE(dev->AcquireLease(&ctx, req, &lease).ok());
  }
  // A tool stream that sends a pose every 200 ms for 2.5 s is not idle.
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx, 30s);
    auto stream = dev->ToolStream(&ctx);
    v1::ToolInput in;
    in.set_lease_id(lease.lease_id());
    in.mutable_pose()->mutable_position()->set_y(0.2);
    v1::ToolFeedback fb;
    for (int i = 0; i < 12; ++i) {
      ASSERT_TRUE(stream->Write(in)) << i;
      ASSERT_TRUE(stream->Read(&fb)) << i;
      std::this_thread::sleep_for(200ms);
    }
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
  }
  EXPECT_EQ(Limits(d).idle_streams_ended(), 0u);
  // One that opens and sends nothing is ended within the timeout and the reaper's second.
  const auto t0 = std::chrono::steady_clock::now();
  grpc::ClientContext ctx;
  SetDeadline(ctx, 30s);
  auto stream = dev->ToolStream(&ctx);
  v1::ToolFeedback fb;
  EXPECT_FALSE(stream->Read(&fb));
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  grpc::Status s = stream->Finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::CANCELLED) << s.error_message();
  EXPECT_GE(took, 0.9);
  EXPECT_LE(took, 10.0);  // 1 s idle + the reaper's period; slack for sanitizer builds
  const v1::Limits lim = Limits(d);
  EXPECT_EQ(lim.idle_streams_ended(), 1u);
  EXPECT_EQ(lim.stream_idle_s(), 1.0);
  EXPECT_TRUE(d.WaitForLog("idle for more than 1 s (--stream-idle)", 5s)) << d.log();
  ASSERT_EQ(d.Terminate(10s), 0) << d.log();
}

}  // namespace
}  // namespace rheo::testing
