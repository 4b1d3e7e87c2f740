// rheod: the Rheo daemon. Owns the 1 kHz loop (and later the device and the scene), serves the
// rheo.v1 gRPC API, and shuts down cleanly on SIGINT/SIGTERM.
#include <execinfo.h>
#include <fcntl.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <malloc.h>
#include <openssl/rand.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <mutex>
#include <sstream>
#include <thread>

#include "daemon/api/decode_errors.h"
#include "daemon/api/recording_service.h"
#include "daemon/api/services.h"
#include "daemon/loop/engine.h"
#include "daemon/loop/frame_hub.h"
#include "daemon/loop/tick_cost.h"
#include "daemon/loop/tick_ring.h"
#include "daemon/net/tcp_relay.h"
#include "daemon/record/recorder.h"
#include "daemon/replay/player.h"
#include "daemon/web/gateway.h"

#ifndef RHEO_VERSION
#define RHEO_VERSION "0.0.0"
#endif

namespace {

// An exception nobody caught ends the daemon; say which, and where, before the abort (the
// default handler prints nothing a user or a CI log could act on).
[[noreturn]] void ReportUncaught() {
  std::fputs("rheod: terminating on an uncaught exception: ", stderr);
  if (std::exception_ptr e = std::current_exception()) {
    try {
      std::rethrow_exception(e);
    } catch (const std::exception& x) {
      std::fputs(x.what(), stderr);
    } catch (...) {
      std::fputs("(not a std::exception)", stderr);
    }
  } else {
    std::fputs("(none: std::terminate called directly)", stderr);
  }
  std::fputs("\n", stderr);
  void* frames[64];
  backtrace_symbols_fd(frames, backtrace(frames, 64), 2);
  std::abort();
}

struct Flags {
  std::string listen = "127.0.0.1:50051";
  std::string data_dir;
  std::string recording_dir;  // "": DATA_DIR/recordings
  std::string replay;         // a recording to play back instead of simulating
  std::string device = "none";
  std::string device_config;  // "": the X5 frame file from the install or the source tree
  std::string device_port;
  double watchdog_ms = 3.0;
  double reply_timeout_ms = 0.0;  // 0: 2 ms for hardware, 20 ms for the emulator
  double tool_radius = 3e-3;
  std::string log_level = "info";
  double rate_hz = 1000.0;
  bool realtime = true;
  int workers = 0;
  int max_jobs = 4;
  int job_timeout_s = 120;
  int64_t max_tets = 500000;
  double sim_budget_percent = 60.0;
  int64_t store_quota_mb = 4096;
  int64_t audit_keep = static_cast<int64_t>(rheo::daemon::Store::kDefaultAuditKeep);
  std::string http = "127.0.0.1:8080";  // the studio's gateway, or "off"
  std::string web_root;                 // "": clients/web of the source tree
  int http_connections = 256;
  // TLS for gRPC and the studio (wss/https); with a client CA, client certificates are required.
  std::string tls_cert, tls_key, tls_client_ca;
  bool insecure = false;  // allow plaintext on a non-loopback address
  // Per-token limits (0: none).
  double limit_calls = 10.0;  // expensive calls per second (burst: twice as many)
  int limit_streams = 64;
  int limit_jobs = 2;
  double stream_idle_s = 60.0;
};

// Holds an exclusive lock on the data directory so two daemons never share one store.
class DataDirLock {
 public:
  bool Acquire(const std::filesystem::path& dir, std::string& error) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) {
      error = "cannot create data directory " + dir.string() + ": " + ec.message();
      return false;
    }
    const std::string path = (dir / "rheod.lock").string();
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) {
      error = "cannot open " + path + ": " + std::strerror(errno);
      return false;
    }
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      error = "data directory " + dir.string() + " is in use by another rheod (lock " + path + ")";
      return false;
    }
    std::string pid = std::to_string(::getpid()) + "\n";
    if (::ftruncate(fd_, 0) != 0 || ::write(fd_, pid.data(), pid.size()) < 0) {
      // The lock is what matters; the pid is informational.
    }
    return true;
  }
  ~DataDirLock() {
    if (fd_ >= 0) ::close(fd_);
  }

 private:
  int fd_ = -1;
};

// The X5 frame file: next to an installed rheod (share/rheo/devices), else the source tree.
std::string DefaultDeviceConfig(const char* argv0) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) exe = fs::absolute(argv0, ec);
  const fs::path installed =
      exe.parent_path().parent_path() / "share/rheo/devices/spidar_g_x5.json";
  if (fs::exists(installed, ec)) return installed.string();
#ifdef RHEO_SOURCE_DEVICES
  const fs::path source = fs::path(RHEO_SOURCE_DEVICES) / "spidar_g_x5.json";
  if (fs::exists(source, ec)) return source.string();
#endif
  return installed.string();
}

// The studio's files: next to an installed rheod (share/rheo/web), else the source tree's.
std::filesystem::path DefaultWebRoot() {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  const fs::path installed = exe.parent_path().parent_path() / "share/rheo/web";
  if (!ec && fs::exists(installed / "index.html", ec)) return installed;
  return fs::path(RHEO_SOURCE_WEB);
}

// True for addresses only this machine can reach: 127.0.0.0/8, ::1, localhost, unix sockets.
bool IsLoopbackListen(const std::string& listen) {
  if (listen.rfind("unix:", 0) == 0 || listen.rfind("unix-abstract:", 0) == 0) return true;
  std::string host = listen.substr(0, listen.rfind(':'));
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

std::string ReadWhole(const std::string& path, std::string& error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = "cannot read " + path + ": " + std::strerror(errno);
    return "";
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The first admin token, readable only by this user: DATA_DIR/admin.token (mode 0600).
bool WriteTokenFile(const std::string& path, const std::string& token, std::string& error) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) {
    error = "cannot write " + path + ": " + std::strerror(errno);
    return false;
  }
  const std::string line = token + "\n";
  const bool ok = ::fchmod(fd, 0600) == 0 &&
                  ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
  if (!ok) error = "cannot write " + path + ": " + std::strerror(errno);
  ::close(fd);
  return ok;
}

std::string DefaultDataDir() {
  if (const char* x = std::getenv("XDG_DATA_HOME"); x && *x) return std::string(x) + "/rheo";
  if (const char* h = std::getenv("HOME"); h && *h) return std::string(h) + "/.local/share/rheo";
  return "./rheo-data";
}

}  // namespace

// Runs `fn` now and then every `period` on the timer's io_context while it returns true; the
// timer's cancel() ends it.
static void RunEvery(boost::asio::steady_timer& timer, std::chrono::steady_clock::duration period,
                     std::function<bool()> fn) {
  if (!fn()) return;
  timer.expires_after(period);
  timer.async_wait([&timer, period, fn = std::move(fn)](const boost::system::error_code& ec) {
    if (!ec) RunEvery(timer, period, fn);
  });
}

int main(int argc, char** argv) {
  std::set_terminate(ReportUncaught);
  // Few malloc arenas, before any thread starts: gRPC's and the gateway's handler threads each
  // get one by default (8 per core), and each keeps what it freed. Measured under load.sh
  // (4 min): anonymous RSS +12.0 MB with the default, +4.3 MB with 2 arenas.
  mallopt(M_ARENA_MAX, 2);
  Flags flags;
  CLI::App app{"rheod: the Rheo haptics daemon (sketch -> soft solid -> touch)"};
  app.set_config("--config", "", "TOML or INI file with the same keys as the long flags");
  app.add_option("--listen", flags.listen, "gRPC listen address host:port (port 0 = any free)")
      ->capture_default_str();
  app.add_option("--data-dir", flags.data_dir, "where objects and recordings are stored")
      ->default_str("$XDG_DATA_HOME/rheo");
  app.add_option("--recording-dir", flags.recording_dir,
                 "where session recordings (MCAP files) are written")
      ->default_str("DATA_DIR/recordings");
  app.add_option("--replay", flags.replay,
                 "play back this recording (.mcap) to every client at its recorded pace instead "
                 "of simulating: pause, seek and speed with rheoctl record playback; no device");
  app.add_option("--device", flags.device,
                 "haptic device: none, sim-spidar-g (the emulator behind the real driver), "
                 "spidar-g (hardware on --device-port) or network (a client's ToolStream)")
      ->check(CLI::IsMember({"none", "sim-spidar-g", "spidar-g", "network"}))
      ->capture_default_str();
  app.add_option("--device-config", flags.device_config, "SPIDAR-G frame file")
      ->default_str("share/rheo/devices/spidar_g_x5.json");
  app.add_option("--device-port", flags.device_port, "serial port of the SPIDAR-G boards");
  app.add_option("--watchdog-timeout", flags.watchdog_ms,
                 "loop stall that safe-stops the device [ms]")
      ->check(CLI::Range(0.5, 100.0))
      ->capture_default_str();
  app.add_option("--device-reply-timeout", flags.reply_timeout_ms,
                 "longest wait for a board reply [ms] (0: 2 hardware, 20 emulator)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_option("--tool-radius", flags.tool_radius, "haptic tool tip radius [m]")
      ->check(CLI::Range(1e-4, 0.05))
      ->capture_default_str();
  app.add_option("--log-level", flags.log_level, "trace, debug, info, warn, error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
      ->capture_default_str();
  app.add_option("--rate", flags.rate_hz, "loop rate [Hz]")
      ->check(CLI::Range(100.0, 4000.0))
      ->capture_default_str();
  app.add_option("--workers", flags.workers, "mesh worker threads (0 = cores - 1, at least 1)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  app.add_option("--max-jobs", flags.max_jobs, "mesh jobs in flight (queued + running)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--job-timeout", flags.job_timeout_s, "longest a mesh job may run [s]")
      ->check(CLI::Range(1, 3600))
      ->capture_default_str();
  app.add_option("--max-tets", flags.max_tets, "largest tetrahedral mesh an object may have")
      ->check(CLI::Range(int64_t{1000}, int64_t{10000000}))
      ->capture_default_str();
  app.add_option("--audit-keep", flags.audit_keep,
                 "audit rows kept of the state-changing calls, newest first (0 = all)")
      ->check(CLI::Range(int64_t{0}, int64_t{1} << 40))
      ->capture_default_str();
  app.add_option("--store-quota", flags.store_quota_mb,
                 "most the stored objects may take in all [MB]; creating one past it is refused")
      ->check(CLI::Range(int64_t{1}, int64_t{1} << 24))
      ->capture_default_str();
  app.add_option("--sim-budget", flags.sim_budget_percent,
                 "share of each tick the scene's simulation may take [%]; a scene change or "
                 "parameter set predicted to need more is refused. 0: no admission by cost "
                 "(offline runs, or builds far slower than the loop's rate, e.g. a sanitizer's)")
      ->check(CLI::Validator(
          [](std::string& v) -> std::string {
            double x = -1.0;
            try {
              x = std::stod(v);
            } catch (const std::exception&) {
            }
            return x == 0.0 || (x >= 5.0 && x <= 95.0) ? std::string()
                                                       : "must be 0 (off) or in [5, 95], got " + v;
          },
          "0 or [5, 95]"))
      ->capture_default_str();
  app.add_flag("!--no-realtime", flags.realtime, "do not ask for SCHED_FIFO and locked memory");
  app.add_option("--http", flags.http,
                 "the browser studio and its WebSocket: host:port (port 0 = any free) or off")
      ->capture_default_str();
  app.add_option("--web-root", flags.web_root,
                 "the studio's files (default: share/rheo/web of the install, else clients/web of "
                 "the source tree)");
  app.add_option("--http-connections", flags.http_connections,
                 "most WebSocket connections (studio pages and viewers) at once")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--tls-cert", flags.tls_cert,
                 "PEM certificate (chain) for gRPC and the studio (https/wss); needs --tls-key");
  app.add_option("--tls-key", flags.tls_key, "PEM private key of --tls-cert");
  app.add_option("--tls-client-ca", flags.tls_client_ca,
                 "PEM CA: clients must present a certificate it signed (mutual TLS)");
  app.add_option("--limit-calls", flags.limit_calls,
                 "calls per second per token to each expensive method (CreateObject, "
                 "ExtractContour, AddToScene, ExportObject, ExportRecording), twice as many in "
                 "a burst; 0: no "
                 "limit")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  app.add_option("--limit-streams", flags.limit_streams,
                 "open streams (frame watchers, tool streams, builds, exports) per token; 0: no "
                 "limit")
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  app.add_option("--limit-jobs", flags.limit_jobs, "mesh jobs per token at once; 0: no limit")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_option("--stream-idle", flags.stream_idle_s,
                 "a stream whose client neither reads nor writes this long is ended [s]; 0: never")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  app.add_flag("--insecure", flags.insecure,
               "allow plaintext on a non-loopback --listen or --http (tokens then cross the "
               "network readable; warned every minute)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  // SIGINT and SIGTERM are caught from here on (and queued until the shutdown handler waits for
  // them below), so a signal during start-up still shuts down in order and exits 0.
  boost::asio::io_context io;
  boost::asio::signal_set signals(io, SIGINT, SIGTERM);

  auto logger = spdlog::stderr_color_mt("rheod");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(flags.log_level));
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");

  if (flags.data_dir.empty()) flags.data_dir = DefaultDataDir();
  DataDirLock lock;
  if (std::string err; !lock.Acquire(flags.data_dir, err)) {
    spdlog::error("{}", err);
    return 1;
  }

  using namespace rheo::daemon;
  const std::string db_path = (std::filesystem::path(flags.data_dir) / "objects.db").string();
  auto store = Store::Open(db_path, static_cast<uint64_t>(flags.store_quota_mb) << 20);
  if (!store.ok()) {
    spdlog::error("{}", store.error().message);
    return 1;
  }
  (*store)->set_audit_keep(static_cast<uint64_t>(flags.audit_keep));
  auto stored = (*store)->Count();
  spdlog::info("object store {} holds {} objects, {:.1f} of {} MB", db_path,
               stored.ok() ? *stored : 0, static_cast<double>((*store)->used_bytes()) / 1e6,
               flags.store_quota_mb);
  // Who may do what: the tokens (hashes) are in the store. A first start writes an admin token
  // that only this user can read, so local use stays one command.
  TokenRegistry tokens(store->get());
  if (rheo::Status s = tokens.Load(); !s.ok()) {
    spdlog::error("{}", s.error().message);
    return 1;
  }
  const std::string admin_token_path =
      (std::filesystem::path(flags.data_dir) / "admin.token").string();
  if (tokens.empty()) {
    auto made = tokens.Create("admin", Role::kAdmin, 0.0);
    std::string err;
    if (!made.ok() || !WriteTokenFile(admin_token_path, made->token, err)) {
      spdlog::error("cannot make the first admin token: {}",
                    made.ok() ? err : made.error().message);
      return 1;
    }
    spdlog::info(
        "first start: wrote the admin token to {} (mode 0600); rheoctl on this machine reads it, "
        "and `rheoctl token create --role viewer|operator|admin` makes tokens for others",
        admin_token_path);
  } else if (std::filesystem::exists(admin_token_path)) {
    spdlog::info("admin token in {}", admin_token_path);
  }

  // TLS: read once, for gRPC and the studio.
  const bool tls = !flags.tls_cert.empty() || !flags.tls_key.empty();
  std::string tls_cert_pem, tls_key_pem, tls_ca_pem;
  if (tls) {
    std::string err;
    if (flags.tls_cert.empty() || flags.tls_key.empty()) {
      spdlog::error("TLS needs both --tls-cert FILE and --tls-key FILE");
      return 1;
    }
    tls_cert_pem = ReadWhole(flags.tls_cert, err);
    if (err.empty()) tls_key_pem = ReadWhole(flags.tls_key, err);
    if (err.empty() && !flags.tls_client_ca.empty())
      tls_ca_pem = ReadWhole(flags.tls_client_ca, err);
    if (!err.empty()) {
      spdlog::error("{}", err);
      return 1;
    }
  } else if (!flags.tls_client_ca.empty()) {
    spdlog::error("--tls-client-ca needs --tls-cert and --tls-key (mutual TLS is TLS)");
    return 1;
  }
  for (const auto& [flag, address] :
       {std::pair<const char*, std::string>{"--listen", flags.listen}, {"--http", flags.http}}) {
    // TLS covers both: gRPC and the studio's gateway (https and wss).
    if (address == "off" || tls || IsLoopbackListen(address)) continue;
    if (!flags.insecure) {
      spdlog::error(
          "{} {} is not a loopback address and there is no TLS: tokens and every sketch would "
          "cross the network in plaintext. Give a certificate (--tls-cert server.pem --tls-key "
          "server.key; docs/security.md shows how to make one), listen on 127.0.0.1, or accept "
          "the risk with --insecure",
          flag, address);
      return 1;
    }
  }

  const int workers = flags.workers > 0
                          ? flags.workers
                          : std::max(1, static_cast<int>(std::thread::hardware_concurrency()) - 1);
  JobPool<JobEvent> jobs(workers, flags.max_jobs,
                         [](rheo::Error e) { return JobEvent::Failed(std::move(e)); });

  if (!flags.replay.empty() && flags.device != "none") {
    spdlog::error(
        "--replay plays a recording back without a device (the hand in it is the recorded one); "
        "leave out --device {}",
        flags.device);
    return 1;
  }
  // The device is opened and calibrated before the loop starts; the loop then owns its ticks.
  std::unique_ptr<DeviceLink> device;
  rheo::v1::DeviceKind device_kind = rheo::v1::DEVICE_KIND_NONE;
  if (flags.device != "none") {
    DeviceLinkOptions dopts;
    if (flags.device == "sim-spidar-g") {
      dopts.kind = DeviceKind::kSimSpidarG;
      device_kind = rheo::v1::DEVICE_KIND_SIM_SPIDAR_G;
    } else if (flags.device == "spidar-g") {
      dopts.kind = DeviceKind::kSpidarG;
      device_kind = rheo::v1::DEVICE_KIND_SPIDAR_G;
    } else {
      dopts.kind = DeviceKind::kNetwork;
      device_kind = rheo::v1::DEVICE_KIND_NETWORK;
    }
    dopts.config_path =
        flags.device_config.empty() ? DefaultDeviceConfig(argv[0]) : flags.device_config;
    dopts.port = flags.device_port;
    dopts.watchdog_timeout_ns = static_cast<int64_t>(flags.watchdog_ms * 1e6);
    const double reply_ms = flags.reply_timeout_ms > 0              ? flags.reply_timeout_ms
                            : dopts.kind == DeviceKind::kSimSpidarG ? 20.0
                                                                    : 2.0;
    dopts.reply_timeout_us = static_cast<int>(reply_ms * 1e3);
    dopts.realtime = flags.realtime;
    dopts.tool_radius = flags.tool_radius;
    // The reopener's thread says when the serial line goes and comes back (never the loop).
    dopts.log = [device = flags.device](const std::string& line) {
      spdlog::warn("device {}: {}", device, line);
    };
    auto opened = DeviceLink::Open(dopts);
    if (!opened.ok()) {
      spdlog::error("device {}: {}", flags.device, opened.error().message);
      return 1;
    }
    device = std::move(opened).value();
    spdlog::info(
        "device {}: {} ({}) calibrated{}{}; watchdog {:.1f} ms{}; coupling stiffness {:.0f} N/m, "
        "tool radius {:.1f} mm, max force {:.1f} N",
        flags.device, device->info().name, device->info().model,
        dopts.kind == DeviceKind::kNetwork ? "" : ", frame file ",
        dopts.kind == DeviceKind::kNetwork ? "" : dopts.config_path, flags.watchdog_ms,
        dopts.kind == DeviceKind::kNetwork ? " (not used: no motors)" : "",
        device->effective_stiffness(), dopts.tool_radius * 1e3, device->info().max_force);
  }
  LeaseManager leases;

  EngineOptions eopts;
  eopts.loop.period_ns = static_cast<int64_t>(1e9 / flags.rate_hz);
  eopts.loop.realtime_priority = flags.realtime;
  eopts.loop.lock_memory = flags.realtime;
  Engine engine(eopts);
  if (device) engine.AttachDevice(device.get());
  // Session recording: the loop offers each tick to this ring while a recording runs (about
  // 4 MiB, allocated here, before the loop starts and locks its memory).
  auto tick_ring = std::make_unique<TickRing>();
  engine.AttachTickRing(tick_ring.get());
  // Admission by cost: the tick's cost on this machine, measured before the loop starts (on a
  // quiet core rather than beside it).
  const rheo::sim::CostCoefficients tick_cost = rheo::daemon::MeasureTickCost();
  engine.Start();
  const auto& env = engine.loop().environment();
  spdlog::info("loop running at {:.0f} Hz (SCHED_FIFO {}, memory locked {})", flags.rate_hz,
               env.realtime ? "yes" : "no", env.memory_locked ? "yes" : "no");
  if (!env.notes.empty()) spdlog::warn("loop: {}", env.notes);

  SceneRegistry scene;
  FrameHub hub(engine);
  // --replay: the player, not the loop, fills the frame hub, and the scene registry holds the
  // objects of the frame it shows.
  std::unique_ptr<RecordingPlayer> player;
  if (!flags.replay.empty()) {
    auto opened = RecordingPlayer::Open(
        flags.replay, hub, [&scene](const std::vector<const rheo::v1::SceneEvent*>& objects) {
          for (const auto& e : scene.All()) {
            bool keep = false;
            for (const auto* ev : objects)
              keep = keep || ev->object().instance_id() == e->instance_id;
            if (!keep) scene.Erase(e->instance_id);
          }
          for (const auto* ev : objects)
            if (!scene.Find(ev->object().instance_id())) scene.Put(EntryFromSceneEvent(*ev));
        });
    if (!opened.ok()) {
      spdlog::error("--replay {}: {}", flags.replay, opened.error().message);
      engine.Stop();
      return 1;
    }
    player = std::move(opened).value();
    const auto st = player->state();
    spdlog::info("playing back {}: {} frames over {:.1f} s", flags.replay, st.frames,
                 st.duration_s);
    player->Start();
  } else {
    hub.Start();
  }

  std::atomic<bool> shutting_down{false};
  DaemonContext ctx;
  ctx.engine = &engine;
  ctx.hub = &hub;
  ctx.version = RHEO_VERSION;
  ctx.data_dir = flags.data_dir;
  ctx.device = device_kind;
  ctx.device_link = device.get();
  ctx.leases = &leases;
  ctx.tokens = &tokens;
  QuotaLimits quota_limits;
  quota_limits.calls_per_s = flags.limit_calls;
  quota_limits.burst = 2.0 * flags.limit_calls;
  quota_limits.streams = flags.limit_streams;
  quota_limits.jobs = flags.limit_jobs;
  quota_limits.stream_idle = std::chrono::milliseconds(std::llround(flags.stream_idle_s * 1e3));
  Quotas quotas(quota_limits);
  ctx.quotas = &quotas;
  ctx.started = std::chrono::steady_clock::now();
  ctx.shutting_down = &shutting_down;
  ctx.store = store->get();
  ctx.scene = &scene;
  ctx.jobs = &jobs;
  ctx.build_limits.max_tets = flags.max_tets;
  ctx.job_timeout = std::chrono::seconds(flags.job_timeout_s);
  ctx.tick_cost = tick_cost;
  ctx.sim_budget_ns = flags.sim_budget_percent > 0.0
                          ? flags.sim_budget_percent * 1e-2 * 1e9 / flags.rate_hz
                          : std::numeric_limits<double>::infinity();
  // The session recorder: its files are listed (each opened with the MCAP reader) before the
  // server starts, so ListRecordings sees them from the first call.
  RecorderOptions recorder_options;
  recorder_options.dir = flags.recording_dir.empty()
                             ? (std::filesystem::path(flags.data_dir) / "recordings").string()
                             : flags.recording_dir;
  recorder_options.library = std::string("rheod ") + RHEO_VERSION;
  recorder_options.fill_frame = [&ctx](const LoopFrame& f, bool topology, rheo::v1::Frame* out) {
    FillFrame(ctx, f, {topology, /*positions=*/true, /*quantized=*/false}, out);
  };
  recorder_options.fill_loop_status = [&ctx](rheo::v1::LoopStatus* out) {
    FillLoopStatus(ctx, out);
  };
  Recorder recorder(engine, hub, *tick_ring, recorder_options);
  const auto found = recorder.Load();
  if (!found.ok()) {
    spdlog::error("{}; choose another --recording-dir", found.error().message);
    hub.Stop();
    engine.Stop();
    return 1;
  }
  spdlog::info("recordings in {}: {}", recorder_options.dir, *found);
  ctx.recorder = &recorder;
  ctx.player = player.get();
  spdlog::info(
      "tick cost model: {:.2f} ns per element and explicit substep, {:.2f} per implicit substep, "
      "{:.2f} per CG iteration, {:.1f} and {:.1f} more per tetrahedron in the linear system; {}",
      ctx.tick_cost.explicit_ns, ctx.tick_cost.implicit_ns, ctx.tick_cost.cg_ns,
      ctx.tick_cost.system_ns, ctx.tick_cost.system_cg_ns,
      flags.sim_budget_percent > 0.0
          ? fmt::format("the simulation may take {:.0f} us of each tick", ctx.sim_budget_ns * 1e-3)
          : std::string("no admission by cost (--sim-budget 0)"));

  AuthServiceImpl auth_service(ctx);
  DaemonServiceImpl daemon_service(ctx);
  FrameServiceImpl frame_service(ctx);
  SceneServiceImpl scene_service(ctx);
  ObjectServiceImpl object_service(ctx);
  DeviceServiceImpl device_service(ctx);
  RecordingServiceImpl recording_service(ctx);

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  int port = 0;
  // Every port checks every call against the role table (AuthProcessor) before any handler:
  // TLS when given, else local credentials (loopback only: gRPC refuses other peers). gRPC
  // cannot check tokens on plaintext credentials, so --insecure on a non-loopback address is a
  // relay onto a local port (below), never an unchecked one.
  auto processor = std::make_shared<AuthProcessor>(tokens, store->get(), &quotas);
  SetCallerTokens(&tokens);
  auto port_credentials = [&](bool local_tcp) {
    std::shared_ptr<grpc::ServerCredentials> creds;
    if (tls && local_tcp) {
      grpc::SslServerCredentialsOptions ssl(
          tls_ca_pem.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                             : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
      ssl.pem_root_certs = tls_ca_pem;
      ssl.pem_key_cert_pairs.push_back({tls_key_pem, tls_cert_pem});
      creds = grpc::SslServerCredentials(ssl);
    } else {
      creds = grpc::experimental::LocalServerCredentials(local_tcp ? LOCAL_TCP : UDS);
    }
    creds->SetAuthMetadataProcessor(processor);
    return creds;
  };
  const bool relay_insecure = !tls && !IsLoopbackListen(flags.listen);
  builder.AddListeningPort(relay_insecure ? std::string("127.0.0.1:0") : flags.listen,
                           port_credentials(true), &port);
  // The studio's gateway calls the API as a client of this server, on a socket of its own that
  // checks tokens as every port does (an abstract unix socket: nothing on disk to clean up).
  std::string gateway_socket;
  {
    unsigned char r[8];
    RAND_bytes(r, sizeof r);
    char name[64];
    std::snprintf(name, sizeof name, "unix-abstract:rheod-%d-%02x%02x%02x%02x%02x%02x%02x%02x",
                  static_cast<int>(::getpid()), r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7]);
    gateway_socket = name;
  }
  if (flags.http != "off") builder.AddListeningPort(gateway_socket, port_credentials(false));
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.SetMaxReceiveMessageSize(static_cast<int>(rheo::daemon::kMaxSketchRequestBytes));
  // Keepalive: rheod pings a connection idle for 30 s and drops it when no answer comes in 10 s
  // (a vanished client's streams end); clients may ping every 10 s, with or without calls.
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 30'000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 10'000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 10'000);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  builder.RegisterService(&auth_service);
  builder.RegisterService(&daemon_service);
  builder.RegisterService(&frame_service);
  builder.RegisterService(&scene_service);
  builder.RegisterService(&object_service);
  builder.RegisterService(&device_service);
  builder.RegisterService(&recording_service);
  {
    // Undecodable requests: INVALID_ARGUMENT naming the expected message, not an empty INTERNAL.
    std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> chain;
    chain.push_back(std::make_unique<DecodeErrorInterceptorFactory>());
    chain.push_back(std::make_unique<AuditInterceptorFactory>(store->get()));
    // Scene and device commands into the running recording (/commands).
    chain.push_back(std::make_unique<RecordingInterceptorFactory>(&recorder));
    builder.experimental().SetInterceptorCreators(std::move(chain));
  }
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    spdlog::error(
        "cannot listen on {}: the address is in use (another rheod or another program holds "
        "the port) or invalid; choose another --listen host:port",
        flags.listen);
    hub.Stop();
    engine.Stop();
    return 1;
  }
  std::string host = flags.listen.substr(0, flags.listen.rfind(':'));
  // --insecure on a non-loopback address: plaintext clients reach the checked local port
  // through a relay (tokens are still checked; they cross the network readable).
  std::unique_ptr<rheo::daemon::net::TcpRelay> relay;
  if (relay_insecure) {
    relay = std::make_unique<rheo::daemon::net::TcpRelay>(flags.listen,
                                                          "127.0.0.1:" + std::to_string(port));
    if (std::string err = relay->Start(); !err.empty()) {
      spdlog::error("{}; choose another --listen host:port", err);
      server->Shutdown(std::chrono::system_clock::now());
      hub.Stop();
      engine.Stop();
      return 1;
    }
    port = relay->port();
  }
  ctx.listen_address = host + ":" + std::to_string(port);
  spdlog::info("rheod {} listening on {} (data dir {}, device {}, {})", RHEO_VERSION,
               ctx.listen_address, flags.data_dir, flags.device,
               tls ? (tls_ca_pem.empty() ? "TLS" : "mutual TLS")
                   : (relay_insecure ? "PLAINTEXT (--insecure)" : "loopback only"));

  // The studio: its files and the WebSocket bridge onto this server's own API (a gRPC client of
  // the gateway socket, so every token check, limit, validation and status code is the gRPC one).
  std::unique_ptr<rheo::daemon::web::Gateway> gateway;
  if (flags.http != "off") {
    rheo::daemon::web::GatewayOptions web;
    web.address = flags.http;
    web.web_root =
        flags.web_root.empty() ? DefaultWebRoot() : std::filesystem::path(flags.web_root);
    web.max_connections = flags.http_connections;
    web.tls_cert_pem = tls_cert_pem;  // https and wss with the same certificate as gRPC
    web.tls_key_pem = tls_key_pem;
    web.tls_client_ca_pem = tls_ca_pem;
    grpc::ChannelArguments channel_args;
    channel_args.SetMaxReceiveMessageSize(64 << 20);
    // A slow page must hold back its own stream at the daemon (whose frame service then skips
    // frames), not queue them in this channel: a small HTTP/2 window, never grown by BDP probes.
    channel_args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
    channel_args.SetInt(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, 16 * 1024);
    gateway = std::make_unique<rheo::daemon::web::Gateway>(
        web, grpc::CreateCustomChannel(gateway_socket, grpc::experimental::LocalCredentials(UDS),
                                       channel_args));
    if (grpc::Status s = gateway->Start(); !s.ok()) {
      spdlog::error("{}", s.error_message());
      server->Shutdown(std::chrono::system_clock::now());
      hub.Stop();
      engine.Stop();
      return 1;
    }
    if (!std::filesystem::exists(web.web_root / "index.html"))
      spdlog::warn("the studio's files are not in {} (no index.html); pass --web-root clients/web",
                   web.web_root.string());
    else if (!std::filesystem::exists(web.web_root / "node_modules" / "three"))
      spdlog::warn(
          "three.js is not installed in {}: run `npm ci` there (scripts/install-deps "
          "does), or the 3D view will not load",
          web.web_root.string());
    std::string web_host = flags.http.substr(0, flags.http.rfind(':'));
    const char* scheme = tls ? "https" : "http";
    spdlog::info("studio at {}://{}:{}/ (watch-only viewers: {}://{}:{}/?view){}", scheme, web_host,
                 gateway->port(), scheme, web_host, gateway->port(),
                 tls ? (tls_ca_pem.empty() ? " over TLS" : " over mutual TLS") : "");
  }
  // Plaintext where others can listen: said once a minute, so nobody forgets it is on.
  boost::asio::steady_timer insecure_warning(io);
  RunEvery(insecure_warning, std::chrono::minutes(1), [&] {
    std::string where;
    if (relay_insecure) where = "--listen " + flags.listen;
    if (!tls && flags.http != "off" && !IsLoopbackListen(flags.http))
      where += (where.empty() ? "" : " and ") + std::string("--http ") + flags.http;
    if (where.empty()) return false;
    spdlog::warn(
        "--insecure: {} serve plaintext on a non-loopback address; tokens, sketches and frames "
        "cross the network readable (give --tls-cert/--tls-key instead)",
        where);
    return true;
  });
  // Streams whose clients stalled (a write that cannot complete, a tool stream gone quiet) are
  // ended, checked once a second; each such end is logged and counted in GetStatus.
  boost::asio::steady_timer idle_reaper(io);
  if (flags.stream_idle_s > 0) {
    RunEvery(idle_reaper, std::chrono::seconds(1), [&] {
      if (int n = quotas.CancelIdle(); n > 0)
        spdlog::warn("ended {} stream(s) idle for more than {:.0f} s (--stream-idle)", n,
                     flags.stream_idle_s);
      return true;
    });
  }
  // Memory the handlers freed goes back to the system every 10 s (glibc keeps freed pages of
  // its per-thread arenas otherwise; under a lab's load the RSS crept up by 0.7 MB a minute with
  // a flat heap). Off the loop, which never allocates.
  boost::asio::steady_timer trimmer(io);
  RunEvery(trimmer, std::chrono::seconds(10), [] {
    malloc_trim(0);
    return true;
  });

  // Shutdown, in the safe order and bounded: the device to minimum tension first, then the mesh
  // jobs are cancelled, the server and the loop stop. A job or a handler that does not stop in
  // time is not waited for: past kHardStop the process leaves anyway (the device is already at
  // minimum tension, and every stored object is one transaction, so nothing is half-written).
  constexpr auto kServerGrace = std::chrono::milliseconds(500);
  constexpr auto kJobsGrace = std::chrono::milliseconds(1000);
  constexpr auto kHardStop = std::chrono::milliseconds(1900);
  std::chrono::steady_clock::time_point signalled{};
  std::mutex stop_mutex;
  std::condition_variable stop_cv;
  bool stopped = false;
  std::thread hard_stop;
  signals.async_wait([&](const boost::system::error_code&, int signo) {
    signalled = std::chrono::steady_clock::now();
    spdlog::info("signal {} received, shutting down", signo);
    shutting_down.store(true);
    if (device) {
      device->EmergencyStop();  // every motor to minimum tension before anything else
      spdlog::info("device {}: every motor to minimum tension", flags.device);
    }
    hard_stop = std::thread([&, t0 = signalled] {
      std::unique_lock<std::mutex> l(stop_mutex);
      if (stop_cv.wait_until(l, t0 + kHardStop, [&] { return stopped; })) return;
      spdlog::error(
          "shutdown did not finish within {} ms (a request or a job does not stop); the device "
          "is at minimum tension, exiting now",
          kHardStop.count());
      spdlog::default_logger()->flush();
      std::_Exit(0);
    });
    insecure_warning.cancel();
    trimmer.cancel();
    idle_reaper.cancel();
    if (relay) relay->Stop();
    jobs.CancelAll();  // running mesh jobs are asked to stop
    // A running recording is closed (its last chunk, summary and footer written) while the
    // loop, the hub and the services still run; no new one starts.
    if (auto r = recorder.Shutdown())
      spdlog::info("recording {} closed on shutdown: {:.1f} s, {} bytes, {}", r->id(),
                   r->duration_s(), r->bytes(), r->file());
    if (gateway) gateway->Stop();  // studio pages: their calls cancelled, connections closed
    server->GetHealthCheckService()->SetServingStatus(false);
    hub.Stop();  // open frame streams end with UNAVAILABLE
    server->Shutdown(std::chrono::system_clock::now() + kServerGrace);
  });
  io.run();
  server->Wait();
  engine.Stop();
  if (device) {
    const std::string last = device->Shutdown();
    spdlog::info("device {} safe-stopped and closed", flags.device);
    if (!last.empty()) spdlog::info("{}", last);
  }
  const auto& s = engine.loop().stats();
  spdlog::info("stopped after {} ticks ({} late, period p99 {:.1f} us)", s.ticks.load(),
               s.late_ticks.load(), s.period.Quantile(0.99) / 1e3);
  const int running = jobs.in_flight();
  if (!jobs.Shutdown(signalled + kJobsGrace)) {
    spdlog::warn(
        "{} mesh job(s) still running after the cancel; exiting without waiting for them "
        "(each stored object is one transaction: nothing half-written is kept)",
        running);
    spdlog::default_logger()->flush();
    std::_Exit(0);  // a worker is still running: destroying the pool would wait for it
  }
  {
    std::lock_guard<std::mutex> l(stop_mutex);
    stopped = true;
  }
  stop_cv.notify_all();
  if (hard_stop.joinable()) hard_stop.join();
  return 0;
}
