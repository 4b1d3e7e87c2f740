// Starts a real rheod on an ephemeral loopback port with a temporary data dir, for integration
// tests; stops it with SIGTERM.
#pragma once

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace rheo::testing {

/// True in a sanitizer build (the daemon's tests then run it with --sim-budget 0).
constexpr bool kSanitizerBuild =
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    true;
#else
    false;
#endif

/// A running rheod child process. Its stderr is captured; the address is read from the
/// "listening on" log line, so no fixed ports and no sleeps. `--listen` among the extra
/// arguments replaces the default 127.0.0.1:0.
class RheodProcess {
 public:
  explicit RheodProcess(std::vector<std::string> extra_args = {});
  ~RheodProcess();

  bool started() const { return !address_.empty(); }
  const std::string& address() const { return address_; }
  /// The studio gateway's port (--http 127.0.0.1:0 unless the test passes --http), 0 if off.
  int http_port() const { return http_port_; }
  const std::string& data_dir() const { return data_dir_; }
  /// The child's process id (-1 once it exited and was reaped).
  int pid() const { return pid_; }
  /// A channel carrying the daemon's first admin token (DATA_DIR/admin.token).
  std::shared_ptr<grpc::Channel> channel() const;
  /// A channel carrying `token` ("" carries none).
  std::shared_ptr<grpc::Channel> channel(const std::string& token) const;
  /// The admin token rheod wrote on its first start.
  std::string admin_token() const;

  /// Sends SIGTERM and waits; returns the exit code (or 128 + signal), -1 on timeout.
  int Terminate(std::chrono::milliseconds timeout, std::chrono::milliseconds* took = nullptr);
  /// Waits for the process to exit on its own; returns as Terminate does.
  int WaitForExit(std::chrono::milliseconds timeout);
  /// Sends a signal without waiting.
  void Signal(int signo);
  /// Waits until the log contains `needle` or the timeout passes.
  bool WaitForLog(const std::string& needle, std::chrono::milliseconds timeout);
  std::string log() const;

 private:
  int pid_ = -1;
  int stderr_fd_ = -1;
  std::string data_dir_;
  bool owns_data_dir_ = false;
  std::string address_;
  int http_port_ = 0;
  std::thread reader_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::string log_;
  bool eof_ = false;
};

/// Deadline for a unary call.
inline void SetDeadline(grpc::ClientContext& ctx,
                        std::chrono::milliseconds ms = std::chrono::seconds(10)) {
  ctx.set_deadline(std::chrono::system_clock::now() + ms);
}

/// The daemon's loop rate over `window` [ticks/s], from its own tick count and uptime (two
/// GetStatus calls); `detail`, when given, gets the window's ticks, late, overrun and skipped.
double LoopTickRate(RheodProcess& d, std::chrono::milliseconds window,
                    std::string* detail = nullptr);

/// One call of any method with `request` (serialized) as its only request; a stream is cancelled
/// after its first response. The status it ended with.
grpc::Status CallRaw(const std::shared_ptr<grpc::Channel>& channel, const std::string& path,
                     const std::string& request,
                     std::chrono::milliseconds deadline = std::chrono::seconds(5));
/// CallRaw with the default (empty) request.
inline grpc::Status CallEmpty(const std::shared_ptr<grpc::Channel>& channel,
                              const std::string& path) {
  return CallRaw(channel, path, std::string());
}

/// sim-spidar-g: the emulated hand presses `depth_m` into the object under it over `seconds`
/// (DeviceService.SimulatedHand press).
grpc::Status PressHand(const RheodProcess& d, double depth_m, double seconds);

/// Stores the stroke sketch in the file at `path` (CreateObject, meshed at `resolution` [m]) and
/// returns the stored object's id ("" after a failed expectation).
std::string StoreSketchFile(const RheodProcess& d, const std::string& path, double resolution,
                            std::chrono::seconds deadline = std::chrono::seconds(180));

/// A sketch of 19,000 short random strokes in a 10-pixel disc: the densest stroke merge the
/// limits allow (about 2 s in the sketch stage), for tests that need a job that runs a while.
std::string DenseStrokeBomb();

/// A certificate authority made for one test with Debian's openssl: "ca" and "other-ca", a
/// "server" leaf for localhost and 127.0.0.1 signed by ca, a "client" leaf signed by ca and a
/// "stranger" client leaf signed by other-ca (NAME.pem and NAME.key each). Removed afterwards.
class Pki {
 public:
  Pki();
  ~Pki();
  bool ok() const { return ok_; }
  std::string operator()(const std::string& name) const;

 private:
  bool Run(std::vector<std::string> args);
  bool Ca(const std::string& n);
  bool Leaf(const std::string& n, const std::string& ca, const std::string& ext);
  std::string dir_;
  bool ok_ = false;
};

/// Runs a program and captures stdout, stderr and the exit code.
struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};
RunResult RunProgram(const std::vector<std::string>& argv);

}  // namespace rheo::testing
