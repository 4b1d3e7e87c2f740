// rheoctl: command-line client of rheod. Exit 0 on success; otherwise the gRPC status code
// (1..16) with "CODE: message" on stderr.
#include <google/protobuf/util/json_util.h>
#include <grpcpp/grpcpp.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <iostream>

#include "grpc/health/v1/health.grpc.pb.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"

namespace {

struct Global {
  std::string server = "127.0.0.1:50051";
  double timeout_s = 5.0;
};

const char* CodeName(grpc::StatusCode c) {
  switch (c) {
    case grpc::OK: return "OK";
    case grpc::CANCELLED: return "CANCELLED";
    case grpc::UNKNOWN: return "UNKNOWN";
    case grpc::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::NOT_FOUND: return "NOT_FOUND";
    case grpc::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::ABORTED: return "ABORTED";
    case grpc::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::INTERNAL: return "INTERNAL";
    case grpc::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::DATA_LOSS: return "DATA_LOSS";
    case grpc::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN";
  }
}

int Fail(const grpc::Status& s) {
  std::cerr << CodeName(s.error_code()) << ": " << s.error_message() << "\n";
  return s.error_code() == grpc::OK ? 1 : static_cast<int>(s.error_code());
}

std::string ToJson(const google::protobuf::Message& m, bool pretty) {
  google::protobuf::util::JsonPrintOptions o;
  o.add_whitespace = pretty;
  o.preserve_proto_field_names = true;
  std::string out;
  (void)google::protobuf::util::MessageToJsonString(m, &out, o);
  if (!pretty) {
    while (!out.empty() && out.back() == '\n') out.pop_back();
  }
  return out;
}

std::shared_ptr<grpc::Channel> Connect(const Global& g) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(256 << 20);
  return grpc::CreateCustomChannel(g.server, grpc::InsecureChannelCredentials(), args);
}

void SetDeadline(grpc::ClientContext& ctx, const Global& g) {
  ctx.set_deadline(std::chrono::system_clock::now() +
                   std::chrono::milliseconds(static_cast<int64_t>(g.timeout_s * 1000)));
}

void PrintPercentiles(const char* name, const rheo::v1::Percentiles& p) {
  std::printf("  %-13s p50 %8.1f us  p99 %8.1f us  p99.9 %8.1f us  max %8.1f us\n", name,
              p.p50_us(), p.p99_us(), p.p999_us(), p.max_us());
}

int Status(const Global& g, bool json) {
  auto stub = rheo::v1::DaemonService::NewStub(Connect(g));
  grpc::ClientContext ctx;
  SetDeadline(ctx, g);
  rheo::v1::DaemonStatus st;
  grpc::Status s = stub->GetStatus(&ctx, rheo::v1::GetStatusRequest(), &st);
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(st, true);
    return 0;
  }
  const auto& l = st.loop();
  std::printf("rheod %s at %s, up %.1f s, data dir %s\n", st.version().c_str(),
              st.listen_address().c_str(), st.uptime_s(), st.data_dir().c_str());
  std::printf("device: %s\n", rheo::v1::DeviceKind_Name(st.device()).c_str());
  std::printf(
      "loop: %.0f Hz, %llu ticks, %llu late, %llu overruns, %llu skipped; SCHED_FIFO %s, "
      "memory locked %s\n",
      l.rate_hz(), (unsigned long long)l.ticks(), (unsigned long long)l.late_ticks(),
      (unsigned long long)l.overruns(), (unsigned long long)l.skipped_ticks(),
      l.realtime_priority() ? "yes" : "no", l.memory_locked() ? "yes" : "no");
  PrintPercentiles("period", l.period());
  PrintPercentiles("wake latency", l.wake_latency());
  PrintPercentiles("tick work", l.work());
  if (!l.notes().empty()) std::printf("  notes: %s\n", l.notes().c_str());
  std::printf("scene objects %u, stored objects %u, jobs %u, frame clients %u\n",
              st.scene_objects(), st.stored_objects(), st.running_jobs(), st.frame_clients());
  return 0;
}

int Watch(const Global& g, double rate, uint64_t count, bool positions) {
  auto stub = rheo::v1::FrameService::NewStub(Connect(g));
  grpc::ClientContext ctx;
  rheo::v1::WatchFramesRequest req;
  req.set_rate_hz(rate);
  req.set_max_frames(count);
  req.set_positions(positions);
  auto reader = stub->WatchFrames(&ctx, req);
  rheo::v1::Frame f;
  while (reader->Read(&f)) {
    std::cout << ToJson(f, false) << "\n";
    std::cout.flush();
  }
  grpc::Status s = reader->Finish();
  return s.ok() ? 0 : Fail(s);
}

int Health(const Global& g) {
  auto stub = grpc::health::v1::Health::NewStub(Connect(g));
  grpc::ClientContext ctx;
  SetDeadline(ctx, g);
  grpc::health::v1::HealthCheckResponse r;
  grpc::Status s = stub->Check(&ctx, grpc::health::v1::HealthCheckRequest(), &r);
  if (!s.ok()) return Fail(s);
  std::cout << grpc::health::v1::HealthCheckResponse::ServingStatus_Name(r.status()) << "\n";
  return r.status() == grpc::health::v1::HealthCheckResponse::SERVING ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  Global g;
  CLI::App app{"rheoctl: talk to a running rheod"};
  app.add_option("--server", g.server, "rheod address host:port")->capture_default_str();
  app.add_option("--timeout", g.timeout_s, "deadline of each call [s]")->capture_default_str();
  app.require_subcommand(1);

  bool json = false;
  auto* status = app.add_subcommand("status", "daemon version, loop timing, device, counts");
  status->add_flag("--json", json, "print the DaemonStatus message as JSON");

  double rate = 10;
  uint64_t count = 0;
  bool positions = false;
  auto* watch = app.add_subcommand("watch", "stream frames as JSON lines (Ctrl-C to stop)");
  watch->add_option("--rate", rate, "frames per second, 1..1000")->capture_default_str();
  watch->add_option("--count", count, "stop after this many frames (0 = never)")
      ->capture_default_str();
  watch->add_flag("--positions", positions, "include per-vertex positions");

  auto* health = app.add_subcommand("health", "standard gRPC health check");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (*status) return Status(g, json);
  if (*watch) return Watch(g, rate, count, positions);
  if (*health) return Health(g);
  return 1;
}
