// Work a client asks for stops when the client or its deadline says so: CancelJob and the job's
// deadline free the worker's core within 100 ms even inside the sketch stage, ExtractContour runs
// on the worker pool under the client's deadline, and degenerate solids are refused.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include "rheo/v1/objects.grpc.pb.h"
#include "rheod_fixture.h"

namespace rheo::testing {
namespace {

using namespace std::chrono_literals;

// The issue's bound: a cancel frees the core within 100 ms. A sanitizer build runs the polled
// loops and the stream's teardown several times slower (166 ms seen under ASan with the other
// tests on both cores); the optimised stage holds the 100 ms.
constexpr double kCancelLatencyMs = kSanitizerBuild ? 500.0 : 100.0;
using Clock = std::chrono::steady_clock;
// A worker still running burns a core: ~0.3 s of CPU per 300 ms window. A stopped one leaves the
// idle loop's share plus noise: the 1 kHz loop, a stream's teardown and the clock-tick
// granularity of /proc (10 ms) gave 0.06 s against an idle 0.01 s on two busy cores. A third of a
// core separates the two cases with room on both sides.
constexpr double kStoppedCpuSlack = 0.1;

// CPU time the process has used [s] (user + system, from /proc/PID/stat).
double ProcessCpu(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::istringstream rest(text.substr(text.rfind(')') + 2));
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {  // fields 3.. after "pid (comm) "
    if (i == 14) utime = std::stoull(field);
    if (i == 15) stime = std::stoull(field);
  }
  return double(utime + stime) / double(sysconf(_SC_CLK_TCK));
}

double CpuOver(int pid, std::chrono::milliseconds window) {
  const double a = ProcessCpu(pid);
  std::this_thread::sleep_for(window);
  return ProcessCpu(pid) - a;
}

TEST(RheodCancel, CancelJobFreesTheCoreInsideTheSketchStage) {
  RheodProcess d({"--workers", "1"});
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  const double idle = CpuOver(d.pid(), 300ms);

  v1::CreateObjectRequest req;
  req.mutable_sketch()->set_strokes_json(DenseStrokeBomb());
  grpc::ClientContext ctx;
  SetDeadline(ctx, 60s);
  auto reader = stub->CreateObject(&ctx, req);
  v1::CreateObjectProgress p;
  ASSERT_TRUE(reader->Read(&p));
  ASSERT_EQ(p.stage(), "queued");
  const std::string job_id = p.job_id();
  const double busy = CpuOver(d.pid(), 200ms);
  EXPECT_GT(busy, 0.1) << "the job should keep a core busy";

  grpc::ClientContext cctx;
  SetDeadline(cctx);
  v1::CancelJobRequest creq;
  creq.set_job_id(job_id);
  v1::CancelJobResponse cres;
  const auto cancelled_at = Clock::now();
  ASSERT_TRUE(stub->CancelJob(&cctx, creq, &cres).ok());
  EXPECT_TRUE(cres.cancelled());
  while (reader->Read(&p)) {
  }
  const grpc::Status s = reader->Finish();
  const double latency_ms =
      std::chrono::duration<double, std::milli>(Clock::now() - cancelled_at).count();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::CANCELLED) << s.error_message();
  EXPECT_NE(s.error_message().find("cancelled"), std::string::npos) << s.error_message();
  EXPECT_LT(latency_ms, kCancelLatencyMs) << "from CancelJob to the end of the stream";
  const double after = CpuOver(d.pid(), 300ms);
  EXPECT_LT(after, idle + kStoppedCpuSlack)
      << "CPU over 300 ms: idle " << idle << " s, with the job " << busy
      << " s in 200 ms, after the cancel " << after << " s";
  std::printf(
      "cancel: stream ended %.1f ms after CancelJob; CPU per 300 ms idle %.3f s, "
      "after cancel %.3f s (job: %.3f s per 200 ms)\n",
      latency_ms, idle, after, busy);
}

TEST(RheodCancel, JobDeadlineFreesTheCoreInsideTheSketchStage) {
  RheodProcess d({"--workers", "1"});
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  const double idle = CpuOver(d.pid(), 300ms);
  v1::CreateObjectRequest req;
  req.mutable_sketch()->set_strokes_json(DenseStrokeBomb());
  grpc::ClientContext ctx;
  SetDeadline(ctx, 400ms);
  const auto start = Clock::now();
  auto reader = stub->CreateObject(&ctx, req);
  v1::CreateObjectProgress p;
  while (reader->Read(&p)) {
  }
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  // The job's own deadline is the client's: by 100 ms past it (the sanitizer builds' bound
  // past it there) the worker has stopped.
  std::this_thread::sleep_until(start + 400ms +
                                std::chrono::milliseconds(static_cast<int>(kCancelLatencyMs)));
  const double after = CpuOver(d.pid(), 300ms);
  EXPECT_LT(after, idle + kStoppedCpuSlack)
      << "idle " << idle << " s, after the deadline " << after << " s";
}

TEST(RheodCancel, ExtractContourStopsAtTheClientsDeadline) {
  RheodProcess d({"--workers", "1"});
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  const double idle = CpuOver(d.pid(), 300ms);
  v1::ExtractContourRequest req;
  req.mutable_sketch()->set_strokes_json(DenseStrokeBomb());
  grpc::ClientContext ctx;
  SetDeadline(ctx, 300ms);
  v1::ContourReport out;
  const auto start = Clock::now();
  const grpc::Status s = stub->ExtractContour(&ctx, req, &out);
  const double took_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED) << s.error_message();
  EXPECT_LT(took_ms, 1000.0);
  std::this_thread::sleep_until(start + 300ms +
                                std::chrono::milliseconds(static_cast<int>(kCancelLatencyMs)));
  const double after = CpuOver(d.pid(), 300ms);
  EXPECT_LT(after, idle + kStoppedCpuSlack)
      << "idle " << idle << " s, after the deadline " << after << " s";
  std::printf("ExtractContour: %s after %.1f ms; CPU per 300 ms idle %.3f s, after %.3f s\n",
              s.error_message().c_str(), took_ms, idle, after);

  // A small sketch still comes back, through the pool.
  v1::ExtractContourRequest ok;
  std::string circle = "{\"width\":512,\"height\":512,\"strokes\":[[";
  for (int i = 0; i <= 64; ++i) {
    char b[64];
    std::snprintf(b, sizeof b, "%s[%.2f,%.2f]", i ? "," : "", 256 + 150 * std::cos(i * M_PI / 32),
                  256 + 150 * std::sin(i * M_PI / 32));
    circle += b;
  }
  ok.mutable_sketch()->set_strokes_json(circle + "]]}");
  grpc::ClientContext octx;
  SetDeadline(octx);
  const grpc::Status os = stub->ExtractContour(&octx, ok, &out);
  ASSERT_TRUE(os.ok()) << os.error_message();
  ASSERT_GE(out.contour().points_size(), 8);
  for (const auto& q : out.contour().points())
    EXPECT_NEAR(std::hypot(q.x() - 256, q.y() - 256), 150, 3.0);
}

TEST(RheodCancel, ExtractContourIsRefusedWhenThePoolIsFull) {
  RheodProcess d({"--workers", "1", "--max-jobs", "1"});
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  v1::CreateObjectRequest req;
  req.mutable_sketch()->set_strokes_json(DenseStrokeBomb());
  grpc::ClientContext ctx;
  SetDeadline(ctx, 60s);
  auto reader = stub->CreateObject(&ctx, req);
  v1::CreateObjectProgress p;
  ASSERT_TRUE(reader->Read(&p));
  v1::ExtractContourRequest ex;
  ex.mutable_sketch()->set_strokes_json(R"({"width":512,"height":512,"strokes":[[[1,1],[9,9]]]})");
  grpc::ClientContext ectx;
  SetDeadline(ectx);
  v1::ContourReport out;
  const grpc::Status s = stub->ExtractContour(&ectx, ex, &out);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("--max-jobs"), std::string::npos) << s.error_message();
  ctx.TryCancel();
  while (reader->Read(&p)) {
  }
  reader->Finish();
}

TEST(RheodCancel, DegenerateContourIsRefusedWithTheNumbers) {
  RheodProcess d;
  ASSERT_TRUE(d.started()) << d.log();
  auto stub = v1::ObjectService::NewStub(d.channel());
  v1::CreateObjectRequest req;
  for (int i = 0; i < 24; ++i) {
    auto* q = req.mutable_sketch()->mutable_contour()->add_points();
    q->set_x(1e-9 * 0.5 * (1 + std::cos(2 * M_PI * i / 24)));
    q->set_y(1e-9 * 0.5 * (1 + std::sin(2 * M_PI * i / 24)));
  }
  grpc::ClientContext ctx;
  SetDeadline(ctx, 30s);
  auto reader = stub->CreateObject(&ctx, req);
  v1::CreateObjectProgress p;
  bool stored = false;
  while (reader->Read(&p)) stored = stored || p.has_object();
  const grpc::Status s = reader->Finish();
  EXPECT_FALSE(stored);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << s.error_message();
  EXPECT_NE(s.error_message().find("the solid is 2.5e-13 m"), std::string::npos)
      << s.error_message();
  EXPECT_NE(s.error_message().find("at least 0.001 m (1 mm)"), std::string::npos)
      << s.error_message();
  EXPECT_NE(s.error_message().find("draw larger"), std::string::npos) << s.error_message();
}

}  // namespace
}  // namespace rheo::testing
