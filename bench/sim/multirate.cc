// sim_bench multirate [sample] [max_tets]: a press through a virtual coupling on a sketched
// object at about 5k, 20k and 100k tets, the full solve every 1 ms tick beside the multi-rate
// scheme (sim/multirate.h: the patch near the tool every tick, the whole every N ticks). Per
// size and N: the hand's force error against the full solve (RMS and peak over the press), the
// tick's own work (patch step + contact) and the whole's step against its period.
#include "sim/multirate.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <vector>

#include "bench.h"

namespace sim_bench {
namespace {

using Clock = std::chrono::steady_clock;
double Us(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

constexpr double kDt = 1e-3;
constexpr int kSettleTicks = 1000;
constexpr int kPressTicks = 900;
constexpr double kSpeed = 0.03;       // device speed down and back up [m/s]
constexpr double kToolRadius = 8e-3;  // a fingertip [m]

// The device's scripted path [m]: down for 0.3 s, held 0.3 s, back up for 0.3 s.
Vec3 DeviceAt(const Vec3& start, int k) {
  const double t = k * kDt;
  const double depth = t < 0.3   ? kSpeed * t
                       : t < 0.6 ? kSpeed * 0.3
                                 : std::max(0.0, kSpeed * (0.9 - t));
  return start - Vec3(0, depth, 0);
}

struct Run {
  std::vector<Vec3> force;       // on the hand, per tick [N]
  std::vector<double> tick_us;   // the tick's own work
  std::vector<double> whole_us;  // the whole's steps (multi-rate)
  int64_t restores = 0;
  int64_t cg = 0, substeps = 0;  // CG iterations and substeps over the ticks (the loop's step)
  rheo::sim::MultiRateCounts counts;
  int32_t patch_nodes = 0, patch_tets = 0;
};

// The hand's coupling: the device is tied to the nodes within kToolRadius of the top by springs
// of kCoupling in all, each to its place at rest, so the force the hand feels depends only on how
// the object moves (no contact search in the way). The springs act as loads held over a tick.
constexpr double kCoupling = 500.0;  // [N/m]

// Hand force (on the hand) and the node loads (on the object) for device position `dev`.
struct Grip {
  std::vector<int32_t> nodes;
  std::vector<Vec3> offset;  // from the device point at rest [m]
};

Vec3 Couple(const Grip& grip, std::span<const Vec3> x, const Vec3& dev,
            std::vector<NodeLoad>& loads) {
  loads.clear();
  Vec3 hand = Vec3::Zero();
  const double k = kCoupling / grip.nodes.size();
  for (size_t q = 0; q < grip.nodes.size(); ++q) {
    const int32_t i = grip.nodes[q];
    const Vec3 f = k * (dev + grip.offset[q] - x[i]);  // on the object, towards the device
    loads.push_back({i, f, k});
    hand -= f;
  }
  return hand;
}

Grip GripAt(const SimObject& o, int32_t top) {
  Grip grip;
  const Vec3 c = o.positions()[top];
  for (int32_t i = 0; i < o.model().num_nodes; ++i) {
    if ((o.positions()[i] - c).norm() >= kToolRadius) continue;
    grip.nodes.push_back(i);
    grip.offset.push_back(o.positions()[i] - c);
  }
  return grip;
}

Run RunFull(const SimObject& settled, const Grip& grip, const Vec3& start) {
  auto obj = std::make_unique<SimObject>(settled);
  Run r;
  std::vector<NodeLoad> loads;
  for (int k = 0; k < kPressTicks; ++k) {
    const auto t0 = Clock::now();
    const Vec3 hand = Couple(grip, obj->positions(), DeviceAt(start, k), loads);
    for (const NodeLoad& l : loads) obj->SetExternalForce(l.node, l.force, l.stiffness);
    const StepResult st = obj->Step(kDt);
    r.tick_us.push_back(Us(t0, Clock::now()));
    r.force.push_back(hand);
    r.restores += st.restored;
    r.cg += st.solver_iterations;
    r.substeps += st.substeps;
  }
  return r;
}

Run RunMultiRate(const SimObject& settled, const Grip& grip, const Vec3& start, int period) {
  auto mr = MultiRate::Create(std::make_unique<SimObject>(settled), period, PatchOptions{});
  Run r;
  std::vector<NodeLoad> loads;
  loads.reserve(grip.nodes.size());
  for (int k = 0; k < kPressTicks; ++k) {
    if (k % period == 0) {
      // The whole's step runs beside the ticks of its period (another thread in the daemon):
      // timed on its own.
      mr->Sync(start);
      const auto w0 = Clock::now();
      r.restores += mr->StepWhole(period * kDt).restored;
      r.whole_us.push_back(Us(w0, Clock::now()));
    }
    const auto t0 = Clock::now();
    const Vec3 hand = Couple(grip, mr->positions(), DeviceAt(start, k), loads);
    const StepResult st = mr->FastTick(loads, kDt);
    r.tick_us.push_back(Us(t0, Clock::now()));
    r.cg += st.solver_iterations;
    r.substeps += st.substeps;
    r.force.push_back(hand);
  }
  r.counts = mr->counts();
  if (const Patch* p = mr->patch()) {
    r.patch_nodes = p->inner_nodes();
    r.patch_tets = static_cast<int32_t>(p->object().model().tets.size());
  }
  return r;
}

}  // namespace

int MultiRate(const std::string& sample, int max_tets) {
  auto meshes = MeshSampleSizes(sample, max_tets);
  if (!meshes.ok()) {
    std::fprintf(stderr, "sim_bench multirate: %s\n", meshes.error().message.c_str());
    return 1;
  }
  std::printf(
      "# samples/%s.json, organ preset, BDF2, 1 ms ticks; settled on the floor for %d ticks, then "
      "pressed\n# by a device tied by %.0f N/m to the nodes within %.0f mm of the top: down %.0f "
      "mm/s for 0.3 s, held 0.3 s, up.\n# full: the whole object every tick. N: the patch "
      "(radius %.0f mm) every tick, the whole every N ticks.\n",
      sample.c_str(), kSettleTicks, kCoupling, kToolRadius * 1e3, kSpeed * 1e3,
      PatchOptions{}.radius * 1e3);
  std::printf("%7s %4s %9s %9s %9s %8s %8s %10s %10s %9s %8s %7s %8s %8s %7s %6s\n", "tets", "N",
              "tick_med", "tick_p99", "tick_max", "whole_us", "whole/N", "F_rms_err", "F_peak_err",
              "F_peak", "patch_n", "tets_p", "rebuilds", "restores", "cg/tick", "sub/t");
  for (size_t mi = 0; mi < meshes->meshes.size(); ++mi) {
    Parameters p = FindPreset("organ")->params;
    p.sleep_time = 0.0;
    auto made = SimObject::Create(meshes->meshes[mi], p, Integrator::kImplicitEuler);
    if (!made.ok()) {
      std::fprintf(stderr, "sim_bench multirate: %s\n", made.error().message.c_str());
      return 1;
    }
    SimObject& settled = **made;
    double y_min = 1e30;
    for (const Vec3& x : settled.positions()) y_min = std::min(y_min, x.y());
    settled.Translate(Vec3(0, p.floor_height - y_min, 0));
    for (int k = 0; k < kSettleTicks; ++k) settled.Step(kDt);
    std::printf("# %zu tets: kinetic energy after settling %.3g J\n", settled.model().tets.size(),
                settled.kinetic_energy());
    // The tool starts 4 mm above the highest node.
    int32_t top = 0;
    for (int32_t i = 0; i < settled.model().num_nodes; ++i)
      if (settled.positions()[i].y() > settled.positions()[top].y()) top = i;
    const Vec3 start = settled.positions()[top];
    const Grip grip = GripAt(settled, top);
    const size_t tets = settled.model().tets.size();
    const Run full = RunFull(settled, grip, start);
    double f_peak = 0.0;
    for (const Vec3& f : full.force) f_peak = std::max(f_peak, f.norm());
    const double ticks = static_cast<double>(kPressTicks);
    std::printf(
        "%7zu %4s %9.1f %9.1f %9.1f %8s %8s %10s %10s %9.3f %8s %7s %8s %8lld %7.2f %6.2f\n", tets,
        "full", Median(full.tick_us), Percentile(full.tick_us, 0.99),
        *std::max_element(full.tick_us.begin(), full.tick_us.end()), "-", "-", "-", "-", f_peak,
        "-", "-", "-", static_cast<long long>(full.restores), full.cg / ticks,
        full.substeps / ticks);
    std::fflush(stdout);
    for (int period : {1, 5, 10, 20}) {
      const Run mr = RunMultiRate(settled, grip, start, period);
      double e2 = 0.0, e_peak = 0.0;
      for (size_t k = 0; k < mr.force.size(); ++k) {
        const double e = (mr.force[k] - full.force[k]).norm();
        e2 += e * e;
        e_peak = std::max(e_peak, e);
      }
      if (std::getenv("RHEO_MR_TRACE"))
        for (size_t k = 0; k < mr.force.size(); k += 30)
          std::printf("  trace N=%d t=%3zu full %.4f mr %.4f\n", period, k, full.force[k].y(),
                      mr.force[k].y());
      const double whole = Median(mr.whole_us);
      std::printf(
          "%7zu %4d %9.1f %9.1f %9.1f %8.0f %8.2f %10.4f %10.4f %9.3f %8d %7d %8lld %8lld %7.2f "
          "%6.2f\n",
          tets, period, Median(mr.tick_us), Percentile(mr.tick_us, 0.99),
          *std::max_element(mr.tick_us.begin(), mr.tick_us.end()), whole, whole / (period * 1e3),
          std::sqrt(e2 / mr.force.size()), e_peak, f_peak, mr.patch_nodes, mr.patch_tets,
          static_cast<long long>(mr.counts.rebuilds),
          static_cast<long long>(mr.restores + mr.counts.patch_restores), mr.cg / ticks,
          mr.substeps / ticks);
      std::fflush(stdout);
    }
  }
  std::printf(
      "# tick: the loop's own work per tick [us] (full: the whole step + contact; N: patch step + "
      "contact).\n# whole_us: median of the whole's steps, each covering N ticks; whole/N < 1: it "
      "keeps up with real time on\n# its own core. F_*_err: |F_multirate - F_full| on the hand "
      "over the press [N]; F_peak: the full solve's peak.\n# cg/tick, sub/t: the loop's step's CG "
      "iterations and substeps per tick (full: the whole's; N: the patch's).\n");
  return 0;
}

}  // namespace sim_bench
