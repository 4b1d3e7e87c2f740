// Integration tests against a real rheod process on loopback.
#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "grpc/health/v1/health.grpc.pb.h"
#include "grpc/reflection/v1alpha/reflection.grpc.pb.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/device.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheo/v1/scene.grpc.pb.h"
#include "rheod_fixture.h"

namespace rheo::testing {
namespace {

using namespace std::chrono_literals;

class RheodTest : public ::testing::Test {
 protected:
  void SetUp() override {
    daemon_ = std::make_unique<RheodProcess>();
    ASSERT_TRUE(daemon_->started()) << "rheod did not start; its log:\n" << daemon_->log();
  }
  std::unique_ptr<RheodProcess> daemon_;
};

TEST_F(RheodTest, HealthIsServing) {
  auto stub = grpc::health::v1::Health::NewStub(daemon_->channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  grpc::health::v1::HealthCheckResponse r;
  ASSERT_TRUE(stub->Check(&ctx, {}, &r).ok());
  EXPECT_EQ(r.status(), grpc::health::v1::HealthCheckResponse::SERVING);
}

TEST_F(RheodTest, ReflectionListsEveryService) {
  auto stub = grpc::reflection::v1alpha::ServerReflection::NewStub(daemon_->channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  auto stream = stub->ServerReflectionInfo(&ctx);
  grpc::reflection::v1alpha::ServerReflectionRequest req;
  req.set_list_services("*");
  ASSERT_TRUE(stream->Write(req));
  grpc::reflection::v1alpha::ServerReflectionResponse resp;
  ASSERT_TRUE(stream->Read(&resp));
  std::set<std::string> names;
  for (const auto& s : resp.list_services_response().service()) names.insert(s.name());
  for (const char* want :
       {"rheo.v1.DaemonService", "rheo.v1.FrameService", "rheo.v1.SceneService",
        "rheo.v1.ObjectService", "rheo.v1.DeviceService", "rheo.v1.RecordingService"})
    EXPECT_TRUE(names.count(want)) << want << " missing from reflection";

  // A generic client can also fetch the schema of a service.
  req.set_file_containing_symbol("rheo.v1.DaemonService");
  ASSERT_TRUE(stream->Write(req));
  ASSERT_TRUE(stream->Read(&resp));
  EXPECT_GT(resp.file_descriptor_response().file_descriptor_proto_size(), 0);
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

TEST_F(RheodTest, LoopTicksAdvanceAndStatisticsAreReported) {
  auto daemon = rheo::v1::DaemonService::NewStub(daemon_->channel());
  auto frames = rheo::v1::FrameService::NewStub(daemon_->channel());
  rheo::v1::DaemonStatus first, second;
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(daemon->GetStatus(&ctx, {}, &first).ok());
  }
  // Two frames at 100 Hz guarantee the loop has moved on by at least one tick.
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    rheo::v1::WatchFramesRequest req;
    req.set_rate_hz(100);
    req.set_max_frames(2);
    auto reader = frames->WatchFrames(&ctx, req);
    rheo::v1::Frame f1, f2;
    ASSERT_TRUE(reader->Read(&f1));
    ASSERT_TRUE(reader->Read(&f2));
    EXPECT_GT(f2.stamp().tick(), f1.stamp().tick());
    EXPECT_GT(f2.stamp().sim_time(), f1.stamp().sim_time());
    EXPECT_TRUE(reader->Finish().ok());
  }
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(daemon->GetStatus(&ctx, {}, &second).ok());
  }
  EXPECT_GT(second.loop().ticks(), first.loop().ticks());
  EXPECT_DOUBLE_EQ(second.loop().rate_hz(), 1000.0);
  const auto& p = second.loop().period();
  EXPECT_GT(p.count(), 0u);
  EXPECT_GT(p.p50_us(), 0.0);
  EXPECT_LE(p.p50_us(), p.p99_us());
  EXPECT_LE(p.p99_us(), p.p999_us());
  EXPECT_LE(p.p999_us(), p.max_us());
  EXPECT_FALSE(second.version().empty());
  EXPECT_EQ(second.device(), rheo::v1::DEVICE_KIND_NONE);
}

TEST_F(RheodTest, PauseStopsSimulatedTimeAndResumeRestartsIt) {
  auto scene = rheo::v1::SceneService::NewStub(daemon_->channel());
  rheo::v1::ControlResponse r1, r2, r3;
  rheo::v1::ControlRequest req;
  req.set_command(rheo::v1::RUN_COMMAND_PAUSE);
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(scene->Control(&ctx, req, &r1).ok());
  }
  EXPECT_TRUE(r1.paused());
  req.set_command(rheo::v1::RUN_COMMAND_STEP);
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(scene->Control(&ctx, req, &r2).ok());
  }
  EXPECT_NEAR(r2.sim_time() - r1.sim_time(), 0.001, 1e-9) << "STEP advances exactly one tick";
  req.set_command(rheo::v1::RUN_COMMAND_RESET);
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(scene->Control(&ctx, req, &r3).ok());
  }
  EXPECT_EQ(r3.sim_time(), 0.0);
  EXPECT_TRUE(r3.paused());
  req.set_command(rheo::v1::RUN_COMMAND_RESUME);
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    ASSERT_TRUE(scene->Control(&ctx, req, &r3).ok());
  }
  EXPECT_FALSE(r3.paused());
  // Stepping a running scene is refused with a reason.
  req.set_command(rheo::v1::RUN_COMMAND_STEP);
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  grpc::Status s = scene->Control(&ctx, req, &r3);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("pause"), std::string::npos);
}

TEST_F(RheodTest, BadInputGetsAClearErrorAndTheDaemonKeepsRunning) {
  auto frames = rheo::v1::FrameService::NewStub(daemon_->channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  rheo::v1::WatchFramesRequest req;
  req.set_rate_hz(5000);
  auto reader = frames->WatchFrames(&ctx, req);
  rheo::v1::Frame f;
  EXPECT_FALSE(reader->Read(&f));
  grpc::Status s = reader->Finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("rate_hz"), std::string::npos);

  auto scene = rheo::v1::SceneService::NewStub(daemon_->channel());
  grpc::ClientContext ctx2;
  SetDeadline(ctx2);
  rheo::v1::ControlResponse r;
  EXPECT_EQ(scene->Control(&ctx2, rheo::v1::ControlRequest(), &r).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);

  auto health = grpc::health::v1::Health::NewStub(daemon_->channel());
  grpc::ClientContext ctx3;
  SetDeadline(ctx3);
  grpc::health::v1::HealthCheckResponse h;
  ASSERT_TRUE(health->Check(&ctx3, {}, &h).ok());
  EXPECT_EQ(h.status(), grpc::health::v1::HealthCheckResponse::SERVING);
}

TEST_F(RheodTest, DeviceCallsWithoutADeviceSaySo) {
  auto device = rheo::v1::DeviceService::NewStub(daemon_->channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  rheo::v1::DeviceStatus st;
  ASSERT_TRUE(device->GetDeviceStatus(&ctx, {}, &st).ok());
  EXPECT_EQ(st.kind(), rheo::v1::DEVICE_KIND_NONE);
  grpc::ClientContext ctx2;
  SetDeadline(ctx2);
  rheo::v1::CalibrateResponse cr;
  grpc::Status s = device->Calibrate(&ctx2, {}, &cr);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("--device"), std::string::npos);
}

TEST_F(RheodTest, SigtermEndsOpenStreamsWithAStatusAndExitsCleanly) {
  auto frames = rheo::v1::FrameService::NewStub(daemon_->channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx, 30s);
  rheo::v1::WatchFramesRequest req;
  req.set_rate_hz(50);
  auto reader = frames->WatchFrames(&ctx, req);
  rheo::v1::Frame f;
  ASSERT_TRUE(reader->Read(&f));  // the stream is open
  // The daemon's own shutdown (signal to "stopped" log line) must take under 2 s; process exit
  // after that only adds the sanitizers' leak check, so it gets a looser bound.
  auto t0 = std::chrono::steady_clock::now();
  daemon_->Signal(SIGTERM);
  ASSERT_TRUE(daemon_->WaitForLog("stopped after", 10s)) << daemon_->log();
  auto took =
      std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - t0);
  EXPECT_LT(took.count(), 2000) << "shutdown must finish within 2 s";
  EXPECT_EQ(daemon_->WaitForExit(30s), 0) << daemon_->log();
  while (reader->Read(&f)) {
  }
  grpc::Status s = reader->Finish();
  EXPECT_FALSE(s.ok());
  EXPECT_TRUE(s.error_code() == grpc::StatusCode::UNAVAILABLE ||
              s.error_code() == grpc::StatusCode::CANCELLED)
      << s.error_code() << " " << s.error_message();
  EXPECT_NE(daemon_->log().find("shutting down"), std::string::npos);
}

TEST(RheodStartup, SecondDaemonOnTheSameDataDirIsRefused) {
  RheodProcess first;
  ASSERT_TRUE(first.started()) << first.log();
  RunResult r = RunProgram({RHEOD_PATH, "--listen", "127.0.0.1:0", "--data-dir", first.data_dir()});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("in use by another rheod"), std::string::npos) << r.err;
}

// The size of the next frame on the wire [bytes].
size_t FrameBytes(RheodProcess& d) {
  auto frames = v1::FrameService::NewStub(d.channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx, 10s);
  v1::WatchFramesRequest w;
  w.set_rate_hz(30);
  auto reader = frames->WatchFrames(&ctx, w);
  v1::Frame f;
  size_t bytes = 0;
  if (reader->Read(&f)) bytes = f.ByteSizeLong();
  ctx.TryCancel();
  reader->Finish();
  return bytes;
}

TEST(RheodLimits, HugeStringsAreRefusedWithAShortMessageAndFramesStaySmall) {
  RheodProcess d({"--device", "network"});
  ASSERT_TRUE(d.started()) << d.log();
  const size_t before = FrameBytes(d);
  ASSERT_GT(before, 0u);
  auto dev = v1::DeviceService::NewStub(d.channel());
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    // Past the method's request size (64 KB): refused before any field is looked at.
    v1::AcquireLeaseRequest req;
    req.set_client_name(std::string(5u << 20, 'n'));
    v1::Lease lease;
    grpc::Status s = dev->AcquireLease(&ctx, req, &lease);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message().size();
    EXPECT_LT(s.error_message().size(), 200u);
    EXPECT_NE(s.error_message().find("AcquireLease: the request is 5.0 MB"), std::string::npos)
        << s.error_message();
  }
  {
    // Within it, a string past its field's limit.
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::AcquireLeaseRequest req;
    req.set_client_name(std::string(20000, 'n'));
    v1::Lease lease;
    grpc::Status s = dev->AcquireLease(&ctx, req, &lease);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << s.error_message().size();
    EXPECT_LT(s.error_message().size(), 200u);
    EXPECT_NE(s.error_message().find("client_name"), std::string::npos) << s.error_message();
    EXPECT_NE(s.error_message().find("200"), std::string::npos) << s.error_message();
  }
  auto objects = v1::ObjectService::NewStub(d.channel());
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::GetObjectRequest req;
    req.set_id(std::string(30000, '\x01'));
    v1::Object o;
    grpc::Status s = objects->GetObject(&ctx, req, &o);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << s.error_message().size();
    EXPECT_LT(s.error_message().size(), 200u);
    EXPECT_NE(s.error_message().find("id is 30000 bytes"), std::string::npos) << s.error_message();
    EXPECT_NE(s.error_message().find("\\x01"), std::string::npos) << s.error_message();
  }
  {
    // Nested: a parameter name inside AddToScene.
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    auto scene = v1::SceneService::NewStub(d.channel());
    v1::AddToSceneRequest req;
    req.set_object_id("x");
    req.add_overrides()->set_name(std::string(40000, 'k'));
    v1::SceneObject so;
    grpc::Status s = scene->AddToScene(&ctx, req, &so);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_LT(s.error_message().size(), 200u);
    EXPECT_NE(s.error_message().find("overrides[0].name"), std::string::npos) << s.error_message();
  }
  {
    // An unknown id is quoted short: NOT_FOUND, not a transport error.
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::GetObjectRequest req;
    req.set_id(std::string(100, 'z'));
    v1::Object o;
    grpc::Status s = objects->GetObject(&ctx, req, &o);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::NOT_FOUND);
    EXPECT_LT(s.error_message().size(), 100u) << s.error_message();
  }
  // A fitting name is granted, and the frames do not grow by more than it.
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::AcquireLeaseRequest req;
    req.set_client_name("alice");
    v1::Lease lease;
    EXPECT_TRUE(dev->AcquireLease(&ctx, req, &lease).ok());
  }
  const size_t after = FrameBytes(d);
  EXPECT_LT(after, before + 64) << before << " -> " << after << " bytes";
}

TEST(RheodStartup, SecondDaemonOnTheSamePortIsRefused) {
  RheodProcess first;
  ASSERT_TRUE(first.started()) << first.log();
  // Its own data directory, so only the port is shared.
  RheodProcess second({"--listen", first.address()});
  EXPECT_FALSE(second.started()) << second.log();
  EXPECT_EQ(second.WaitForExit(10s), 1) << second.log();
  EXPECT_NE(second.log().find("cannot listen on " + first.address()), std::string::npos)
      << second.log();
  // The first one still serves.
  auto stub = grpc::health::v1::Health::NewStub(first.channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  grpc::health::v1::HealthCheckResponse r;
  EXPECT_TRUE(stub->Check(&ctx, {}, &r).ok());
}

// The TCP ports a process listens on, from the socket inodes of /proc/PID/fd and the LISTEN
// rows (state 0A) of /proc/net/tcp and tcp6.
std::vector<int> ListeningPorts(int pid) {
  std::set<std::string> inodes;
  std::error_code ec;
  for (const auto& e :
       std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec)) {
    std::error_code lec;
    const std::string target = std::filesystem::read_symlink(e.path(), lec).string();
    if (target.rfind("socket:[", 0) == 0) inodes.insert(target.substr(8, target.size() - 9));
  }
  std::vector<int> ports;
  for (const char* table : {"/proc/net/tcp", "/proc/net/tcp6"}) {
    std::ifstream in(table);
    std::string line;
    std::getline(in, line);  // header
    while (std::getline(in, line)) {
      std::istringstream row(line);
      std::string sl, local, remote, state, queues, timer, retr, uid, timeout, inode;
      row >> sl >> local >> remote >> state >> queues >> timer >> retr >> uid >> timeout >> inode;
      if (state != "0A" || !inodes.count(inode)) continue;
      ports.push_back(std::stoi(local.substr(local.rfind(':') + 1), nullptr, 16));
    }
  }
  return ports;
}

TEST(RheodStartup, PortZeroOpensExactlyTheLoggedPorts) {
  // gRPC and the studio's gateway, each on the port its log line names, and nothing else.
  RheodProcess d;
  ASSERT_TRUE(d.started()) << d.log();
  const int logged = std::stoi(d.address().substr(d.address().rfind(':') + 1));
  ASSERT_GT(d.http_port(), 0) << d.log();
  std::vector<int> ports = ListeningPorts(d.pid());
  std::sort(ports.begin(), ports.end());
  std::string listed;
  for (int p : ports) listed += std::to_string(p) + " ";
  std::vector<int> expected = {logged, d.http_port()};
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(ports, expected) << "listening ports: " << listed << "; logged " << logged << " and "
                             << d.http_port();
  // With the studio off, only the gRPC port.
  RheodProcess off({"--http", "off"});
  ASSERT_TRUE(off.started()) << off.log();
  const std::vector<int> only = ListeningPorts(off.pid());
  ASSERT_EQ(only.size(), 1u);
  EXPECT_EQ(only[0], std::stoi(off.address().substr(off.address().rfind(':') + 1)));
}

TEST(RheodStartup, NonLoopbackListenWithInsecureWarnsWhatIsExposed) {
  // Without --insecure it is refused (rheod_auth_test); with it, served and warned.
  RheodProcess d({"--listen", "0.0.0.0:0", "--insecure"});
  ASSERT_TRUE(d.WaitForLog("listening on", 30s)) << d.log();
  ASSERT_TRUE(d.WaitForLog("non-loopback address", 5s)) << d.log();
  const std::string log = d.log();
  EXPECT_NE(log.find("--insecure: --listen 0.0.0.0:0 serve plaintext"), std::string::npos) << log;
  EXPECT_NE(log.find("tokens, sketches and frames cross the network readable"), std::string::npos)
      << log;
  EXPECT_EQ(d.Terminate(10s), 0) << d.log();
  // Loopback stays quiet.
  RheodProcess local;
  ASSERT_TRUE(local.started()) << local.log();
  EXPECT_EQ(local.log().find("non-loopback address"), std::string::npos) << local.log();
}

TEST(RheodStartup, BadFlagsAreRefusedWithAMessage) {
  RunResult r = RunProgram({RHEOD_PATH, "--device", "teleporter"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--device"), std::string::npos) << r.err;
}

TEST(RheodStartup, ConfigFileSetsFlags) {
  RheodProcess probe;  // only for a temporary folder that is cleaned up
  ASSERT_TRUE(probe.started());
  std::string cfg = probe.data_dir() + "/rheod.toml";
  FILE* f = fopen(cfg.c_str(), "w");
  ASSERT_NE(f, nullptr);
  fprintf(f, "rate = 500\nlog-level = \"debug\"\n");
  fclose(f);
  RheodProcess configured({"--config", cfg});
  ASSERT_TRUE(configured.started()) << configured.log();
  auto daemon = rheo::v1::DaemonService::NewStub(configured.channel());
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  rheo::v1::DaemonStatus st;
  ASSERT_TRUE(daemon->GetStatus(&ctx, {}, &st).ok());
  EXPECT_DOUBLE_EQ(st.loop().rate_hz(), 500.0);
}

// rheoctl is a separate process talking to the daemon.
TEST_F(RheodTest, RheoctlStatusWatchAndHealth) {
  RunResult st = RunProgram({RHEOCTL_PATH, "--data-dir", daemon_->data_dir(), "--server",
                             daemon_->address(), "status", "--json"});
  ASSERT_EQ(st.exit_code, 0) << st.err;
  auto j = nlohmann::json::parse(st.out);
  EXPECT_GT(std::stoull(j["loop"]["ticks"].get<std::string>()), 0u);

  RunResult human = RunProgram(
      {RHEOCTL_PATH, "--data-dir", daemon_->data_dir(), "--server", daemon_->address(), "status"});
  ASSERT_EQ(human.exit_code, 0) << human.err;
  EXPECT_NE(human.out.find("p99.9"), std::string::npos);

  RunResult w =
      RunProgram({RHEOCTL_PATH, "--data-dir", daemon_->data_dir(), "--server", daemon_->address(),
                  "watch", "--rate", "200", "--count", "3", "--json"});
  ASSERT_EQ(w.exit_code, 0) << w.err;
  int lines = 0;
  std::istringstream in(w.out);
  for (std::string line; std::getline(in, line);) {
    auto fj = nlohmann::json::parse(line);
    EXPECT_TRUE(fj.contains("stamp"));
    ++lines;
  }
  EXPECT_EQ(lines, 3);

  // Without --json: one line a frame for people, no JSON.
  RunResult summary = RunProgram({RHEOCTL_PATH, "--data-dir", daemon_->data_dir(), "--server",
                                  daemon_->address(), "watch", "--rate", "200", "--count", "2"});
  ASSERT_EQ(summary.exit_code, 0) << summary.err;
  std::istringstream sin(summary.out);
  lines = 0;
  for (std::string line; std::getline(sin, line); ++lines) {
    EXPECT_EQ(line.rfind("tick ", 0), 0u) << line;
    EXPECT_NE(line.find(" objects"), std::string::npos) << line;
    EXPECT_EQ(line.find('{'), std::string::npos) << line;
  }
  EXPECT_EQ(lines, 2);

  RunResult h = RunProgram(
      {RHEOCTL_PATH, "--data-dir", daemon_->data_dir(), "--server", daemon_->address(), "health"});
  EXPECT_EQ(h.exit_code, 0);
  EXPECT_NE(h.out.find("SERVING"), std::string::npos);

  RunResult bad = RunProgram({RHEOCTL_PATH, "--data-dir", daemon_->data_dir(), "--server",
                              daemon_->address(), "watch", "--rate", "0.5", "--count", "1"});
  EXPECT_EQ(bad.exit_code, static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT));
  EXPECT_NE(bad.err.find("INVALID_ARGUMENT"), std::string::npos) << bad.err;
}

TEST(RheoctlAlone, UnreachableServerExitsNonZeroWithTheStatus) {
  // Port 1 on loopback has no listener in a test sandbox.
  RunResult r = RunProgram({RHEOCTL_PATH, "--server", "127.0.0.1:1", "--timeout", "1", "status"});
  EXPECT_EQ(r.exit_code, static_cast<int>(grpc::StatusCode::UNAVAILABLE)) << r.err;
  EXPECT_NE(r.err.find("UNAVAILABLE"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace rheo::testing
