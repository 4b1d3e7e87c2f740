// Many viewers of one simulation through the studio's WebSocket: N connections (a load client
// speaking the same protocol as the browser studio) watch one object of about 5k tetrahedra at
// R Hz for S seconds. Two daemons in one run, one after the other on the same machine and object:
// without viewers, then with them. Prints a markdown table: frames per second per viewer (min,
// median), bytes per frame, the daemon's and the gateway threads' CPU, the loop's period p99 and
// p99.9 in both runs, and the latency from the loop publishing a frame to a viewer receiving it.
// A second table compares the frame encodings (JSON or binary, float or 16-bit positions).
//
//   viewers_bench --rheod build/rel/server/daemon/rheod [--viewers 32] [--rate 30] [--seconds 60]
//                 [--sketch samples/bean.json] [--resolution 0.007]
#include <fcntl.h>
#include <google/protobuf/util/time_util.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "rheo/v1/frames.pb.h"
#include "rheo/ws/ws_client.h"

extern char** environ;

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

// A rheod child with --http 127.0.0.1:0; ports read from its log.
class Daemon {
 public:
  explicit Daemon(const std::string& path) {
    data_ = std::filesystem::temp_directory_path() /
            ("rheo-webbench-" + std::to_string(getpid()) + "-" + std::to_string(++count_));
    std::filesystem::create_directories(data_);
    log_ = data_ / "rheod.log";
    std::vector<std::string> args = {path,           "--listen",           "127.0.0.1:0",
                                     "--http",       "127.0.0.1:0",        "--data-dir",
                                     data_.string(), "--http-connections", "1000"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 2, log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (posix_spawn(&pid_, path.c_str(), &fa, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&fa);
    for (int i = 0; i < 600 && pid_ > 0 && http_port_ == 0; ++i) {
      std::this_thread::sleep_for(50ms);
      std::ifstream in(log_);
      std::stringstream ss;
      ss << in.rdbuf();
      const std::string l = ss.str();
      auto at = l.find("studio at http://127.0.0.1:");
      if (at != std::string::npos) http_port_ = std::atoi(l.c_str() + at + 27);
    }
    // Its first admin token: every page below sends it first ({"auth": TOKEN}).
    std::ifstream token(data_ / "admin.token");
    std::getline(token, token_);
  }
  ~Daemon() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
    std::error_code ec;
    std::filesystem::remove_all(data_, ec);
  }
  int http_port() const { return http_port_; }
  int pid() const { return pid_; }
  static inline std::string token_;

 private:
  static inline int count_ = 0;
  std::filesystem::path data_, log_;
  int pid_ = -1;
  int http_port_ = 0;
};

// CPU seconds of a process, or of its threads named `thread_name`.
double CpuSeconds(int pid, const std::string& thread_name = "") {
  const double tick = static_cast<double>(sysconf(_SC_CLK_TCK));
  auto read_stat = [&](const std::filesystem::path& stat) {
    std::ifstream in(stat);
    std::string s((std::istreambuf_iterator<char>(in)), {});
    auto close = s.rfind(')');
    if (close == std::string::npos) return 0.0;
    std::istringstream rest(s.substr(close + 2));
    std::string field;
    double utime = 0, stime = 0;
    for (int i = 3; i <= 15 && rest >> field; ++i) {
      if (i == 14) utime = std::stod(field);
      if (i == 15) stime = std::stod(field);
    }
    return (utime + stime) / tick;
  };
  const std::filesystem::path proc = "/proc/" + std::to_string(pid);
  if (thread_name.empty()) return read_stat(proc / "stat");
  double sum = 0;
  std::error_code ec;
  for (auto& t : std::filesystem::directory_iterator(proc / "task", ec)) {
    std::ifstream comm(t.path() / "comm");
    std::string name;
    std::getline(comm, name);
    if (name == thread_name) sum += read_stat(t.path() / "stat");
  }
  return sum;
}

json Call(rheo::ws::Client& c, uint32_t id, const std::string& method, const json& request,
          std::vector<json>* messages = nullptr) {
  c.SendText(json{{"id", id}, {"method", method}, {"request", request}}.dump());
  json last;
  rheo::ws::Message m;
  while (c.Read(&m, 120s)) {
    json j = json::parse(m.data);
    if (j.value("id", 0u) != id) continue;
    if (j.contains("status")) return j["status"].value("code", -1) == 0 ? last : json();
    last = j["message"];
    if (messages) messages->push_back(last);
  }
  return json();
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5))];
}

// Pulls "published":"..." out of a frame's JSON without parsing the whole message.
int64_t PublishedNs(const std::string& frame) {
  auto at = frame.find("\"published\":\"");
  if (at == std::string::npos) return 0;
  at += 13;
  auto end = frame.find('"', at);
  google::protobuf::Timestamp t;
  if (!google::protobuf::util::TimeUtil::FromString(frame.substr(at, end - at), &t)) return 0;
  return google::protobuf::util::TimeUtil::TimestampToNanoseconds(t);
}

int64_t UnixNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

struct LoopFigures {
  double p50 = 0, p99 = 0, p999 = 0, max = 0;
  uint64_t ticks = 0, late = 0;
};

// A page's connection: the studio's WebSocket, then the daemon's token.
std::unique_ptr<rheo::ws::Client> Open(int port, std::string* error);

// The loop's figures from GetStatus, on a connection of its own (one left idle for a minute
// without answering the gateway's pings is closed, as it should be).
LoopFigures Loop(int port) {
  LoopFigures f;
  std::string error;
  auto c = Open(port, &error);
  if (!c) {
    std::fprintf(stderr, "GetStatus: %s\n", error.c_str());
    std::exit(1);
  }
  json s = Call(*c, 1, "rheo.v1.DaemonService/GetStatus", json::object());
  if (s.is_null()) {
    std::fprintf(stderr, "GetStatus failed\n");
    std::exit(1);
  }
  const json& p = s["loop"]["period"];
  f.p50 = p["p50Us"];
  f.p99 = p["p99Us"];
  f.p999 = p["p999Us"];
  f.max = p["maxUs"];
  f.ticks = std::stoull(s["loop"]["ticks"].get<std::string>());
  f.late = std::stoull(s["loop"]["lateTicks"].get<std::string>());
  return f;
}

std::unique_ptr<rheo::ws::Client> Open(int port, std::string* error) {
  auto c = rheo::ws::Client::Connect("127.0.0.1", port, error);
  if (c && !c->SendText(json{{"auth", Daemon::token_}}.dump())) c.reset();
  return c;
}

struct Setup {
  std::unique_ptr<rheo::ws::Client> control;
  uint32_t tets = 0;
};

Setup MakeObject(const Daemon& d, const std::string& strokes, double resolution) {
  Setup s;
  std::string error;
  s.control = Open(d.http_port(), &error);
  if (!s.control) {
    std::fprintf(stderr, "cannot connect: %s\n", error.c_str());
    return s;
  }
  json made = Call(*s.control, 1, "rheo.v1.ObjectService/CreateObject",
                   {{"name", "bench"},
                    {"sketch", {{"strokesJson", strokes}}},
                    {"meshOptions", {{"resolution", resolution}}},
                    {"addToScene", true}});
  if (made.is_null() || !made.contains("object")) {
    std::fprintf(stderr, "creating the object failed\n");
    s.control.reset();
    return s;
  }
  s.tets = made["object"]["mesh"]["tetrahedronCount"];
  // Let it fall and settle a little, so both runs simulate the same kind of scene.
  std::this_thread::sleep_for(2s);
  return s;
}

struct ViewerResult {
  uint64_t frames = 0;
  uint64_t bytes = 0;
  uint64_t dropped = 0;
  std::vector<double> latency_ms;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"many WebSocket viewers of one simulation"};
  std::string rheod, sketch = "samples/bean.json";
  int viewers = 32;
  double rate = 30, seconds = 60, resolution = 0.007;
  app.add_option("--rheod", rheod, "the rheod binary")->required();
  app.add_option("--viewers", viewers, "viewer connections");
  app.add_option("--rate", rate, "frames per second each viewer asks for");
  app.add_option("--seconds", seconds, "length of each run [s]");
  app.add_option("--sketch", sketch, "strokes JSON of the object");
  app.add_option("--resolution", resolution, "mesh resolution [m]");
  CLI11_PARSE(app, argc, argv);
  std::ifstream in(sketch);
  const std::string strokes((std::istreambuf_iterator<char>(in)), {});
  if (strokes.empty()) {
    std::fprintf(stderr, "cannot read %s\n", sketch.c_str());
    return 1;
  }

  // Run 1: the same scene without viewers.
  LoopFigures quiet;
  double quiet_cpu = 0;
  uint32_t tets = 0;
  {
    Daemon d(rheod);
    Setup s = MakeObject(d, strokes, resolution);
    if (!s.control) return 1;
    tets = s.tets;
    const LoopFigures before = Loop(d.http_port());
    const double cpu0 = CpuSeconds(d.pid());
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    quiet_cpu = (CpuSeconds(d.pid()) - cpu0) / seconds;
    quiet = Loop(d.http_port());
    quiet.late -= before.late;
  }

  // Run 2: with the viewers.
  LoopFigures loaded;
  double loaded_cpu = 0, http_cpu = 0;
  std::vector<ViewerResult> results(viewers);
  std::vector<std::pair<std::string, double>> encodings;
  {
    Daemon d(rheod);
    Setup s = MakeObject(d, strokes, resolution);
    if (!s.control) return 1;
    // Bytes per frame of each encoding, 60 frames each, one viewer.
    for (bool binary : {false, true})
      for (bool quantized : {false, true}) {
        std::string error;
        auto c = Open(d.http_port(), &error);
        c->SendText(json{
            {"id", 1},
            {"method", "rheo.v1.FrameService/WatchFrames"},
            {"request",
             {{"rateHz", 60}, {"positions", true}, {"quantized", quantized}, {"maxFrames", 61}}},
            {"binary",
             binary}}.dump());
        rheo::ws::Message m;
        uint64_t bytes = 0, n = 0;
        bool first = true;
        while (c->Read(&m, 10s)) {
          if (!m.binary && m.data.find("\"status\"") != std::string::npos &&
              m.data.find("\"message\":{") == std::string::npos)
            break;
          if (first) {  // the first frame carries the topology too
            first = false;
            continue;
          }
          bytes += m.data.size();
          ++n;
        }
        encodings.emplace_back(std::string(binary ? "binary" : "JSON") + ", " +
                                   (quantized ? "16-bit positions" : "float positions"),
                               n ? static_cast<double>(bytes) / n : 0.0);
      }

    const LoopFigures before = Loop(d.http_port());
    std::atomic<bool> stop{false};
    std::vector<std::thread> threads;
    const double cpu0 = CpuSeconds(d.pid());
    const double http0 = CpuSeconds(d.pid(), "rheod-http");
    const auto t0 = Clock::now();
    for (int v = 0; v < viewers; ++v)
      threads.emplace_back([&, v] {
        std::string error;
        auto c = Open(d.http_port(), &error);
        if (!c) return;
        c->SendText(json{{"id", 1},
                         {"method", "rheo.v1.FrameService/WatchFrames"},
                         {"request", {{"rateHz", rate}, {"positions", true}, {"quantized", true}}}}
                        .dump());
        ViewerResult& r = results[v];
        rheo::ws::Message m;
        bool first = true;
        while (!stop.load()) {
          if (!c->Read(&m, 200ms)) continue;
          const int64_t now = UnixNs();
          if (first) {
            first = false;
            continue;
          }
          ++r.frames;
          r.bytes += m.data.size();
          if (const int64_t p = PublishedNs(m.data); p > 0)
            r.latency_ms.push_back((now - p) * 1e-6);
          auto at = m.data.find("\"droppedFrames\":\"");
          if (at != std::string::npos)
            r.dropped += std::strtoull(m.data.c_str() + at + 17, nullptr, 10);
        }
        c->Close();
      });
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
    loaded_cpu = (CpuSeconds(d.pid()) - cpu0) / elapsed;
    http_cpu = (CpuSeconds(d.pid(), "rheod-http") - http0) / elapsed;
    loaded = Loop(d.http_port());
    loaded.late -= before.late;
    stop = true;
    for (auto& t : threads) t.join();
    std::vector<double> fps, latency;
    uint64_t bytes = 0, frames = 0, dropped = 0;
    for (auto& r : results) {
      fps.push_back(r.frames / elapsed);
      bytes += r.bytes;
      frames += r.frames;
      dropped += r.dropped;
      latency.insert(latency.end(), r.latency_ms.begin(), r.latency_ms.end());
    }
    std::printf("## %d viewers at %.0f Hz for %.0f s on one object of %u tetrahedra\n\n", viewers,
                rate, seconds, tets);
    std::printf("| figure | value |\n|---|---|\n");
    std::printf("| frames per second per viewer, min | %.1f |\n", Percentile(fps, 0.0));
    std::printf("| frames per second per viewer, median | %.1f |\n", Percentile(fps, 0.5));
    std::printf("| bytes per frame (JSON, 16-bit positions) | %.0f |\n",
                frames ? static_cast<double>(bytes) / frames : 0.0);
    std::printf("| frames skipped for the viewers (dropped_frames) | %llu of %llu |\n",
                static_cast<unsigned long long>(dropped),
                static_cast<unsigned long long>(dropped + frames));
    std::printf("| publish-to-viewer latency p50 / p99 [ms] | %.2f / %.2f |\n",
                Percentile(latency, 0.5), Percentile(latency, 0.99));
    std::printf("| rheod CPU without / with viewers [cores] | %.2f / %.2f |\n", quiet_cpu,
                loaded_cpu);
    std::printf("| gateway threads' CPU [cores] | %.2f |\n", http_cpu);
    std::printf(
        "\n| loop period [us] | p50 | p99 | p99.9 | max | late ticks "
        "|\n|---|---|---|---|---|---|\n");
    std::printf("| without viewers | %.1f | %.1f | %.1f | %.1f | %llu |\n", quiet.p50, quiet.p99,
                quiet.p999, quiet.max, static_cast<unsigned long long>(quiet.late));
    std::printf("| with %d viewers | %.1f | %.1f | %.1f | %.1f | %llu |\n", viewers, loaded.p50,
                loaded.p99, loaded.p999, loaded.max, static_cast<unsigned long long>(loaded.late));
    std::printf("| difference | %+.1f | %+.1f | %+.1f | | |\n", loaded.p50 - quiet.p50,
                loaded.p99 - quiet.p99, loaded.p999 - quiet.p999);
    std::printf(
        "\n| frame encoding (one object, after the topology) | bytes per frame |\n|---|---|\n");
    for (auto& [name, b] : encodings) std::printf("| %s | %.0f |\n", name.c_str(), b);
    std::printf("\n(loop percentiles are the daemons' own, over each daemon's whole run)\n");
  }
  return 0;
}
