// spidar-g-sim: a simulated SPIDAR-G on a pseudo-terminal, for running rheod (or any UART-board
// host) without hardware. Prints the line's stable path (a symbolic link to the pty), then the
// grip pose once a second. SIGUSR1 unplugs the line, SIGUSR2 plugs it in again (a new pty).
#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <thread>

#include "drivers/device_factory.h"
#include "drivers/spidar_emulator.h"

namespace {
volatile std::sig_atomic_t g_stop = 0;
volatile std::sig_atomic_t g_plug = 0;  // 1: unplug, 2: replug (the main loop does it)
void OnSignal(int) {
  g_stop = 1;
}
void OnPlugSignal(int signal) {
  g_plug = signal == SIGUSR1 ? 1 : 2;
}
}  // namespace

int main(int argc, char** argv) {
  using namespace rheo::drivers;
  CLI::App app{"Simulated SPIDAR-G: the open UART motor board protocol on a pseudo-terminal"};
  std::string config_path;
  std::string hand = "hold", line_path;
  double radius = 0.02, period = 4.0, seconds = 0.0;
  bool lockstep = false, no_gravity = false;
  app.add_option("-c,--config", config_path, "frame layout (drivers/config/spidar_g_*.json)")
      ->required();
  app.add_option("--hand", hand,
                 "hold: hold the grip at the centre; circle: move it in a "
                 "horizontal circle; free: let go")
      ->check(CLI::IsMember({"hold", "circle", "free"}));
  app.add_option("--radius", radius, "circle radius [m]");
  app.add_option("--period", period, "circle period [s]");
  app.add_option("--seconds", seconds, "stop after this long (0: until SIGINT/SIGTERM)");
  app.add_flag("--lockstep", lockstep, "advance 1 ms of physics per current command");
  app.add_flag("--no-gravity", no_gravity, "no gravity on the grip");
  app.add_option("--line", line_path,
                 "symbolic link to keep pointing at the present pty (default: one in a "
                 "directory of its own under the temporary directory)");
  CLI11_PARSE(app, argc, argv);

  auto config = LoadSpidarConfigFile(config_path);
  if (!config.ok()) {
    std::fprintf(stderr, "spidar-g-sim: %s\n", config.error().message.c_str());
    return 1;
  }
  EmulatorOptions options;
  options.lockstep = lockstep;
  options.line_path = line_path;
  if (no_gravity) options.gravity = rheo::Vec3::Zero();
  auto emulator = SpidarEmulator::Start(*config, options);
  if (!emulator.ok()) {
    std::fprintf(stderr, "spidar-g-sim: %s\n", emulator.error().message.c_str());
    return 2;
  }
  SpidarEmulator& e = **emulator;
  if (hand == "free") {
    e.ReleaseHand();
  } else if (hand == "circle") {
    e.ScriptHand([radius, period](double t) {
      Pose p;
      const double a = 2.0 * M_PI * t / period;
      p.position = rheo::Vec3(radius * std::cos(a) - radius, 0.0, radius * std::sin(a));
      return p;
    });
  }
  std::printf("%s\n", e.line_path().c_str());
  std::fflush(stdout);
  std::fprintf(stderr, "spidar-g-sim: %s -> %s\n", e.line_path().c_str(), e.pty_path().c_str());
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  std::signal(SIGUSR1, OnPlugSignal);
  std::signal(SIGUSR2, OnPlugSignal);
  int elapsed_ms = 0;
  while (!g_stop && (seconds <= 0.0 || elapsed_ms < seconds * 1000)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    elapsed_ms += 100;
    if (const int plug = g_plug; plug != 0) {
      g_plug = 0;
      const rheo::Status s = plug == 1 ? e.Unplug() : e.Replug();
      if (!s.ok()) {
        std::fprintf(stderr, "spidar-g-sim: %s\n", s.error().message.c_str());
      } else {
        std::fprintf(stderr, "spidar-g-sim: %s\n",
                     plug == 1 ? "unplugged" : ("plugged in: " + e.pty_path()).c_str());
      }
    }
    if (elapsed_ms % 1000 == 0) {
      const GripSnapshot s = e.Snapshot();
      std::fprintf(stderr,
                   "t=%.1f s grip at (%.1f, %.1f, %.1f) mm, string force (%.2f, %.2f, %.2f) N, "
                   "%llu commands, %llu protocol errors\n",
                   s.time, s.pose.position.x() * 1e3, s.pose.position.y() * 1e3,
                   s.pose.position.z() * 1e3, s.strings.force.x(), s.strings.force.y(),
                   s.strings.force.z(), static_cast<unsigned long long>(s.current_commands),
                   static_cast<unsigned long long>(s.protocol_errors));
    }
  }
  e.Stop();
  return 0;
}
