#include "rheod_fixture.h"

#include <fcntl.h>
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "rheo/client/channel.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/device.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"

extern char** environ;

namespace rheo::testing {
namespace {

std::vector<char*> Argv(const std::vector<std::string>& args) {
  std::vector<char*> v;
  for (const auto& a : args) v.push_back(const_cast<char*>(a.c_str()));
  v.push_back(nullptr);
  return v;
}

std::string MakeTempDir() {
  std::string tmpl = (std::filesystem::temp_directory_path() / "rheod-test-XXXXXX").string();
  char* p = mkdtemp(tmpl.data());
  return p ? std::string(p) : std::string();
}

int WaitExit(int pid, std::chrono::milliseconds timeout) {
  auto end = std::chrono::steady_clock::now() + timeout;
  while (true) {
    int status = 0;
    int r = waitpid(pid, &status, WNOHANG);
    if (r == pid) {
      if (WIFEXITED(status)) return WEXITSTATUS(status);
      if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
      return -1;
    }
    if (std::chrono::steady_clock::now() > end) return -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // polling a child's exit
  }
}

}  // namespace

RheodProcess::RheodProcess(std::vector<std::string> extra_args) {
  std::vector<std::string> args = {RHEOD_PATH, "--log-level", "debug"};
  if (std::find(extra_args.begin(), extra_args.end(), "--listen") == extra_args.end())
    args.insert(args.end(), {"--listen", "127.0.0.1:0"});
  auto http = std::find(extra_args.begin(), extra_args.end(), "--http");
  const bool http_on =
      http == extra_args.end() || http + 1 == extra_args.end() || *(http + 1) != "off";
  if (http == extra_args.end()) args.insert(args.end(), {"--http", "127.0.0.1:0"});
  auto given = std::find(extra_args.begin(), extra_args.end(), "--data-dir");
  if (given != extra_args.end() && given + 1 != extra_args.end()) {
    data_dir_ = *(given + 1);  // the caller's: not removed afterwards
  } else {
    data_dir_ = MakeTempDir();
    owns_data_dir_ = true;
    args.insert(args.end(), {"--data-dir", data_dir_});
  }
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  // A sanitizer build simulates about 30 times slower than the optimised one, and the daemon's
  // cost model measures exactly that: it would refuse the tests' objects as too slow for the
  // tick. These builds are for memory and threading errors; they run without admission by cost
  // unless a test asks for a budget itself.
  if (std::find(extra_args.begin(), extra_args.end(), "--sim-budget") == extra_args.end())
    args.insert(args.end(), {"--sim-budget", "0"});
  // The emulator's board answers in well under a millisecond, but a sanitizer build beside the
  // other tests has been seen to miss the emulator's 20 ms reply timeout at start-up.
  if (std::find(extra_args.begin(), extra_args.end(), "--device-reply-timeout") == extra_args.end())
    args.insert(args.end(), {"--device-reply-timeout", "100"});
#endif
  args.insert(args.end(), extra_args.begin(), extra_args.end());
  int pipefd[2];
  if (pipe2(pipefd, O_CLOEXEC) != 0) return;
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, pipefd[1], 2);
  auto argv = Argv(args);
  if (posix_spawn(&pid_, args[0].c_str(), &fa, nullptr, argv.data(), environ) != 0) pid_ = -1;
  posix_spawn_file_actions_destroy(&fa);
  close(pipefd[1]);
  stderr_fd_ = pipefd[0];
  reader_ = std::thread([this] {
    char buf[4096];
    while (true) {
      ssize_t n = read(stderr_fd_, buf, sizeof buf);
      std::lock_guard<std::mutex> lock(mutex_);
      if (n <= 0) {
        eof_ = true;
        cv_.notify_all();
        return;
      }
      log_.append(buf, static_cast<size_t>(n));
      cv_.notify_all();
    }
  });
  if (pid_ < 0) return;
  if (!WaitForLog("listening on", std::chrono::seconds(60))) return;
  std::string l = log();
  size_t at = l.find("listening on 127.0.0.1:");
  if (at != std::string::npos) {
    size_t start = at + std::string("listening on ").size();
    size_t end = l.find_first_not_of("0123456789.:", start);
    address_ = l.substr(start, end - start);
  }
  if (http_on && !address_.empty() && WaitForLog("studio at http", std::chrono::seconds(10))) {
    l = log();
    at = l.find("://", l.find("studio at http"));  // http:// or https://
    size_t colon = at == std::string::npos ? at : l.find(':', at + 3);
    if (colon != std::string::npos) http_port_ = std::atoi(l.c_str() + colon + 1);
  }
}

RheodProcess::~RheodProcess() {
  if (pid_ > 0) {
    kill(pid_, SIGKILL);
    WaitExit(pid_, std::chrono::seconds(5));
  }
  if (reader_.joinable()) reader_.join();
  if (stderr_fd_ >= 0) close(stderr_fd_);
  // A failed test shows what its daemon said (a crash's message and backtrace among it).
  if (::testing::Test::HasFailure())
    std::fprintf(stderr, "--- rheod's log ---\n%s\n", log().c_str());
  std::error_code ec;
  if (owns_data_dir_ && !data_dir_.empty()) std::filesystem::remove_all(data_dir_, ec);
}

std::shared_ptr<grpc::Channel> RheodProcess::channel() const {
  return channel(admin_token());
}

std::shared_ptr<grpc::Channel> RheodProcess::channel(const std::string& token) const {
  rheo::client::ChannelOptions o;
  o.target = address_;
  o.token = token;
  return rheo::client::Connect(o, nullptr);
}

std::string RheodProcess::admin_token() const {
  return rheo::client::ReadTokenFile(data_dir_ + "/admin.token", nullptr);
}

bool RheodProcess::WaitForLog(const std::string& needle, std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  return cv_.wait_for(lock, timeout, [&] {
    return eof_ || log_.find(needle) != std::string::npos;
  }) && log_.find(needle) != std::string::npos;
}

std::string RheodProcess::log() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return log_;
}

int RheodProcess::WaitForExit(std::chrono::milliseconds timeout) {
  if (pid_ <= 0) return -1;
  int code = WaitExit(pid_, timeout);
  if (code != -1) pid_ = -1;
  return code;
}

void RheodProcess::Signal(int signo) {
  if (pid_ > 0) kill(pid_, signo);
}

int RheodProcess::Terminate(std::chrono::milliseconds timeout, std::chrono::milliseconds* took) {
  if (pid_ <= 0) return -1;
  auto t0 = std::chrono::steady_clock::now();
  kill(pid_, SIGTERM);
  int code = WaitExit(pid_, timeout);
  if (took)
    *took = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() -
                                                                  t0);
  if (code != -1) pid_ = -1;
  return code;
}

grpc::Status CallRaw(const std::shared_ptr<grpc::Channel>& channel, const std::string& path,
                     const std::string& request, std::chrono::milliseconds deadline) {
  grpc::GenericStub stub(channel);
  grpc::ClientContext ctx;
  SetDeadline(ctx, deadline);
  grpc::CompletionQueue cq;
  auto call = stub.PrepareCall(&ctx, path, &cq);
  void* tag;
  bool ok;
  auto step = [&](int want) {
    EXPECT_TRUE(cq.Next(&tag, &ok));
    EXPECT_EQ(tag, reinterpret_cast<void*>(want));
    return ok;
  };
  call->StartCall(reinterpret_cast<void*>(1));
  step(1);
  grpc::Slice bytes(request);
  grpc::ByteBuffer buffer(&bytes, 1);
  call->Write(buffer, reinterpret_cast<void*>(2));
  step(2);
  call->WritesDone(reinterpret_cast<void*>(3));
  step(3);
  grpc::ByteBuffer reply;
  call->Read(&reply, reinterpret_cast<void*>(4));
  if (step(4)) ctx.TryCancel();  // a stream: its first response is enough
  grpc::Status status;
  call->Finish(&status, reinterpret_cast<void*>(5));
  step(5);
  return status;
}

grpc::Status PressHand(const RheodProcess& d, double depth_m, double seconds) {
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::SimulatedHandRequest req;
  req.mutable_press()->set_depth_m(depth_m);
  req.mutable_press()->set_seconds(seconds);
  v1::SimulatedHandResponse r;
  return v1::DeviceService::NewStub(d.channel())->SimulatedHand(&ctx, req, &r);
}

std::string StoreSketchFile(const RheodProcess& d, const std::string& path, double resolution,
                            std::chrono::seconds deadline) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << "cannot read " << path;
  std::stringstream text;
  text << in.rdbuf();
  auto objects = v1::ObjectService::NewStub(d.channel());
  v1::CreateObjectRequest req;
  req.set_name(std::filesystem::path(path).stem().string());
  req.mutable_sketch()->set_strokes_json(text.str());
  req.mutable_mesh_options()->set_resolution(resolution);
  grpc::ClientContext ctx;
  SetDeadline(ctx, deadline);
  auto reader = objects->CreateObject(&ctx, req);
  v1::CreateObjectProgress p;
  std::string id;
  while (reader->Read(&p))
    if (p.has_object()) id = p.object().id();
  grpc::Status s = reader->Finish();
  EXPECT_TRUE(s.ok()) << s.error_message();
  return id;
}

std::string DenseStrokeBomb() {
  std::mt19937 rng(11);
  auto u = [&] { return rng() / 4294967296.0; };
  std::string j = "{\"width\":512,\"height\":512,\"strokes\":[";
  char b[64];
  for (int k = 0; k < 19000; ++k) {
    const double r = 5.0 * std::sqrt(u()), phi = 2 * M_PI * u();
    double x = 256 + r * std::cos(phi), y = 256 + r * std::sin(phi), dir = 2 * M_PI * u();
    j += k ? ",[" : "[";
    for (int i = 0; i < 5; ++i) {
      std::snprintf(b, sizeof b, "%s[%.2f,%.2f]", i ? "," : "", x, y);
      j += b;
      dir += u() - 0.5;
      x += 2 * std::cos(dir), y += 2 * std::sin(dir);
    }
    j += "]";
  }
  return j + "]}";
}

Pki::Pki() {
  dir_ = (std::filesystem::temp_directory_path() /
          ("rheo-pki-" + std::to_string(::getpid()) + "-" + std::to_string(std::rand())))
             .string();
  std::filesystem::create_directories(dir_);
  ok_ = Ca("ca") && Ca("other-ca") &&
        Leaf("server", "ca", "subjectAltName=DNS:localhost,IP:127.0.0.1") &&
        Leaf("client", "ca", "extendedKeyUsage=clientAuth") &&
        Leaf("stranger", "other-ca", "extendedKeyUsage=clientAuth");
}

Pki::~Pki() {
  std::error_code ec;
  std::filesystem::remove_all(dir_, ec);
}

std::string Pki::operator()(const std::string& name) const {
  return (std::filesystem::path(dir_) / name).string();
}

bool Pki::Run(std::vector<std::string> args) {
  args.insert(args.begin(), "/usr/bin/openssl");
  RunResult r = RunProgram(args);
  if (r.exit_code != 0) ADD_FAILURE() << "openssl: " << r.err;
  return r.exit_code == 0;
}

bool Pki::Ca(const std::string& n) {
  return Run({"req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
              "-keyout", (*this)(n + ".key"), "-out", (*this)(n + ".pem"), "-days", "2", "-subj",
              "/CN=rheo test " + n});
}

bool Pki::Leaf(const std::string& n, const std::string& ca, const std::string& ext) {
  std::ofstream((*this)(n + ".ext")) << ext << "\n";
  return Run({"req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
              "-keyout", (*this)(n + ".key"), "-out", (*this)(n + ".csr"), "-subj",
              "/CN=" + (n == "server" ? std::string("localhost") : n)}) &&
         Run({"x509", "-req", "-in", (*this)(n + ".csr"), "-CA", (*this)(ca + ".pem"), "-CAkey",
              (*this)(ca + ".key"), "-CAcreateserial", "-out", (*this)(n + ".pem"), "-days", "2",
              "-extfile", (*this)(n + ".ext")});
}

RunResult RunProgram(const std::vector<std::string>& args) {
  RunResult r;
  int out[2], err[2];
  if (pipe2(out, O_CLOEXEC) != 0 || pipe2(err, O_CLOEXEC) != 0) return r;
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, out[1], 1);
  posix_spawn_file_actions_adddup2(&fa, err[1], 2);
  auto argv = Argv(args);
  int pid = -1;
  int rc = posix_spawn(&pid, args[0].c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  close(out[1]);
  close(err[1]);
  if (rc != 0) {
    close(out[0]);
    close(err[0]);
    return r;
  }
  std::thread t([&] {
    char b[4096];
    ssize_t n;
    while ((n = read(err[0], b, sizeof b)) > 0) r.err.append(b, static_cast<size_t>(n));
  });
  char b[4096];
  ssize_t n;
  while ((n = read(out[0], b, sizeof b)) > 0) r.out.append(b, static_cast<size_t>(n));
  t.join();
  close(out[0]);
  close(err[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

double LoopTickRate(RheodProcess& d, std::chrono::milliseconds window, std::string* detail) {
  auto stub = v1::DaemonService::NewStub(d.channel());
  auto status = [&] {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::DaemonStatus st;
    EXPECT_TRUE(stub->GetStatus(&ctx, {}, &st).ok());
    return st;
  };
  const v1::DaemonStatus a = status();
  std::this_thread::sleep_for(window);
  const v1::DaemonStatus b = status();
  if (detail)
    *detail = "ticks " + std::to_string(b.loop().ticks() - a.loop().ticks()) + " in " +
              std::to_string(b.uptime_s() - a.uptime_s()) + " s, late " +
              std::to_string(b.loop().late_ticks() - a.loop().late_ticks()) + ", overruns " +
              std::to_string(b.loop().overruns() - a.loop().overruns()) + ", skipped " +
              std::to_string(b.loop().skipped_ticks() - a.loop().skipped_ticks());
  return static_cast<double>(b.loop().ticks() - a.loop().ticks()) / (b.uptime_s() - a.uptime_s());
}

}  // namespace rheo::testing
