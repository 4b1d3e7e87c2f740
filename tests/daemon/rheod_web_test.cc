// The studio's gateway against a real rheod: static files, the WebSocket bridge onto every kind of
// rheo.v1 call (unary, server stream, the bidirectional ToolStream), status codes carried back
// unchanged, quantised frames, a slow viewer that skips frames without slowing a fast one, and
// malformed messages answered in words on a connection that stays usable.
#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheo/v1/scene.grpc.pb.h"
#include "rheo/ws/ws_client.h"
#include "rheod_fixture.h"

namespace rheo::testing {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

// A connection with call bookkeeping: replies are sorted by call id as they arrive.
class Rpc {
 public:
  // Sends `token` first ({"auth": ...}); the daemon's admin token unless given ("" sends none).
  explicit Rpc(const RheodProcess& d, const std::string& origin = "", int receive_buffer = 0,
               std::optional<std::string> token = std::nullopt, const ws::Tls* tls = nullptr) {
    std::string error;
    client_ = ws::Client::Connect("127.0.0.1", d.http_port(), &error, origin, "/rpc",
                                  receive_buffer, tls);
    EXPECT_TRUE(client_) << error;
    const std::string t = token ? *token : d.admin_token();
    if (client_ && !t.empty()) {
      EXPECT_TRUE(client_->SendText(json{{"auth", t}}.dump()));
    }
  }
  bool ok() const { return client_ != nullptr; }
  ws::Client& client() { return *client_; }

  void Open(uint32_t id, const std::string& method, const json& request) {
    ASSERT_TRUE(
        client_->SendText(json{{"id", id}, {"method", method}, {"request", request}}.dump()));
  }
  void Send(const json& j) { ASSERT_TRUE(client_->SendText(j.dump())); }

  // Reads until call `id` has its status; returns its messages and status.
  struct Result {
    std::vector<json> messages;
    json status;
  };
  Result Wait(uint32_t id, std::chrono::milliseconds timeout = 30s) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (!done_.count(id) && std::chrono::steady_clock::now() < until) ReadOne();
    Result r;
    r.messages = std::move(messages_[id]);
    messages_.erase(id);
    r.status = done_.count(id) ? done_[id] : json{{"code", -1}, {"message", "no status in time"}};
    done_.erase(id);
    return r;
  }
  Result Call(uint32_t id, const std::string& method, const json& request = json::object()) {
    Open(id, method, request);
    return Wait(id);
  }
  std::vector<std::string>& binary() { return binary_; }

  // Reads until call `id` has `n` messages (kept for Wait) or its status; false on timeout.
  bool AwaitMessages(uint32_t id, size_t n, std::chrono::milliseconds timeout = 30s) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (messages_[id].size() < n && !done_.count(id) &&
           std::chrono::steady_clock::now() < until) {
      ReadOne();
    }
    return messages_[id].size() >= n;
  }

 private:
  void ReadOne() {
    ws::Message m;
    if (!client_->Read(&m, 200ms)) return;
    if (m.binary) {
      binary_.push_back(m.data);
      return;
    }
    json j = json::parse(m.data);
    const uint32_t got = j.value("id", 0u);
    if (j.contains("status")) {
      done_[got] = j["status"];
    } else {
      messages_[got].push_back(j["message"]);
    }
  }

  std::unique_ptr<ws::Client> client_;
  std::map<uint32_t, std::vector<json>> messages_;
  std::map<uint32_t, json> done_;
  std::vector<std::string> binary_;
};

std::string CircleStrokes(double cx = 200, double cy = 200, double r = 120) {
  json pts = json::array();
  for (int i = 0; i <= 64; ++i) {
    const double a = 2 * M_PI * i / 64.0;
    pts.push_back({cx + r * std::cos(a), cy + r * std::sin(a)});
  }
  return json{{"width", 400}, {"height", 400}, {"strokes", json::array({pts})}}.dump();
}

json CreateDiskRequest(bool add) {
  return json{{"name", "disk"},
              {"sketch", {{"strokesJson", CircleStrokes()}}},
              {"meshOptions", {{"thickness", 1.0}}},
              {"addToScene", add}};
}

int Code(const Rpc::Result& r) {
  return r.status.value("code", -1);
}

TEST(RheodWeb, ServesTheStudioFilesAndRefusesPathsOutsideIt) {
  const auto root =
      std::filesystem::temp_directory_path() / ("rheo-web-root-" + std::to_string(::getpid()));
  std::filesystem::create_directories(root / "js");
  std::filesystem::create_directories(root / "node_modules/three/build");
  std::filesystem::create_directories(root / "node_modules/other");
  std::ofstream(root / "index.html") << "<!doctype html><title>studio</title>";
  std::ofstream(root / "js/main.js") << "export const x = 1;";
  std::ofstream(root / "node_modules/three/build/three.module.js") << "export const THREE = 1;";
  std::ofstream(root / "node_modules/other/secret.js") << "secret";
  RheodProcess d({"--web-root", root.string()});
  ASSERT_TRUE(d.started());
  ASSERT_GT(d.http_port(), 0) << d.log();
  std::string body, type;
  EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/", &body, &type), 200);
  EXPECT_NE(body.find("studio"), std::string::npos);
  EXPECT_EQ(type, "text/html; charset=utf-8");
  EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/?view", &body), 200);
  EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/js/main.js", &body, &type), 200);
  EXPECT_EQ(type, "text/javascript; charset=utf-8");
  EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET",
                            "/vendor/three/build/three.module.js", &body),
            200);
  EXPECT_EQ(body, "export const THREE = 1;");
  EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "HEAD", "/js/main.js", &body), 200);
  // Refused: outside the folder, other npm packages, missing files, other methods.
  for (const char* bad :
       {"/../index.html", "/js/../../etc/passwd", "/%2e%2e/index.html", "/vendor/other/secret.js",
        "/node_modules/other/secret.js", "/js//main.js", "/js/%00main.js", "/js/%zz"})
    EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", bad, &body), 400) << bad;
  EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/nothing.js", &body), 404);
  EXPECT_NE(body.find("no such file"), std::string::npos);
  EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "POST", "/", &body), 405);
  // A page of another site may not open the WebSocket; the studio's own page may.
  std::string error;
  EXPECT_FALSE(ws::Client::Connect("127.0.0.1", d.http_port(), &error, "http://evil.example"));
  EXPECT_NE(error.find("declined"), std::string::npos) << error;
  EXPECT_TRUE(ws::Client::Connect("127.0.0.1", d.http_port(), &error,
                                  "http://127.0.0.1:" + std::to_string(d.http_port())))
      << error;
  EXPECT_FALSE(ws::Client::Connect("127.0.0.1", d.http_port(), &error, "", "/other"));
  std::filesystem::remove_all(root);
}

TEST(RheodWeb, UnaryCallsCarryTheApiAndItsStatusCodesUnchanged) {
  RheodProcess d;
  ASSERT_TRUE(d.started());
  Rpc rpc(d);
  ASSERT_TRUE(rpc.ok());
  auto status = rpc.Call(1, "rheo.v1.DaemonService/GetStatus");
  ASSERT_EQ(Code(status), 0) << status.status;
  ASSERT_EQ(status.messages.size(), 1u);
  EXPECT_EQ(status.messages[0]["version"], "0.1.0");
  EXPECT_TRUE(status.messages[0].contains("storedObjects"));  // zero values are written too
  EXPECT_EQ(status.messages[0]["frameClients"], 0);

  // The same NOT_FOUND, with the same words, as a gRPC client gets.
  auto missing = rpc.Call(2, "rheo.v1.ObjectService/GetObject", {{"id", "no-such-object"}});
  v1::Object object;
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::GetObjectRequest req;
  req.set_id("no-such-object");
  grpc::Status direct = v1::ObjectService::NewStub(d.channel())->GetObject(&ctx, req, &object);
  EXPECT_EQ(Code(missing), static_cast<int>(direct.error_code()));
  EXPECT_EQ(missing.status["name"], "NOT_FOUND");
  EXPECT_EQ(missing.status["message"], direct.error_message());

  // A parameter out of range: refused as over gRPC (code and words).
  auto bad = rpc.Call(3, "rheo.v1.SceneService/SetParameters",
                      {{"instanceId", 0}, {"parameters", {{{"name", "gravity"}, {"value", 1e9}}}}});
  {
    v1::SetParametersRequest sp;
    auto* p = sp.add_parameters();
    p->set_name("gravity");
    p->set_value(1e9);
    v1::SetParametersResponse out;
    grpc::ClientContext c2;
    SetDeadline(c2);
    grpc::Status s = v1::SceneService::NewStub(d.channel())->SetParameters(&c2, sp, &out);
    EXPECT_FALSE(s.ok());
    EXPECT_EQ(Code(bad), static_cast<int>(s.error_code()));
    EXPECT_EQ(bad.status["message"], s.error_message());
    EXPECT_FALSE(s.error_message().empty());
  }

  // Binary: the protobuf bytes behind the call's id.
  rpc.Send({{"id", 4},
            {"method", "rheo.v1.DaemonService/GetStatus"},
            {"request", json::object()},
            {"binary", true}});
  auto bin = rpc.Wait(4);
  EXPECT_EQ(Code(bin), 0);
  ASSERT_EQ(rpc.binary().size(), 1u);
  const std::string& b = rpc.binary()[0];
  ASSERT_GT(b.size(), 4u);
  EXPECT_EQ(static_cast<unsigned char>(b[0]), 4);
  v1::DaemonStatus parsed;
  ASSERT_TRUE(parsed.ParseFromString(b.substr(4)));
  EXPECT_EQ(parsed.version(), "0.1.0");
}

TEST(RheodWeb, MalformedMessagesAreAnsweredInWordsAndTheConnectionStaysUsable) {
  RheodProcess d;
  ASSERT_TRUE(d.started());
  Rpc rpc(d);
  ASSERT_TRUE(rpc.ok());
  struct Case {
    std::string text;
    uint32_t id;  // the id the answer carries
    int code;
    std::string words;  // part of the message
  };
  const std::vector<Case> cases = {
      {"not json", 0, 3, "not JSON"},
      {"[1,2]", 0, 3, "JSON object"},
      {"{}", 0, 3, "no \"id\""},
      {R"({"id":-1,"method":"x"})", 0, 3, "\"id\" must be"},
      {R"({"id":1.5,"method":"x"})", 0, 3, "\"id\" must be"},
      {R"({"id":4294967296,"method":"x"})", 0, 3, "\"id\" must be"},
      {R"({"id":7})", 7, 3, "exactly one of"},
      {R"({"id":7,"method":"a","cancel":true})", 7, 3, "exactly one of"},
      {R"({"id":7,"method":""})", 7, 3, "\"method\" must be"},
      {R"({"id":7,"method":5})", 7, 3, "\"method\" must be"},
      {R"({"id":7,"method":"rheo.v1.Nope/Nothing"})", 7, 12, "SceneService: "},
      {R"({"id":7,"method":"rheo.v1.DaemonService/GetStatus","request":[1]})", 7, 3, "JSON object"},
      {R"({"id":7,"method":"rheo.v1.DaemonService/GetStatus","extra":1})", 7, 3,
       "unknown field \"extra\""},
      {R"({"id":7,"method":"rheo.v1.DaemonService/GetStatus","binary":"yes"})", 7, 3,
       "true or false"},
      {R"({"id":7,"method":"rheo.v1.ObjectService/GetObject","request":{"idd":"x"}})", 7, 3,
       "rheo.v1.GetObjectRequest"},
      {R"({"id":7,"method":"rheo.v1.ObjectService/GetObject","request":{"id":5}})", 7, 3,
       "rheo.v1.GetObjectRequest"},
      {R"({"id":7,"method":"rheo.v1.DeviceService/ToolStream"})", 7, 3, "client stream"},
      {R"({"id":7,"method":"rheo.v1.DeviceService/ToolStream","stream":true,"request":{}})", 7, 3,
       "as writes"},
      {R"({"id":9,"write":{}})", 9, 5, "no open call 9"},
      {R"({"id":9,"end":true})", 9, 5, "no open call 9"},
      {R"({"id":9,"cancel":true})", 9, 5, "no open call 9"},
      {R"({"id":9,"cancel":false})", 9, 3, "must be true"},
      {R"({"id":9,"cancel":true,"x":1})", 9, 3, "only \"id\" and \"cancel\""},
      {R"({"id":9,"write":[]})", 9, 3, "JSON object"},
  };
  for (const Case& c : cases) {
    ASSERT_TRUE(rpc.client().SendText(c.text));
    auto r = rpc.Wait(c.id, 10s);
    EXPECT_EQ(Code(r), c.code) << c.text << " -> " << r.status;
    EXPECT_NE(r.status.value("message", "").find(c.words), std::string::npos)
        << c.text << " -> " << r.status;
  }
  // Binary messages: too short, id 0, a write to no call.
  for (const std::string& b : {std::string("ab"), std::string("\0\0\0\0x", 5)}) {
    ASSERT_TRUE(rpc.client().SendBinary(b));
    EXPECT_EQ(Code(rpc.Wait(0, 10s)), 3);
  }
  ASSERT_TRUE(rpc.client().SendBinary(std::string("\x09\0\0\0x", 5)));
  EXPECT_EQ(Code(rpc.Wait(9, 10s)), 5);
  // Still serving on the same connection, and the daemon is fine.
  auto after = rpc.Call(20, "rheo.v1.DaemonService/GetStatus");
  EXPECT_EQ(Code(after), 0) << after.status;
}

TEST(RheodWeb, StreamsProgressAndQuantisedFramesAndCancels) {
  RheodProcess d;
  ASSERT_TRUE(d.started());
  Rpc rpc(d);
  ASSERT_TRUE(rpc.ok());
  // A server stream: progress by stage, the object last.
  auto made = rpc.Call(1, "rheo.v1.ObjectService/CreateObject", CreateDiskRequest(true));
  ASSERT_EQ(Code(made), 0) << made.status;
  ASSERT_GE(made.messages.size(), 2u);
  std::vector<std::string> stages;
  for (const json& m : made.messages) stages.push_back(m["stage"]);
  EXPECT_EQ(stages.front(), "queued");
  const json& last = made.messages.back();
  ASSERT_TRUE(last.contains("object"));
  EXPECT_FALSE(last["object"]["id"].get<std::string>().empty());
  const int instance = last["sceneObject"]["instanceId"];
  EXPECT_GT(instance, 0);

  // An open outline: refused with the sketch stage's words, nothing stored.
  json open_line = {
      {"width", 400}, {"height", 400}, {"strokes", {{{10, 10}, {200, 10}, {390, 200}}}}};
  auto refused = rpc.Call(2, "rheo.v1.ObjectService/CreateObject",
                          {{"name", "line"}, {"sketch", {{"strokesJson", open_line.dump()}}}});
  EXPECT_EQ(refused.status["name"], "INVALID_ARGUMENT") << refused.status;
  auto listed = rpc.Call(3, "rheo.v1.ObjectService/ListObjects");
  ASSERT_EQ(Code(listed), 0);
  EXPECT_EQ(listed.messages[0]["objects"].size(), 1u);

  // Paused, so two frames show the same positions: floats and 16-bit agree to the box/65535.
  ASSERT_EQ(Code(rpc.Call(4, "rheo.v1.SceneService/Control", {{"command", "RUN_COMMAND_PAUSE"}})),
            0);
  auto floats = rpc.Call(5, "rheo.v1.FrameService/WatchFrames",
                         {{"rateHz", 30}, {"maxFrames", 1}, {"positions", true}});
  auto quant =
      rpc.Call(6, "rheo.v1.FrameService/WatchFrames",
               {{"rateHz", 30}, {"maxFrames", 1}, {"positions", true}, {"quantized", true}});
  ASSERT_EQ(Code(floats), 0);
  ASSERT_EQ(Code(quant), 0);
  ASSERT_EQ(floats.messages.size(), 1u);
  ASSERT_EQ(quant.messages.size(), 1u);
  const json& fo = floats.messages[0]["objects"][0];
  const json& qo = quant.messages[0]["objects"][0];
  EXPECT_FALSE(quant.messages[0]["topology"].empty());  // the first frame has the topology
  v1::ObjectState qs;
  ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(qo.dump(), &qs).ok());
  const auto& pos = fo["positions"];
  ASSERT_EQ(qs.positions_q().size(), pos.size() * 2);
  EXPECT_TRUE(qs.positions().empty());
  const double lo[3] = {qs.bounds_min().x(), qs.bounds_min().y(), qs.bounds_min().z()};
  const double hi[3] = {qs.bounds_max().x(), qs.bounds_max().y(), qs.bounds_max().z()};
  double worst = 0.0;
  for (size_t i = 0; i < pos.size(); ++i) {
    const auto* bytes = reinterpret_cast<const unsigned char*>(qs.positions_q().data());
    const int qv = bytes[2 * i] | (bytes[2 * i + 1] << 8);
    const int a = static_cast<int>(i % 3);
    const double decoded = lo[a] + qv / 65535.0 * (hi[a] - lo[a]);
    worst = std::max(worst, std::abs(decoded - pos[i].get<double>()) / (hi[a] - lo[a]));
  }
  EXPECT_LE(worst, 0.5 / 65535.0 + 1e-6);
  EXPECT_TRUE(quant.messages[0]["stamp"].contains("published"));

  // An endless stream, cancelled: CANCELLED, and the daemon's frame client is gone.
  ASSERT_EQ(Code(rpc.Call(7, "rheo.v1.SceneService/Control", {{"command", "RUN_COMMAND_RESUME"}})),
            0);
  rpc.Open(8, "rheo.v1.FrameService/WatchFrames", {{"rateHz", 60}});
  // Cancelled once a frame has come (however long a loaded machine takes to send the first).
  EXPECT_TRUE(rpc.AwaitMessages(8, 1));
  rpc.Send({{"id", 8}, {"cancel", true}});
  auto cancelled = rpc.Wait(8);
  EXPECT_EQ(cancelled.status["name"], "CANCELLED");
  EXPECT_GE(cancelled.messages.size(), 1u);
  for (int i = 0; i < 100; ++i) {
    auto s = rpc.Call(100 + i, "rheo.v1.DaemonService/GetStatus");
    if (s.messages.at(0)["frameClients"] == 0) break;
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_EQ(rpc.Call(99, "rheo.v1.DaemonService/GetStatus").messages.at(0)["frameClients"], 0);
}

TEST(RheodWeb, ASlowViewerSkipsFramesAndNeverSlowsAFastOne) {
  RheodProcess d;
  ASSERT_TRUE(d.started());
  Rpc setup(d);
  ASSERT_EQ(Code(setup.Call(1, "rheo.v1.ObjectService/CreateObject", CreateDiskRequest(true))), 0);
  Rpc fast(d);
  Rpc slow(d, "", 32 * 1024);  // a viewer on a slow link: a small receive window
  const json watch = {{"rateHz", 50}, {"positions", true}, {"quantized", true}};
  fast.Open(1, "rheo.v1.FrameService/WatchFrames", watch);
  slow.Open(1, "rheo.v1.FrameService/WatchFrames", watch);
  // The fast viewer reads for 2 s while the slow one reads nothing.
  int fast_frames = 0;
  const auto until = std::chrono::steady_clock::now() + 2s;
  while (std::chrono::steady_clock::now() < until) {
    ws::Message m;
    if (fast.client().Read(&m, 100ms)) ++fast_frames;
  }
  // Then the slow one catches up: what waited for it is bounded (no queue of 100 frames), and
  // the frames after the stall say how many it skipped.
  int slow_backlog = 0;
  size_t backlog_bytes = 0;
  uint64_t dropped = 0;
  ws::Message m;
  while (slow.client().Read(&m, 10ms)) {
    ++slow_backlog;
    backlog_bytes += m.data.size();
    dropped += std::stoull(json::parse(m.data)["message"]["droppedFrames"].get<std::string>());
  }
  int slow_after = 0;
  const auto until2 = std::chrono::steady_clock::now() + 300ms;
  while (std::chrono::steady_clock::now() < until2)
    if (slow.client().Read(&m, 50ms)) {
      ++slow_after;
      dropped += std::stoull(json::parse(m.data)["message"]["droppedFrames"].get<std::string>());
    }
  // A sanitizer build beside other tests' daemons (each with a SCHED_FIFO loop on 2 cores) has
  // been seen to serve 4 frames in those 2 s to any viewer: the rate is checked where it means
  // something, the bounds and the counting everywhere.
  EXPECT_GE(fast_frames, kSanitizerBuild ? 1 : 90) << "a 50 Hz viewer over 2 s";
  // Held for it: the kernel's buffers (the gateway's 64 KB send buffer, doubled by Linux, and the
  // viewer's 32 KB window) plus the message being written, never the 100 frames of the stall.
  EXPECT_LE(backlog_bytes, 512u * 1024u) << slow_backlog << " frames held for a stalled viewer";
  EXPECT_LT(slow_backlog, 60) << "frames held for a viewer that did not read for 2 s at 50 Hz";
  // Every frame the hub published while the slow viewer stalled either reached it or is counted
  // as skipped: received plus skipped covers what the fast viewer read in its 2 s (the hub's own
  // rate varies with the machine: 48 skipped of 2.3 s was seen on a loaded 2-core runner, so the
  // count is checked against the frames actually published, not against 50 Hz).
  EXPECT_GE(dropped, 1u) << "the slow viewer's skipped frames are counted";
  EXPECT_GE(dropped + slow_backlog + slow_after + 5, static_cast<uint64_t>(fast_frames))
      << "skipped " << dropped << ", held " << slow_backlog << ", after the stall " << slow_after
      << ": fewer than the " << fast_frames << " frames the fast viewer read";
}

TEST(RheodWeb, TheToolStreamRunsBothWaysThroughTheBridge) {
  RheodProcess d({"--device", "network"});
  ASSERT_TRUE(d.started());
  Rpc rpc(d);
  auto lease = rpc.Call(1, "rheo.v1.DeviceService/AcquireLease",
                        {{"clientName", "browser"}, {"durationS", 10}});
  ASSERT_EQ(Code(lease), 0) << lease.status;
  const std::string lease_id = lease.messages.at(0)["leaseId"];
  rpc.Send({{"id", 2}, {"method", "rheo.v1.DeviceService/ToolStream"}, {"stream", true}});
  int feedback = 0;
  for (int i = 0; i < 50; ++i) {
    json pose = {{"position", {{"x", 0.0}, {"y", 0.1 + 0.001 * i}, {"z", 0.0}}},
                 {"orientation", {{"w", 1.0}}}};
    json input = {{"leaseId", lease_id}, {"pose", pose}};
    rpc.Send({{"id", 2}, {"write", input}});
    ws::Message m;
    while (rpc.client().Read(&m, 5ms))
      if (!m.binary && json::parse(m.data).contains("message")) ++feedback;
    std::this_thread::sleep_for(10ms);
  }
  rpc.Send({{"id", 2}, {"end", true}});
  auto end = rpc.Wait(2);
  feedback += static_cast<int>(end.messages.size());
  EXPECT_EQ(Code(end), 0) << end.status;
  EXPECT_GT(feedback, 10);
  // The lease holder is the one whose tool moved.
  auto status = rpc.Call(3, "rheo.v1.DeviceService/GetDeviceStatus");
  EXPECT_EQ(Code(status), 0);
}

TEST(RheodWeb, ClosingThePageCancelsItsCallsAndManyPagesConnect) {
  RheodProcess d;
  ASSERT_TRUE(d.started());
  {
    std::vector<std::unique_ptr<Rpc>> pages;
    for (int i = 0; i < 8; ++i) {
      pages.push_back(std::make_unique<Rpc>(d));
      pages.back()->Open(1, "rheo.v1.FrameService/WatchFrames", {{"rateHz", 30}});
    }
    for (auto& p : pages) {
      ws::Message m;
      EXPECT_TRUE(p->client().Read(&m, 5s)) << p->client().error();
    }
  }  // closed without a word, as a browser tab does
  Rpc rpc(d);
  int clients = -1;
  for (int i = 0; i < 100 && clients != 0; ++i) {
    clients = rpc.Call(10 + i, "rheo.v1.DaemonService/GetStatus").messages.at(0)["frameClients"];
    if (clients != 0) std::this_thread::sleep_for(20ms);
  }
  EXPECT_EQ(clients, 0);
}

TEST(RheodWeb, HttpOffAndABusyPortAreClear) {
  RheodProcess off({"--http", "off"});
  ASSERT_TRUE(off.started());
  EXPECT_EQ(off.http_port(), 0);
  EXPECT_EQ(off.log().find("studio at"), std::string::npos);
  RheodProcess first;
  ASSERT_TRUE(first.started());
  RunResult r =
      RunProgram({RHEOD_PATH, "--listen", "127.0.0.1:0", "--data-dir", first.data_dir() + "-second",
                  "--http", "127.0.0.1:" + std::to_string(first.http_port())});
  std::filesystem::remove_all(first.data_dir() + "-second");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("cannot serve the studio on"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--http off"), std::string::npos) << r.err;
}

// The studio over TLS: https and wss with the gRPC port's certificate, on a non-loopback address
// without --insecure; plaintext and a wrong CA refused; with a client CA, only a browser (here a
// client) holding a certificate it signed gets in.
TEST(RheodWeb, TheStudioOverTlsAndMutualTls) {
  Pki pki;
  ASSERT_TRUE(pki.ok());
  std::string body, error;
  ws::Tls right, wrong;
  right.ca_file = pki("ca.pem");
  wrong.ca_file = pki("other-ca.pem");
  {
    RheodProcess d(
        {"--http", "0.0.0.0:0", "--tls-cert", pki("server.pem"), "--tls-key", pki("server.key")});
    ASSERT_TRUE(d.started()) << d.log();
    ASSERT_GT(d.http_port(), 0) << d.log();
    EXPECT_NE(d.log().find("studio at https://0.0.0.0:"), std::string::npos) << d.log();
    EXPECT_NE(d.log().find("over TLS"), std::string::npos) << d.log();
    EXPECT_EQ(d.log().find("--insecure"), std::string::npos) << d.log();
    EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/", &body, nullptr, &right), 200)
        << body;
    EXPECT_NE(body.find("<"), std::string::npos);
    EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/", &body), 0)
        << "plaintext HTTP to the TLS port: " << body;
    EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/", &body, nullptr, &wrong), 0)
        << "a CA that did not sign the server: " << body;
    EXPECT_FALSE(ws::Client::Connect("127.0.0.1", d.http_port(), &error));
    Rpc rpc(d, "https://127.0.0.1:" + std::to_string(d.http_port()), 0, std::nullopt, &right);
    ASSERT_TRUE(rpc.ok());
    auto who = rpc.Call(1, "rheo.v1.AuthService/WhoAmI");
    EXPECT_EQ(Code(who), 0) << who.status.dump();
    ASSERT_EQ(who.messages.size(), 1u);
    EXPECT_EQ(who.messages[0].value("tokenName", ""), "admin") << who.messages[0].dump();
    EXPECT_EQ(d.Terminate(10s), 0) << d.log();
  }
  {
    RheodProcess d({"--tls-cert", pki("server.pem"), "--tls-key", pki("server.key"),
                    "--tls-client-ca", pki("ca.pem")});
    ASSERT_TRUE(d.started()) << d.log();
    ASSERT_GT(d.http_port(), 0) << d.log();
    EXPECT_NE(d.log().find("over mutual TLS"), std::string::npos) << d.log();
    EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/", &body, nullptr, &right), 0)
        << "no client certificate: " << body;
    ws::Tls stranger = right;
    stranger.cert_file = pki("stranger.pem");
    stranger.key_file = pki("stranger.key");
    EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/", &body, nullptr, &stranger), 0)
        << "a client certificate another CA signed: " << body;
    ws::Tls mutual = right;
    mutual.cert_file = pki("client.pem");
    mutual.key_file = pki("client.key");
    EXPECT_EQ(ws::HttpRequest("127.0.0.1", d.http_port(), "GET", "/", &body, nullptr, &mutual), 200)
        << body;
    Rpc rpc(d, "", 0, std::nullopt, &mutual);
    ASSERT_TRUE(rpc.ok());
    auto who = rpc.Call(1, "rheo.v1.AuthService/WhoAmI");
    EXPECT_EQ(Code(who), 0) << who.status.dump();
    EXPECT_EQ(d.Terminate(10s), 0) << d.log();
  }
}

}  // namespace
}  // namespace rheo::testing
