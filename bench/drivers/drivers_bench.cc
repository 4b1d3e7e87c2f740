// Per-tick costs of the SPIDAR-G driver, printed as a table of medians and tails.
//   drivers_bench [--quick]
// Columns: pose solver tick (configured iterations), tension QP warm-started along a moving
// trajectory and cold-started on the same problems (ratio cold/warm), a full Exchange+SetWrench
// through the emulator's pseudo-terminal, and the watchdog's time from the last feed to the
// emulator seeing every motor at minimum tension.
#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <random>
#include <thread>
#include <vector>

#include "drivers/device_factory.h"
#include "drivers/spidar_emulator.h"
#include "drivers/spidar_kinematics.h"
#include "drivers/tension_qp.h"
#include "drivers/watchdog.h"
#include "drivers/watchdog_thread.h"

using namespace rheo;
using namespace rheo::drivers;

namespace {

int64_t Now() {
  return MonotonicNowNs();
}

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p * (v.size() - 1) + 0.5))];
}

// A smooth path through the workspace: 1 m/s-ish, rotating, with a wrench that varies.
Pose PathPose(const SpidarConfig& c, int k) {
  Pose p;
  const double t = k * 1e-3;
  for (int a = 0; a < 3; ++a) {
    p.position[a] = 0.8 * c.workspace.half_extent[a] * std::sin(2.0 * t * (a + 1) + a);
  }
  p.orientation = Eigen::AngleAxisd(0.8 * c.workspace.max_tilt * std::sin(1.3 * t),
                                    Vec3(std::sin(t), 1.0, std::cos(0.7 * t)).normalized());
  return p;
}
Wrench PathWrench(int k) {
  const double t = k * 1e-3;
  return Wrench{Vec3(3.0 * std::sin(3 * t), 2.0 * std::cos(2 * t) - 1.0, 2.5 * std::sin(5 * t)),
                Vec3(0.02 * std::sin(t), 0.01 * std::cos(4 * t), 0.015 * std::sin(2 * t))};
}

struct Row {
  const char* frame;
  double pose_med, pose_p99, qp_warm_med, qp_warm_p99, qp_cold_med, qp_warm_iters;
};

Row BenchFrame(const char* frame, int n) {
  auto c =
      LoadSpidarConfigFile(std::string(RHEO_DRIVERS_CONFIG_DIR) + "/spidar_g_" + frame + ".json");
  if (!c.ok()) {
    std::fprintf(stderr, "%s\n", c.error().message.c_str());
    std::exit(1);
  }
  const SpidarConfig& cfg = *c;
  StringGeometry home;
  ComputeStringGeometry(cfg, Pose(), &home);
  std::vector<StringVector> lengths(n);
  std::vector<StringMatrix> a(n);
  for (int k = 0; k < n; ++k) {
    StringGeometry g;
    ComputeStringGeometry(cfg, PathPose(cfg, k), &g);
    a[k] = g.a;
    for (int i = 0; i < 8; ++i) {
      const double mpc = cfg.strings[i].metres_per_count;
      lengths[k][i] = home.length[i] + std::round((g.length[i] - home.length[i]) / mpc) * mpc;
    }
  }
  Row row{frame, 0, 0, 0, 0, 0, 0};
  std::vector<double> t(n);
  PoseSolver solver(cfg);
  solver.Reset(PathPose(cfg, 0));
  for (int k = 0; k < n; ++k) {
    const int64_t t0 = Now();
    solver.Update(lengths[k]);
    t[k] = (Now() - t0) * 1e-3;
  }
  row.pose_med = Percentile(t, 0.5);
  row.pose_p99 = Percentile(t, 0.99);
  TensionSolver warm(cfg);
  double iters = 0;
  for (int k = 0; k < n; ++k) {
    const Wrench w = PathWrench(k);
    const int64_t t0 = Now();
    iters += warm.Solve(a[k], w).iterations;
    t[k] = (Now() - t0) * 1e-3;
  }
  row.qp_warm_med = Percentile(t, 0.5);
  row.qp_warm_p99 = Percentile(t, 0.99);
  row.qp_warm_iters = iters / n;
  TensionSolver cold(cfg);
  for (int k = 0; k < n; ++k) {
    const Wrench w = PathWrench(k);
    cold.Reset();
    const int64_t t0 = Now();
    cold.Solve(a[k], w);
    t[k] = (Now() - t0) * 1e-3;
  }
  row.qp_cold_med = Percentile(t, 0.5);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  const bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  const int n = quick ? 2000 : 20000;
  std::printf("SPIDAR-G driver costs per tick [us] (%d ticks per frame)\n", n);
  std::printf("%-5s | %9s %8s | %11s %8s %10s | %11s %9s\n", "frame", "pose med", "p99",
              "QP warm med", "p99", "iter/solve", "QP cold med", "cold/warm");
  for (const char* frame : {"x3", "x4", "x5", "g6x"}) {
    Row r = BenchFrame(frame, n);
    std::printf("%-5s | %9.2f %8.2f | %11.2f %8.2f %10.2f | %11.2f %9.2f\n", r.frame, r.pose_med,
                r.pose_p99, r.qp_warm_med, r.qp_warm_p99, r.qp_warm_iters, r.qp_cold_med,
                r.qp_cold_med / r.qp_warm_med);
  }

  // A full tick's device part through the emulator (real-time mode, as rheod would run it).
  auto cfg = LoadSpidarConfigFile(std::string(RHEO_DRIVERS_CONFIG_DIR) + "/spidar_g_x5.json");
  if (!cfg.ok()) return 1;
  // The loop, the emulated board and the watchdog as rheod would run them: SCHED_FIFO when
  // permitted (loop 80, emulator 85, watchdog 90), so other work on the machine cannot delay them.
  sched_param loop_param{};
  loop_param.sched_priority = 80;
  const bool loop_rt = pthread_setschedparam(pthread_self(), SCHED_FIFO, &loop_param) == 0;
  EmulatorOptions emu_options;
  emu_options.realtime_priority = 85;
  auto emu = SpidarEmulator::Start(*cfg, emu_options);
  if (!emu.ok()) return 1;
  auto dev = OpenSpidarG(*cfg, (*emu)->pty_path(), {.reply_timeout_us = 200'000});
  if (!dev.ok()) {
    std::fprintf(stderr, "%s\n", dev.error().message.c_str());
    return 1;
  }
  SpidarG& d = **dev;
  if (!d.Calibrate().ok()) return 1;
  const int ticks = quick ? 500 : 3000;
  std::vector<double> ex;
  int failures = 0;
  int64_t next = Now();
  for (int k = 0; k < ticks; ++k) {
    next += 1'000'000;
    timespec ts{static_cast<time_t>(next / 1'000'000'000), static_cast<long>(next % 1'000'000'000)};
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    const int64_t t0 = Now();
    failures += !d.Exchange(1e-3).ok();
    d.SetWrench(Wrench{Vec3(0.5 * std::sin(k * 0.01), 0.0, 0.0), Vec3::Zero()});
    ex.push_back((Now() - t0) * 1e-3);
  }
  std::printf(
      "\nExchange+SetWrench through the emulator pty, 1 kHz, %d ticks (loop %s, emulator %s) "
      "[us]: median %.1f, p99 %.1f, p99.9 %.1f, max %.1f; failed exchanges %d\n",
      ticks, loop_rt ? "SCHED_FIFO 80" : "normal priority",
      (*emu)->realtime() ? "SCHED_FIFO 85" : "normal priority", Percentile(ex, 0.5),
      Percentile(ex, 0.99), Percentile(ex, 0.999), Percentile(ex, 1.0), failures);

  // Watchdog: the loop stops feeding; time until the emulator holds minimum tension.
  const auto min_digits = [&] {
    std::array<int16_t, 8> m;
    for (int i = 0; i < 8; ++i) {
      const auto& s = cfg->strings[i];
      m[i] = static_cast<int16_t>(std::lround(s.command_sign * s.min_tension * s.volts_per_newton *
                                              cfg->board.digits_per_volt));
    }
    return m;
  }();
  std::vector<double> lat, trip, done;
  int skipped = 0;
  bool realtime = false;
  const int trials = quick ? 5 : 20;
  for (int trial = 0; trial < trials; ++trial) {
    d.ClearFaults();
    Watchdog dog(d);
    dog.Arm(Now());
    WatchdogThread thread(dog);
    int64_t last_feed = 0;
    for (int k = 0; k < 50; ++k) {  // 50 fed ticks with a force on
      next = Now() + 1'000'000;
      timespec ts{static_cast<time_t>(next / 1'000'000'000),
                  static_cast<long>(next % 1'000'000'000)};
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
      d.Exchange(1e-3);
      d.SetWrench(Wrench{Vec3(0.0, 1.0, 0.0), Vec3::Zero()});
      last_feed = Now();
      dog.Feed(last_feed);
    }
    // Stall: no more exchanges or feeds. A trial where an exchange failed (busy machine) already
    // sits at minimum tension, so it says nothing about the watchdog: skip it.
    if (d.status().faults != kFaultNone) {
      std::fprintf(stderr, "stall %d skipped: faults %s\n", trial,
                   FaultNames(d.status().faults).c_str());
      thread.Stop();
      ++skipped;
      continue;
    }
    int64_t seen = 0;
    while (Now() - last_feed < 100'000'000) {
      const GripSnapshot s = (*emu)->Snapshot();
      if (s.last_command == min_digits && s.last_command_ns > last_feed) {
        seen = s.last_command_ns;
        break;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
    realtime = thread.realtime();
    thread.Stop();
    lat.push_back(seen ? (seen - last_feed) * 1e-6 : NAN);
    trip.push_back((dog.trip_ns() - last_feed) * 1e-6);
    done.push_back(thread.stop_done_ns() ? (thread.stop_done_ns() - last_feed) * 1e-6 : NAN);
  }
  std::printf(
      "Watchdog (timeout %.1f ms, poll %.2f ms, watchdog thread %s), after the last feed "
      "[ms], %zu stalls (%d skipped: a fault, e.g. a trip, before the stall):\n",
      Watchdog::kDefaultTimeoutNs * 1e-6, Watchdog::kDefaultTimeoutNs / 8 * 1e-6,
      realtime ? "SCHED_FIFO 90" : "normal priority", lat.size(), skipped);
  std::printf("  tripped:                                  median %.2f, max %.2f\n",
              Percentile(trip, 0.5), Percentile(trip, 1.0));
  std::printf("  SafeStop done (command sent, reply read): median %.2f, max %.2f (goal <= 5)\n",
              Percentile(done, 0.5), Percentile(done, 1.0));
  std::printf(
      "  emulated board applied minimum tension:   median %.2f, max %.2f (includes the "
      "emulator thread's own scheduling)\n",
      Percentile(lat, 0.5), Percentile(lat, 1.0));
  return 0;
}
