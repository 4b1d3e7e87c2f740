// web_watchers: N studio viewers on a running rheod's gateway for S seconds, as N browser tabs of
// /?view would be: each its own WebSocket, the token first, then the studio's own WatchFrames
// request (positions, 16-bit quantized, JSON). Counts the frames each received and the frames
// the daemon skipped for it (dropped_frames), and prints a line per viewer:
//   viewer K: F frames, D dropped[, ended: WHY]
// bench/reliability/load.sh runs it beside the gRPC watchers.
//
//   web_watchers --port P --token-file DATA_DIR/admin.token [--viewers 16] [--rate 30]
//                [--seconds 60] [--host 127.0.0.1]
#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "rheo/ws/ws_client.h"

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Viewer {
  uint64_t frames = 0;
  uint64_t dropped = 0;
  std::string ended;  // why the stream ended before the run did ("" if it did not)
};

// dropped_frames of a frame message (a JSON string holding a uint64), without parsing the whole
// frame: the positions make up nearly all of it.
uint64_t DroppedFrames(const std::string& frame) {
  const auto at = frame.find("\"droppedFrames\":\"");
  return at == std::string::npos ? 0 : std::strtoull(frame.c_str() + at + 17, nullptr, 10);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"N studio viewers of a running rheod, through its gateway's WebSocket"};
  std::string host = "127.0.0.1", token_file;
  int port = 0, viewers = 16;
  double rate = 30, seconds = 60;
  app.add_option("--host", host, "the gateway's address");
  app.add_option("--port", port, "the gateway's port (rheod's log: studio at http://...)")
      ->required()
      ->check(CLI::Range(1, 65535));
  app.add_option("--token-file", token_file, "a token (viewer or more), e.g. DATA_DIR/admin.token")
      ->required();
  app.add_option("--viewers", viewers, "connections")->check(CLI::Range(1, 4096));
  app.add_option("--rate", rate, "frames per second each asks for (the studio asks 30)")
      ->check(CLI::Range(1.0, 1000.0));
  app.add_option("--seconds", seconds, "how long they watch [s]")->check(CLI::Range(0.1, 86400.0));
  CLI11_PARSE(app, argc, argv);
  std::ifstream in(token_file);
  std::string token;
  std::getline(in, token);
  if (token.empty()) {
    std::fprintf(stderr, "web_watchers: no token in %s\n", token_file.c_str());
    return 2;
  }

  std::vector<Viewer> results(viewers);
  std::vector<std::thread> threads;
  const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                      std::chrono::duration<double>(seconds));
  for (int v = 0; v < viewers; ++v)
    threads.emplace_back([&, v] {
      Viewer& r = results[v];
      std::string error;
      auto c = rheo::ws::Client::Connect(host, port, &error);
      if (!c || !c->SendText(json{{"auth", token}}.dump()) ||
          !c->SendText(
              json{{"id", 1},
                   {"method", "rheo.v1.FrameService/WatchFrames"},
                   {"request", {{"rateHz", rate}, {"positions", true}, {"quantized", true}}}}
                  .dump())) {
        r.ended = "cannot connect: " + (c ? c->error() : error);
        return;
      }
      rheo::ws::Message m;
      while (Clock::now() < end) {
        if (!c->Read(&m, std::chrono::milliseconds(200))) {
          if (c->error() == "timed out") continue;
          r.ended = c->error();
          return;
        }
        // {"id": 1, "message": {frame}} per frame; {"id": 1, "status": {...}} once at the end
        // (whose own "message" comes after its "status").
        if (m.data.find("\"status\"") < m.data.find("\"message\"")) {
          r.ended = m.data.substr(0, 200);
          return;
        }
        ++r.frames;
        r.dropped += DroppedFrames(m.data);
      }
      c->Close();
    });
  for (auto& t : threads) t.join();
  int failed = 0;
  for (int v = 0; v < viewers; ++v) {
    const Viewer& r = results[v];
    std::printf("viewer %d: %llu frames, %llu dropped%s%s\n", v + 1,
                static_cast<unsigned long long>(r.frames),
                static_cast<unsigned long long>(r.dropped),
                r.ended.empty() ? "" : ", ended: ", r.ended.c_str());
    failed += !r.ended.empty();
  }
  return failed ? 1 : 0;
}
