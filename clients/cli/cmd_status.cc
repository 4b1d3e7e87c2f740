// `rheoctl status`, `rheoctl watch`, `rheoctl health`: the daemon, its frames, its health.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <map>
#include <string>

#include "grpc/health/v1/health.grpc.pb.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheoctl.h"

namespace rheoctl {
namespace {

void PrintPercentiles(const char* name, const rheo::v1::Percentiles& p) {
  std::printf("  %-13s p50 %8.1f us  p99 %8.1f us  p99.9 %8.1f us  max %8.1f us\n", name,
              p.p50_us(), p.p99_us(), p.p999_us(), p.max_us());
}

int ShowStatus(const Global& g, bool json) {
  rheo::v1::DaemonStatus st;
  grpc::Status s = Unary<rheo::v1::DaemonService>(g, &rheo::v1::DaemonService::Stub::GetStatus,
                                                  rheo::v1::GetStatusRequest(), &st);
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(st, true);
    return 0;
  }
  const auto& l = st.loop();
  std::printf("rheod %s at %s, up %.1f s, data dir %s\n", st.version().c_str(),
              st.listen_address().c_str(), st.uptime_s(), st.data_dir().c_str());
  std::printf("device: %s", rheo::v1::DeviceKind_Name(st.device()).c_str());
  if (st.has_device_counters()) {
    const auto& c = st.device_counters();
    std::printf(
        ", connected %s; %llu exchanges, %llu device errors, %llu protocol errors, %llu "
        "recoveries\n",
        st.device_connected() ? "yes" : "NO", (unsigned long long)c.exchanges(),
        (unsigned long long)c.device_errors(), (unsigned long long)c.protocol_errors(),
        (unsigned long long)c.recoveries());
    PrintLineCounters(c);
  } else {
    std::printf("\n");
  }
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
  if (l.restores() > 0) {
    std::printf(
        "  restores: %llu (an object's state went non-finite or too fast and was put back to its "
        "last good state; see each object's restores in `rheoctl watch`)\n",
        (unsigned long long)l.restores());
  }
  if (l.sim_budget_us() > 0)
    std::printf("  simulation: %.0f us a tick predicted for the awake scene, of %.0f us allowed\n",
                l.predicted_sim_us(), l.sim_budget_us());
  else
    std::printf(
        "  simulation: %.0f us a tick predicted for the awake scene (no admission by "
        "cost)\n",
        l.predicted_sim_us());
  if (l.unstable_objects() > 0)
    std::printf(
        "  stopped objects: %u (restored 5 times within a second; set new parameters or reset)\n",
        l.unstable_objects());
  std::printf("scene objects %u, stored objects %u, jobs %u, frame clients %u\n",
              st.scene_objects(), st.stored_objects(), st.running_jobs(), st.frame_clients());
  if (st.has_limits()) {
    const auto& lim = st.limits();
    std::printf(
        "limits per token: %g calls/s to each expensive method (burst %g), %u streams, %u mesh "
        "jobs, idle streams end after %g s (0 = none)\n"
        "  hit: %llu calls, %llu streams, %llu jobs refused; %llu idle streams ended; %u streams "
        "open\n",
        lim.calls_per_s(), lim.burst(), lim.streams(), lim.jobs(), lim.stream_idle_s(),
        (unsigned long long)lim.refused_calls(), (unsigned long long)lim.refused_streams(),
        (unsigned long long)lim.refused_jobs(), (unsigned long long)lim.idle_streams_ended(),
        lim.open_streams());
  }
  return 0;
}

// One line a frame for people: time, each object's size, height range, volume and energy, the
// tool, the loop's late ticks.
std::string FrameLine(const rheo::v1::Frame& f, const std::map<uint32_t, uint32_t>& triangles_of) {
  char b[256];
  std::snprintf(b, sizeof b, "tick %llu  t %.3f s%s", (unsigned long long)f.stamp().tick(),
                f.stamp().sim_time(), f.paused() ? " (paused)" : "");
  std::string line = b;
  line +=
      "  " + std::to_string(f.objects_size()) + (f.objects_size() == 1 ? " object" : " objects");
  for (const auto& o : f.objects()) {
    float lo = 0, hi = 0;
    for (int k = 1; k < o.positions_size(); k += 3) {
      const float y = o.positions(k);
      if (k == 1 || y < lo) lo = y;
      if (k == 1 || y > hi) hi = y;
    }
    std::snprintf(b, sizeof b, "  [#%u: %d vertices", o.instance_id(), o.positions_size() / 3);
    line += b;
    if (auto it = triangles_of.find(o.instance_id()); it != triangles_of.end())
      line += ", " + std::to_string(it->second) + " triangles";
    if (o.positions_size() > 0) {
      std::snprintf(b, sizeof b, ", y %.4f..%.4f m", lo, hi);
      line += b;
    }
    std::snprintf(b, sizeof b, ", volume %.3g m^3, KE %.2g J%s%s%s]", o.volume(),
                  o.kinetic_energy(), o.sleeping() ? ", asleep" : "",
                  o.unstable() ? ", STOPPED (unstable: set new parameters or reset)" : "",
                  o.restores() ? (", " + std::to_string(o.restores()) + " restores").c_str() : "");
    line += b;
  }
  if (f.tool().present()) {
    const auto& force = f.tool().wrench().force();
    std::snprintf(b, sizeof b, "  tool: contact %s, hand force %.2f N",
                  f.tool().in_contact() ? "yes" : "no",
                  std::sqrt(force.x() * force.x() + force.y() * force.y() + force.z() * force.z()));
    line += b;
  }
  line += "  late ticks " + std::to_string(f.loop().late_ticks());
  if (f.dropped_frames()) line += ", dropped " + std::to_string(f.dropped_frames());
  return line;
}

int Watch(const Global& g, double rate, uint64_t count, bool positions, bool json) {
  auto stub = rheo::v1::FrameService::NewStub(Connect(g));
  grpc::ClientContext ctx;
  rheo::v1::WatchFramesRequest req;
  req.set_rate_hz(rate);
  req.set_max_frames(count);
  // The summary shows each object's height range, so it asks for the positions.
  req.set_positions(positions || !json);
  auto reader = stub->WatchFrames(&ctx, req);
  rheo::v1::Frame f;
  std::map<uint32_t, uint32_t> triangles_of;  // instance -> surface triangles (from topology)
  while (reader->Read(&f)) {
    if (json) {
      std::cout << ToJson(f, false) << "\n";
    } else {
      for (const auto& t : f.topology())
        triangles_of[t.instance_id()] = static_cast<uint32_t>(t.triangles_size() / 3);
      std::cout << FrameLine(f, triangles_of) << "\n";
    }
    std::cout.flush();
  }
  grpc::Status s = reader->Finish();
  return s.ok() ? 0 : Fail(s);
}

int Health(const Global& g) {
  grpc::health::v1::HealthCheckResponse r;
  grpc::Status s = Unary<grpc::health::v1::Health>(g, &grpc::health::v1::Health::Stub::Check,
                                                   grpc::health::v1::HealthCheckRequest(), &r);
  if (!s.ok()) return Fail(s);
  std::cout << grpc::health::v1::HealthCheckResponse::ServingStatus_Name(r.status()) << "\n";
  return r.status() == grpc::health::v1::HealthCheckResponse::SERVING ? 0 : 1;
}

}  // namespace

void AddStatusCommands(CLI::App& app, const Global& g) {
  auto json = std::make_shared<bool>(false);
  auto* status = app.add_subcommand("status", "daemon version, loop timing, device, counts");
  status->add_flag("--json", *json, "print the DaemonStatus message as JSON");
  status->callback([&g, json] { g_exit_code = ShowStatus(g, *json); });

  struct WatchArgs {
    double rate = 10;
    uint64_t count = 0;
    bool positions = false;
    bool json = false;
  };
  auto w = std::make_shared<WatchArgs>();
  auto* watch = app.add_subcommand(
      "watch",
      "stream frames, a line each (--json: the Frame messages as JSON lines; Ctrl-C stops)");
  watch->add_option("--rate", w->rate, "frames per second, 1..1000")->capture_default_str();
  watch->add_option("--count", w->count, "stop after this many frames (0 = never)")
      ->capture_default_str();
  watch->add_flag("--json", w->json, "print each Frame message as a JSON line");
  watch->add_flag("--positions", w->positions, "with --json: include per-vertex positions");
  watch->callback([&g, w] { g_exit_code = Watch(g, w->rate, w->count, w->positions, w->json); });

  auto* health = app.add_subcommand("health", "standard gRPC health check");
  health->callback([&g] { g_exit_code = Health(g); });
}

}  // namespace rheoctl
