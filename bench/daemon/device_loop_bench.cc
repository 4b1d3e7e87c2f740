// The daemon's 1 kHz tick with --device sim-spidar-g, measured in-process: the same Engine,
// DeviceLink (emulator + SPIDAR-G driver + watchdog), renderer and simulated object as rheod.
// Scenarios: first the machine's floor (the same loop with an empty tick), then an object of
// about 1,250 and about 5,000 tetrahedra (hard jelly, implicit), the
// emulated hand pressing and releasing it once a second; idle, and loaded with 8 frame watchers
// (the FrameService path: hub snapshot -> Frame message with positions -> serialised) at 60 Hz
// plus a mesh job (sketch -> solid, fine resolution) running back to back.
//
//   device_loop_bench [--seconds S] [--sketch FILE] [--tets N ...] [--no-floor]
//                     [--set NAME=VALUE ...]
// --tets N: an object size to run (repeat for several; default 1250 and 5000); --no-floor skips
// the empty-tick scenarios (e.g. to profile one size alone).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

#include "daemon/api/object_builder.h"
#include "daemon/device/device_link.h"
#include "daemon/loop/engine.h"
#include "daemon/loop/frame_hub.h"
#include "rheo/v1/frames.pb.h"
#include "sim/sim.h"

using namespace rheo;
using namespace rheo::daemon;

namespace {

// --set NAME=VALUE: parameters over the preset's (e.g. cg_iteration_budget=0, the step before it).
std::vector<std::pair<std::string, double>> g_sets;

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Result<StoredObject> Build(const std::string& strokes, double resolution) {
  v1::CreateObjectRequest req;
  req.set_name("bench");
  req.mutable_sketch()->set_strokes_json(strokes);
  req.mutable_mesh_options()->set_resolution(resolution);
  return BuildObject(req, BuildLimits{},
                     [](const v1::CreateObjectProgress&) { return std::optional<Error>(); });
}

// The resolution whose mesh is nearest `tets` (coarse bisection on the edge length).
Result<StoredObject> BuildNear(const std::string& strokes, size_t tets) {
  double lo = 0.002, hi = 0.03;
  std::optional<StoredObject> best;
  for (int i = 0; i < 9; ++i) {
    const double r = std::sqrt(lo * hi);
    auto o = Build(strokes, r);
    if (!o.ok()) return o.error();
    const size_t n = o->mesh.tets.size();
    if (!best || std::abs((double)n - (double)tets) <
                     std::abs((double)best->mesh.tets.size() - (double)tets))
      best = std::move(o).value();
    if (n > tets)
      lo = r;
    else
      hi = r;
  }
  return std::move(*best);
}

void Print(const rt::Histogram& h) {
  std::printf(" %8.1f %8.1f %8.1f %8.1f |", h.Quantile(0.5) / 1e3, h.Quantile(0.99) / 1e3,
              h.Quantile(0.999) / 1e3, h.max_ns() / 1e3);
}

// The load: 8 frame watchers at 60 Hz (hub snapshot -> Frame with positions -> serialised) and
// a mesh job running back to back, until `stop`.
std::vector<std::thread> StartLoad(const std::string& strokes, FrameHub& hub,
                                   std::atomic<bool>& stop, std::atomic<uint64_t>& frames,
                                   std::atomic<uint64_t>& jobs) {
  std::vector<std::thread> load;
  for (int i = 0; i < 8; ++i)
    load.emplace_back([&] {
      const int h = hub.Register(60.0);
      uint64_t seq = 0;
      v1::Frame frame;
      std::string bytes;
      while (!stop.load()) {
        auto snap =
            hub.WaitNewer(seq, std::chrono::steady_clock::now() + std::chrono::milliseconds(200),
                          [&] { return stop.load(); });
        if (!snap) continue;
        seq = snap->seq;
        frame.Clear();
        const LoopFrame& f = snap->frame;
        for (uint32_t k = 0; k < f.object_count; ++k) {
          auto* os = frame.add_objects();
          const float* p = f.positions.data() + 3u * f.objects[k].first;
          os->mutable_positions()->Add(p, p + 3u * f.objects[k].vertex_count);
        }
        frame.SerializeToString(&bytes);
        frames.fetch_add(1);
        std::this_thread::sleep_for(std::chrono::milliseconds(16));
      }
      hub.Unregister(h);
    });
  load.emplace_back([&] {
    while (!stop.load()) {
      (void)Build(strokes, 0.003);
      jobs.fetch_add(1);
    }
  });
  return load;
}

// Runs `engine` for `seconds` after a 0.5 s warm-up, idle or under the load, and prints a row.
// With a device attached (`tets` > 0) the device columns come from its telemetry.
void Measure(Engine& engine, const std::string& strokes, bool loaded, double seconds,
             const std::string& label, size_t tets, bool device) {
  FrameHub hub(engine);
  hub.Start();
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> jobs{0}, frames{0};
  std::vector<std::thread> load;
  if (loaded) load = StartLoad(strokes, hub, stop, frames, jobs);
  // Warm up 0.5 s, then measure a fresh window.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const rt::LoopStats& s = engine.loop().stats();
  const ToolTelemetry before = engine.tool();
  const uint64_t late0 = s.late_ticks.load(), over0 = s.overruns.load(),
                 skipped0 = s.skipped_ticks.load();
  // The loop's histograms are cumulative: the percentiles include the 0.5 s warm-up.
  uint64_t touching = 0, samples = 0;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ++samples;
    if (engine.tool().in_contact) ++touching;
  }
  stop.store(true);
  const ToolTelemetry after = engine.tool();
  std::printf("| %-26s | %5zu |", label.c_str(), tets);
  Print(s.period);
  Print(s.work);
  std::printf(" %6llu %6llu %7llu |", (unsigned long long)(s.late_ticks.load() - late0),
              (unsigned long long)(s.overruns.load() - over0),
              (unsigned long long)(s.skipped_ticks.load() - skipped0));
  if (device) {
    std::printf(" %5llu %4llu %4llu | %3.0f%% |",
                (unsigned long long)(after.deadline_misses - before.deadline_misses),
                (unsigned long long)(after.watchdog_trips - before.watchdog_trips),
                (unsigned long long)(after.device_errors - before.device_errors),
                100.0 * touching / std::max<uint64_t>(samples, 1));
  } else {
    std::printf(" %5s %4s %4s | %4s |", "-", "-", "-", "-");
  }
  std::printf(" %4llu %3llu |\n", (unsigned long long)frames.load(),
              (unsigned long long)jobs.load());
  for (auto& t : load) t.join();
  hub.Stop();
}

// The machine's own floor: the same loop (SCHED_FIFO, locked memory) with nothing to do but
// publish an empty frame, under the same load. Whatever the real tick shows beyond this is ours.
int RunFloor(const std::string& strokes, bool loaded, double seconds, const std::string& label) {
  Engine engine{EngineOptions{}};
  engine.Start();
  Measure(engine, strokes, loaded, seconds, label, 0, /*device=*/false);
  engine.Stop();
  return 0;
}

int RunScenario(const std::string& strokes, const StoredObject& obj, bool loaded, double seconds,
                const std::string& label) {
  DeviceLinkOptions o;
  o.kind = DeviceKind::kSimSpidarG;
  o.config_path = std::string(RHEO_DEVICES) + "/spidar_g_x5.json";
  o.reply_timeout_us = 20000;
  auto link = DeviceLink::Open(o);
  if (!link.ok()) {
    std::fprintf(stderr, "device: %s\n", link.error().message.c_str());
    return 1;
  }
  auto preset = sim::FindPreset("hard-jelly");
  sim::Parameters params = preset->params;
  for (const auto& [name, value] : g_sets) {
    if (Status st = sim::SetParameterByName(params, name, value); !st.ok()) {
      std::fprintf(stderr, "--set %s: %s\n", name.c_str(), st.error().message.c_str());
      return 1;
    }
  }
  // Laid flat: the solid's thickness (along z, out of the sketch's plane) made vertical. Standing
  // on its rim, the bean tipped over onto its side within the warm-up, and the hand, placed over
  // the rim's highest point, pressed into air (0 % contact in every scenario).
  TetMesh mesh = obj.mesh;
  {
    Eigen::AlignedBox3d b;
    for (const Vec3& x : mesh.positions) b.extend(x);
    if (b.sizes().z() < b.sizes().y())
      for (Vec3& x : mesh.positions) x = Vec3(x.x(), -x.z(), x.y());  // +90 deg about x
  }
  auto simobj = sim::SimObject::Create(mesh, params, sim::Integrator::kImplicitEuler);
  if (!simobj.ok()) {
    std::fprintf(stderr, "sim: %s\n", simobj.error().message.c_str());
    return 1;
  }
  // Rest on the floor, the tool origin 5 mm above the highest point.
  Eigen::AlignedBox3d box;
  for (const Vec3& x : mesh.positions) box.extend(x);
  (*simobj)->Translate(Vec3(-box.center().x(), -box.min().y(), -box.center().z()));
  Vec3 top = (*simobj)->positions()[0];
  for (const Vec3& x : (*simobj)->positions())
    if (x.y() > top.y()) top = x;
  const Vec3 origin = top + Vec3(0, o.tool_radius + 0.005, 0);
  double min_mass = 0.0;
  for (const auto& f : obj.mesh.surface)
    for (int32_t v : f) {
      const double m = (*simobj)->model().mass[v];
      if (min_mass == 0.0 || m < min_mass) min_mass = m;
    }
  auto contact = (*link)->MakeContact(obj.mesh.surface, (*simobj)->positions(), origin, min_mass);
  if (!contact.ok()) {
    std::fprintf(stderr, "renderer: %s\n", contact.error().message.c_str());
    return 1;
  }
  EngineOptions eo;
  Engine engine(eo);
  engine.AttachDevice(link->get());
  engine.Start();
  Command oc;
  oc.type = Command::Type::kSetToolOrigin;
  oc.vec = {origin.x(), origin.y(), origin.z()};
  engine.Submit(oc);
  Command add;
  add.type = Command::Type::kAddObject;
  add.instance_id = 1;
  add.object = simobj->release();
  add.contact = contact->release();
  engine.WaitApplied(engine.Submit(add), 2'000'000'000);
  // The hand presses 2-8 mm below the top and back, once a second.
  const double r = o.tool_radius, t0 = (*link)->emulator()->Snapshot().time;
  (*link)->emulator()->ScriptHand([=](double t) {
    drivers::Pose p;
    p.position.y() = -(r + 0.005) - 0.002 - 0.003 * (1.0 - std::cos(2.0 * M_PI * (t - t0)));
    return p;
  });
  Measure(engine, strokes, loaded, seconds, label, obj.mesh.tets.size(), /*device=*/true);
  engine.Stop();
  (*link)->Shutdown();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  double seconds = 5.0;
  std::string sketch = std::string(RHEO_SKETCHES) + "/bean.json";
  std::vector<size_t> sizes;
  bool floor = true;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--no-floor")) floor = false;
    if (!std::strcmp(argv[i], "--tets") && i + 1 < argc) {
      const long n = std::atol(argv[++i]);
      if (n <= 0) {
        std::fprintf(stderr, "--tets expects a positive count, got '%s'\n", argv[i]);
        return 1;
      }
      sizes.push_back(static_cast<size_t>(n));
    }
    if (!std::strcmp(argv[i], "--seconds") && i + 1 < argc) seconds = std::atof(argv[++i]);
    if (!std::strcmp(argv[i], "--sketch") && i + 1 < argc) sketch = argv[++i];
    if (!std::strcmp(argv[i], "--set") && i + 1 < argc) {
      std::string name;
      double value = 0.0;
      if (!sim::ParseSetting(argv[++i], &name, &value)) {
        std::fprintf(stderr, "--set expects name=number, got '%s'\n", argv[i]);
        return 1;
      }
      g_sets.emplace_back(name, value);
    }
  }
  const std::string strokes = ReadText(sketch);
  if (strokes.empty()) {
    std::fprintf(stderr, "cannot read %s (pass --sketch FILE)\n", sketch.c_str());
    return 1;
  }
  std::printf(
      "device_loop_bench: %.1f s per scenario, X5 emulator, hard jelly (implicit), hand\n"
      "pressing 2-8 mm below the top at 1 Hz; load = 8 frame watchers at 60 Hz + a mesh job\n"
      "(times in us; period/work percentiles cover the whole run incl. 0.5 s warm-up;\n"
      "late/overrun/skipped/misses/trips/errors count the measured window)\n",
      seconds);
  for (const auto& [name, value] : g_sets) std::printf("parameter %s = %g\n", name.c_str(), value);
  std::printf("\n");
  std::printf("| %-26s | %5s | %35s | %35s | %6s %6s %7s | %5s %4s %4s | %4s | %4s %3s |\n",
              "scenario", "tets", "period p50 / p99 / p99.9 / max", "work p50 / p99 / p99.9 / max",
              "late", "overr", "skipped", "miss", "trip", "err", "cont", "frms", "job");
  if (sizes.empty()) sizes = {1250, 5000};
  for (bool loaded : {false, true}) {
    if (floor && RunFloor(strokes, loaded, seconds,
                          std::string("empty tick (floor), ") + (loaded ? "loaded" : "idle")) != 0)
      return 1;
  }
  for (size_t target : sizes) {
    auto obj = BuildNear(strokes, target);
    if (!obj.ok()) {
      std::fprintf(stderr, "build: %s\n", obj.error().message.c_str());
      return 1;
    }
    for (bool loaded : {false, true}) {
      // Appended rather than "~" + std::string (GCC 12 flags that with a false -Wrestrict).
      std::string label = "~";
      label += std::to_string(target);
      label += " tets, ";
      label += loaded ? "loaded" : "idle";
      if (RunScenario(strokes, *obj, loaded, seconds, label) != 0) return 1;
    }
  }
  return 0;
}
