// Session recording against a real rheod: a recording of the emulated hand pressing a stored
// heart, read back with rheo_record's McapReader (every channel with its schema, /tool once per
// tick, /frames at the asked rate, the scene's mesh, the parameter change, the commands), its
// export, its listing after a restart, one recording at a time, a daemon killed mid-recording
// (TRUNCATED, complete chunks readable), a full disk (FAILED, the daemon goes on), bad requests.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>
#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "daemon/replay/replay.h"
#include "record/mcap.h"
#include "rheo/v1/daemon.grpc.pb.h"
#include "rheo/v1/device.grpc.pb.h"
#include "rheo/v1/frames.grpc.pb.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheo/v1/recording.grpc.pb.h"
#include "rheo/v1/scene.grpc.pb.h"
#include "rheod_fixture.h"

namespace rheo::testing {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
namespace pb = google::protobuf;
using record::McapReader;

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A data directory the test owns (kept across daemon restarts), removed at the end.
struct TempDir {
  TempDir() {
    char tmpl[] = "/tmp/rheod-record-XXXXXX";
    path = ::mkdtemp(tmpl);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string path;
};

std::vector<std::string> Args(const std::string& dir, std::vector<std::string> more = {}) {
  std::vector<std::string> a = {"--http", "off", "--data-dir", dir};
  a.insert(a.end(), more.begin(), more.end());
  return a;
}

std::unique_ptr<v1::RecordingService::Stub> Recordings(const RheodProcess& d) {
  return v1::RecordingService::NewStub(d.channel());
}

grpc::Status Start(const RheodProcess& d, const std::string& name, std::optional<double> hz,
                   v1::Recording* out) {
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::StartRecordingRequest req;
  req.set_name(name);
  if (hz) req.set_frames_hz(*hz);
  return Recordings(d)->StartRecording(&ctx, req, out);
}

grpc::Status Stop(const RheodProcess& d, v1::Recording* out) {
  grpc::ClientContext ctx;
  SetDeadline(ctx, 30s);
  return Recordings(d)->StopRecording(&ctx, v1::StopRecordingRequest(), out);
}

std::vector<v1::Recording> List(const RheodProcess& d) {
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::ListRecordingsResponse r;
  grpc::Status s = Recordings(d)->ListRecordings(&ctx, v1::ListRecordingsRequest(), &r);
  EXPECT_TRUE(s.ok()) << s.error_message();
  return {r.recordings().begin(), r.recordings().end()};
}

std::optional<v1::Recording> Find(const RheodProcess& d, const std::string& id) {
  for (const v1::Recording& r : List(d))
    if (r.id() == id) return r;
  return std::nullopt;
}

grpc::Status Export(const RheodProcess& d, const std::string& id, std::string* bytes) {
  grpc::ClientContext ctx;
  SetDeadline(ctx, 60s);
  v1::ExportRecordingRequest req;
  req.set_id(id);
  auto reader = Recordings(d)->ExportRecording(&ctx, req);
  v1::RecordingChunk c;
  bytes->clear();
  while (reader->Read(&c)) *bytes += c.data();
  return reader->Finish();
}

// A sketch of samples/ (the bean by default), meshed coarse (under a thousand tetrahedra),
// stored; its id.
std::string StoreSample(const RheodProcess& d, const std::string& sketch = "bean") {
  return StoreSketchFile(d, std::string(RHEO_SKETCHES) + "/" + sketch + ".json", 0.012);
}

grpc::Status AddToScene(const RheodProcess& d, const std::string& id, v1::SceneObject* out) {
  grpc::ClientContext ctx;
  SetDeadline(ctx, 60s);
  v1::AddToSceneRequest add;
  add.set_object_id(id);
  add.set_preset("hard-jelly");
  add.set_integrator(v1::INTEGRATOR_IMPLICIT);
  auto* grip = add.add_overrides();  // the floor holds it: pressed, it stays under the tool
  grip->set_name("friction");
  grip->set_value(5.0);
  return v1::SceneService::NewStub(d.channel())->AddToScene(&ctx, add, out);
}

grpc::Status Control(const RheodProcess& d, v1::RunCommand command) {
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::ControlRequest req;
  req.set_command(command);
  v1::ControlResponse r;
  return v1::SceneService::NewStub(d.channel())->Control(&ctx, req, &r);
}

grpc::Status SetParameter(const RheodProcess& d, uint32_t instance_id, const std::string& name,
                          double value) {
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::SetParametersRequest req;
  req.set_instance_id(instance_id);
  auto* p = req.add_parameters();
  p->set_name(name);
  p->set_value(value);
  v1::SetParametersResponse r;
  return v1::SceneService::NewStub(d.channel())->SetParameters(&ctx, req, &r);
}

// Runs `command` (a shell line); its exit status and what it printed.
std::pair<int, std::string> RunCommand(const std::string& command) {
  std::string out;
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (!p) return {-1, ""};
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  const int status = ::pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

// The emulated hand presses 1 cm into the object for 2 s; true once the tool is in contact,
// pushing (within 30 s: the hand moves over it first).
bool PressUntilTouching(const RheodProcess& d) {
  auto dev = v1::DeviceService::NewStub(d.channel());
  grpc::Status s = PressHand(d, 0.01, 2.0);
  EXPECT_TRUE(s.ok()) << s.error_message();
  if (!s.ok()) return false;
  const auto end = std::chrono::steady_clock::now() + 30s;
  while (std::chrono::steady_clock::now() < end) {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::DeviceStatus st;
    if (!dev->GetDeviceStatus(&ctx, v1::GetDeviceStatusRequest(), &st).ok()) return false;
    if (st.in_contact() && st.fault_bits() == 0 && st.wrench().force().y() > 0.1) return true;
    std::this_thread::sleep_for(50ms);  // polling the daemon's state, not synchronising
  }
  return false;
}

// Messages of a file by topic (each parsed with its channel's type), and the schemas' checks.
struct Contents {
  std::map<std::string, uint64_t> counts;
  std::map<std::string, std::string> schema_of;           // topic -> schema name
  std::vector<std::pair<uint64_t, v1::ToolSample>> tool;  // (log time, sample)
  std::vector<std::pair<uint64_t, v1::Frame>> frames;
  std::vector<v1::SceneEvent> scene;
  std::vector<v1::ParameterChange> parameters;
  std::vector<v1::CommandEvent> commands;
  std::vector<v1::LoopSample> loop;
  std::string error;
};

// Every schema must be a FileDescriptorSet that defines its message type, as the channel's
// "protobuf" encoding asks; every message must parse as its type.
Contents ReadContents(McapReader& reader) {
  Contents c;
  for (const auto& [id, ch] : reader.channels()) {
    c.counts[ch.topic] = 0;
    auto s = reader.schemas().find(ch.schema_id);
    if (s == reader.schemas().end()) {
      c.error += ch.topic + " has no schema; ";
      continue;
    }
    c.schema_of[ch.topic] = s->second.name;
    if (ch.message_encoding != "protobuf" || s->second.encoding != "protobuf")
      c.error += ch.topic + " is not protobuf; ";
    pb::FileDescriptorSet set;
    if (!set.ParseFromArray(s->second.data.data(), static_cast<int>(s->second.data.size()))) {
      c.error += ch.topic + ": the schema is not a FileDescriptorSet; ";
      continue;
    }
    pb::DescriptorPool pool;
    for (const auto& f : set.file()) pool.BuildFile(f);
    if (!pool.FindMessageTypeByName(s->second.name))
      c.error += ch.topic + ": the schema does not define " + s->second.name + "; ";
  }
  Status st = reader.ForEachMessage([&](const record::Message& m) {
    const std::string& topic = m.channel->topic;
    ++c.counts[topic];
    auto parse = [&](pb::Message& msg) {
      if (!msg.ParseFromArray(m.data.data(), static_cast<int>(m.data.size())))
        c.error += topic + ": a message does not parse; ";
    };
    if (topic == "/tool") {
      v1::ToolSample t;
      parse(t);
      c.tool.emplace_back(m.log_time, std::move(t));
    } else if (topic == "/frames") {
      v1::Frame f;
      parse(f);
      c.frames.emplace_back(m.log_time, std::move(f));
    } else if (topic == "/scene") {
      parse(c.scene.emplace_back());
    } else if (topic == "/parameters") {
      parse(c.parameters.emplace_back());
    } else if (topic == "/commands") {
      parse(c.commands.emplace_back());
    } else if (topic == "/loop") {
      parse(c.loop.emplace_back());
    }
    return Status::Ok();
  });
  if (!st.ok()) c.error += st.error().message;
  return c;
}

TEST(RheodRecord, RecordsTheToolFramesSceneParametersAndCommands) {
  TempDir dir;
  auto d = std::make_unique<RheodProcess>(
      Args(dir.path, {"--device", "sim-spidar-g", "--watchdog-timeout", "100"}));
  ASSERT_TRUE(d->started()) << d->log();
  // The heart stays under a press from above (the bean, standing on its narrow edge, is pushed
  // out from under the tool).
  const std::string object_id = StoreSample(*d, "heart");
  ASSERT_FALSE(object_id.empty());

  v1::Recording started;
  grpc::Status s = Start(*d, "press the heart", std::nullopt, &started);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(started.state(), v1::RECORDING_STATE_RECORDING);
  EXPECT_EQ(started.frames_hz(), 60.0);  // the default
  EXPECT_EQ(started.name(), "press the heart");
  // One at a time: the second is refused, naming the first.
  v1::Recording second;
  s = Start(*d, "again", 30.0, &second);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << s.error_message();
  EXPECT_NE(s.error_message().find(started.id()), std::string::npos) << s.error_message();
  // Exporting or deleting the running one is refused.
  std::string bytes;
  EXPECT_EQ(Export(*d, started.id(), &bytes).error_code(), grpc::StatusCode::FAILED_PRECONDITION);

  v1::SceneObject so;
  s = AddToScene(*d, object_id, &so);
  ASSERT_TRUE(s.ok()) << s.error_message();
  const bool touching = PressUntilTouching(*d);
  EXPECT_TRUE(touching) << "the hand did not reach the heart within 30 s";
  s = SetParameter(*d, so.instance_id(), "k_v", 500.0);
  ASSERT_TRUE(s.ok()) << s.error_message();
  std::this_thread::sleep_for(500ms);  // recording the press, not synchronising
  const auto running = Find(*d, started.id());
  ASSERT_TRUE(running);
  EXPECT_EQ(running->state(), v1::RECORDING_STATE_RECORDING);
  EXPECT_GT(running->message_counts().at("/tool"), 0u);

  v1::Recording done;
  s = Stop(*d, &done);
  ASSERT_TRUE(s.ok()) << s.error_message();
  ASSERT_EQ(done.state(), v1::RECORDING_STATE_COMPLETE) << done.DebugString();
  EXPECT_TRUE(done.error().empty()) << done.error();
  EXPECT_EQ(done.bytes(), fs::file_size(done.file()));

  auto reader = McapReader::OpenFile(done.file());
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  EXPECT_TRUE(reader->has_summary());
  EXPECT_FALSE(reader->truncation());
  Contents c = ReadContents(*reader);
  EXPECT_TRUE(c.error.empty()) << c.error;
  const std::map<std::string, std::string> want = {
      {"/tool", "rheo.v1.ToolSample"},       {"/frames", "rheo.v1.Frame"},
      {"/scene", "rheo.v1.SceneEvent"},      {"/parameters", "rheo.v1.ParameterChange"},
      {"/commands", "rheo.v1.CommandEvent"}, {"/loop", "rheo.v1.LoopSample"}};
  EXPECT_EQ(c.schema_of, want);
  for (const auto& [topic, n] : c.counts) EXPECT_EQ(done.message_counts().at(topic), n) << topic;

  // /tool: one sample per tick from the first to the last, each one period after the one before
  // in log time; ticks the ring dropped are the only gaps.
  ASSERT_FALSE(c.tool.empty());
  const uint64_t first = c.tool.front().second.tick(), last = c.tool.back().second.tick();
  EXPECT_EQ(first, done.first_tick());
  EXPECT_LE(last, done.last_tick());  // ticks dropped at the end lie past the last sample
  EXPECT_EQ(c.tool.size() + done.dropped_ticks(), done.last_tick() - first + 1);
  uint64_t gaps = 0, bad_times = 0, contact = 0;
  for (size_t i = 1; i < c.tool.size(); ++i) {
    const uint64_t dt = c.tool[i].second.tick() - c.tool[i - 1].second.tick();
    gaps += dt != 1;
    bad_times += c.tool[i].first - c.tool[i - 1].first != dt * 1'000'000;
  }
  for (const auto& [t, sample] : c.tool) {
    EXPECT_TRUE(sample.present());
    contact += sample.in_contact();
  }
  if (done.dropped_ticks() == 0) {
    EXPECT_EQ(gaps, 0u);
  }
  EXPECT_EQ(bad_times, 0u);
  EXPECT_GT(contact, 100u) << "the press hardly touched the heart";
  const double seconds = done.duration_s();
  std::printf(
      "recorded %.2f s: %zu /tool samples for ticks %llu..%llu (%llu dropped, ring peak "
      "%llu), %llu in contact, %zu frames, %llu bytes (%.0f kB/s), recorder CPU %.3f s "
      "(%.1f %%)\n",
      seconds, c.tool.size(), static_cast<unsigned long long>(first),
      static_cast<unsigned long long>(last), static_cast<unsigned long long>(done.dropped_ticks()),
      static_cast<unsigned long long>(done.ring_peak()), static_cast<unsigned long long>(contact),
      c.frames.size(), static_cast<unsigned long long>(done.bytes()), done.bytes() / seconds / 1e3,
      done.recorder_cpu_s(), 100.0 * done.recorder_cpu_s() / seconds);
  // The loop ticks at 1 kHz (skipped periods of a loaded machine, or of a sanitizer build's
  // slow ticks, are no ticks).
  EXPECT_GT(static_cast<double>(last - first + 1), (kSanitizerBuild ? 0.05 : 0.5) * seconds * 1e3);
  EXPECT_LT(static_cast<double>(last - first + 1), 1.05 * seconds * 1000.0 + 50);

  // /frames at about 60 Hz over the tick span, with positions and the heart's topology first.
  const double tick_seconds = static_cast<double>(last - first + 1) * 1e-3;
  ASSERT_FALSE(c.frames.empty());
  EXPECT_GT(static_cast<double>(c.frames.size()), 0.7 * 60.0 * tick_seconds) << c.frames.size();
  EXPECT_LT(static_cast<double>(c.frames.size()), 1.1 * 60.0 * tick_seconds + 2) << c.frames.size();
  // A frame lies at its tick's time: the /tool sample of the same tick has the same log time.
  std::map<uint64_t, uint64_t> tick_time;
  for (const auto& [t, sample] : c.tool) tick_time[sample.tick()] = t;
  bool frame_with_object = false;
  uint64_t frames_off_tick = 0;
  for (const auto& [t, f] : c.frames) {
    auto same = tick_time.find(f.stamp().tick());
    frames_off_tick += same != tick_time.end() && same->second != t;
    for (const auto& o : f.objects())
      if (o.instance_id() == so.instance_id() && o.positions_size() > 0) frame_with_object = true;
  }
  EXPECT_TRUE(frame_with_object);
  EXPECT_EQ(frames_off_tick, 0u);

  // /scene: the heart added, with a mesh a replay can rebuild.
  const v1::SceneEvent* added = nullptr;
  for (const auto& e : c.scene)
    if (e.kind() == v1::SceneEvent::KIND_ADDED && e.object().instance_id() == so.instance_id())
      added = &e;
  ASSERT_NE(added, nullptr);
  EXPECT_EQ(added->object().object_id(), object_id);
  EXPECT_EQ(added->object().preset(), "hard-jelly");
  EXPECT_EQ(added->object().integrator(), v1::INTEGRATOR_IMPLICIT);
  EXPECT_GT(added->object().parameters_size(), 10);
  const v1::SceneMesh& mesh = added->mesh();
  EXPECT_GT(mesh.vertex_count(), 50u);
  EXPECT_EQ(static_cast<uint32_t>(mesh.rest_positions_size()), 3 * mesh.vertex_count());
  EXPECT_GT(mesh.tetrahedra_size(), 0);
  EXPECT_EQ(mesh.tetrahedra_size() % 4, 0);
  EXPECT_GT(mesh.triangles_size(), 0);
  EXPECT_EQ(mesh.triangles_size() % 3, 0);
  uint32_t worst = 0;
  for (uint32_t v : mesh.tetrahedra()) worst = std::max(worst, v);
  for (uint32_t v : mesh.triangles()) worst = std::max(worst, v);
  EXPECT_LT(worst, mesh.vertex_count());
  std::printf("scene event: %u vertices, %d tetrahedra, %d surface triangles\n",
              mesh.vertex_count(), mesh.tetrahedra_size() / 4, mesh.triangles_size() / 3);

  // /parameters: the change as applied (every parameter, k_v the new value).
  bool changed = false;
  for (const auto& p : c.parameters)
    for (const auto& q : p.parameters())
      if (p.instance_id() == so.instance_id() && q.name() == "k_v" && q.value() == 500.0)
        changed = true;
  EXPECT_TRUE(changed) << c.parameters.size() << " parameter changes";

  // /commands: the add, the press and the change as received, with their status; no lease id.
  std::map<std::string, int> commands;
  for (const auto& cmd : c.commands) {
    ++commands[cmd.method()];
    EXPECT_EQ(cmd.caller(), "admin");
    EXPECT_NE(cmd.request_case(), v1::CommandEvent::REQUEST_NOT_SET) << cmd.method();
  }
  EXPECT_EQ(commands["/rheo.v1.SceneService/AddToScene"], 1);
  EXPECT_EQ(commands["/rheo.v1.DeviceService/SimulatedHand"], 1);
  EXPECT_EQ(commands["/rheo.v1.SceneService/SetParameters"], 1);
  for (const auto& cmd : c.commands)
    if (cmd.method() == "/rheo.v1.SceneService/SetParameters") {
      EXPECT_EQ(cmd.code(), 0);
      ASSERT_TRUE(cmd.has_set_parameters());
      EXPECT_EQ(cmd.set_parameters().parameters(0).name(), "k_v");
    }
  // /loop: once a second, and at start and stop.
  EXPECT_GE(c.loop.size(), 2u);
  EXPECT_GT(c.loop.back().loop().ticks(), 0u);
  EXPECT_EQ(c.loop.back().dropped_ticks(), done.dropped_ticks());

  // The export is the file, byte for byte.
  s = Export(*d, done.id(), &bytes);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(bytes, ReadText(done.file()));

  // After a restart the recording is still listed, complete, with the same counts.
  ASSERT_EQ(d->Terminate(10s), 0) << d->log();
  d = std::make_unique<RheodProcess>(Args(dir.path));
  ASSERT_TRUE(d->started()) << d->log();
  const auto listed = Find(*d, done.id());
  ASSERT_TRUE(listed) << "not listed after a restart";
  EXPECT_EQ(listed->state(), v1::RECORDING_STATE_COMPLETE);
  EXPECT_EQ(listed->name(), "press the heart");
  EXPECT_EQ(listed->bytes(), done.bytes());
  EXPECT_EQ(listed->dropped_ticks(), done.dropped_ticks());
  for (const auto& [topic, n] : done.message_counts())
    EXPECT_EQ(listed->message_counts().at(topic), n) << topic;
  ASSERT_EQ(d->Terminate(10s), 0) << d->log();
}

// Replay: a session (the heart added, pressed by the emulated hand, a parameter changed, paused,
// stepped, resumed, reset) re-run offline from its recording gives every frame and every tool
// sample back bit for bit; a what-if replay on a stiffer object differs, and says by how much;
// a recording that began with the heart already in the scene says it cannot be exact.
TEST(RheodReplay, ARecordedSessionReplaysBitForBitAndAWhatIfDiffers) {
  TempDir dir;
  auto d = std::make_unique<RheodProcess>(
      Args(dir.path, {"--device", "sim-spidar-g", "--watchdog-timeout", "100"}));
  ASSERT_TRUE(d->started()) << d->log();
  const std::string object_id = StoreSample(*d, "heart");
  ASSERT_FALSE(object_id.empty());
  v1::Recording started;
  grpc::Status s = Start(*d, "replay me", 100.0, &started);
  ASSERT_TRUE(s.ok()) << s.error_message();
  v1::SceneObject so;
  s = AddToScene(*d, object_id, &so);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_TRUE(PressUntilTouching(*d)) << "the hand did not reach the heart within 30 s";
  ASSERT_TRUE(SetParameter(*d, so.instance_id(), "k_v", 500.0).ok());
  std::this_thread::sleep_for(300ms);  // pressing the changed heart, not synchronising
  ASSERT_TRUE(Control(*d, v1::RUN_COMMAND_PAUSE).ok());
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(Control(*d, v1::RUN_COMMAND_STEP).ok());
  ASSERT_TRUE(Control(*d, v1::RUN_COMMAND_RESUME).ok());
  std::this_thread::sleep_for(300ms);
  ASSERT_TRUE(Control(*d, v1::RUN_COMMAND_RESET).ok());
  std::this_thread::sleep_for(300ms);
  v1::Recording done;
  s = Stop(*d, &done);
  ASSERT_TRUE(s.ok()) << s.error_message();
  ASSERT_EQ(done.state(), v1::RECORDING_STATE_COMPLETE);

  auto r = daemon::ReplayRecording(done.file());
  ASSERT_TRUE(r.ok()) << r.error().message;
  std::printf(
      "replayed %llu ticks in %.2f s: frames %llu of %llu identical, tool %llu of %llu (%llu in "
      "contact), %llu commands, max position diff %.3g m, max force diff %.3g N\n",
      static_cast<unsigned long long>(r->ticks), r->wall_s,
      static_cast<unsigned long long>(r->frames_identical),
      static_cast<unsigned long long>(r->frames_compared),
      static_cast<unsigned long long>(r->samples_identical),
      static_cast<unsigned long long>(r->samples_compared),
      static_cast<unsigned long long>(r->contact_ticks),
      static_cast<unsigned long long>(r->commands), r->max_position_diff_m, r->max_force_diff_n);
  for (const std::string& c : r->caveats) ADD_FAILURE() << "caveat: " << c;
  EXPECT_EQ(r->ticks, done.last_tick() - done.first_tick() + 1);
  EXPECT_EQ(r->objects, 1u);
  // The add, the tool origin, the change, pause, 3 steps, resume and reset.
  EXPECT_GE(r->commands, 9u);
  EXPECT_GT(r->contact_ticks, 100u);
  EXPECT_GT(r->frames_compared, 100u);
  EXPECT_EQ(r->frames_identical, r->frames_compared)
      << "first difference at tick " << r->first_difference_tick;
  EXPECT_EQ(r->samples_identical, r->samples_compared);
  EXPECT_EQ(r->max_position_diff_m, 0.0);
  EXPECT_EQ(r->max_force_diff_n, 0.0);
  EXPECT_TRUE(r->bit_identical());

  // A sanitizer build replays about 60 times slower (22 s for this file): the bit-identical
  // replay above is what it checks; the what-if, the options and the command line are the
  // optimised build's.
  if (kSanitizerBuild) {
    ASSERT_EQ(d->Terminate(10s), 0) << d->log();
    return;
  }
  // What if the heart had been stiffer (k_v 1000 from the start, against 400 and then 500): the
  // same hand, other positions and forces.
  daemon::ReplayOptions stiffer;
  stiffer.set = {{"k_v", 1000.0}};
  auto w = daemon::ReplayRecording(done.file(), stiffer);
  ASSERT_TRUE(w.ok()) << w.error().message;
  std::printf(
      "what-if k_v 1000: frames %llu of %llu identical, max position diff %.3g m, max "
      "force diff %.3g N\n",
      static_cast<unsigned long long>(w->frames_identical),
      static_cast<unsigned long long>(w->frames_compared), w->max_position_diff_m,
      w->max_force_diff_n);
  EXPECT_FALSE(w->bit_identical());
  EXPECT_LT(w->frames_identical, w->frames_compared);
  EXPECT_GT(w->max_position_diff_m, 1e-5);
  EXPECT_GT(w->max_force_diff_n, 1e-3);
  daemon::ReplayOptions bad;
  bad.set = {{"no_such_parameter", 1.0}};
  EXPECT_FALSE(daemon::ReplayRecording(done.file(), bad).ok());

  // The command line: `rheo replay --check` exits 0 on this file, and says so.
  auto [code, text] = RunCommand(std::string(RHEO_PATH) + " replay --check " + done.file());
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("replay: bit-identical"), std::string::npos) << text;
  auto [bad_code, bad_text] = RunCommand(std::string(RHEO_PATH) + " replay " + dir.path + "/none");
  EXPECT_EQ(bad_code, 1) << bad_text;

  // A recording started with the heart already in the scene cannot be exact, and says why.
  s = Start(*d, "late start", 30.0, &started);
  ASSERT_TRUE(s.ok()) << s.error_message();
  std::this_thread::sleep_for(500ms);
  s = Stop(*d, &done);
  ASSERT_TRUE(s.ok()) << s.error_message();
  auto late = daemon::ReplayRecording(done.file());
  ASSERT_TRUE(late.ok()) << late.error().message;
  EXPECT_FALSE(late->bit_identical());
  ASSERT_FALSE(late->caveats.empty());
  EXPECT_NE(late->caveats[0].find("before the recording started"), std::string::npos)
      << late->caveats[0];
  auto [late_code, late_text] =
      RunCommand(std::string(RHEO_PATH) + " replay --check " + done.file());
  EXPECT_EQ(late_code, 3) << late_text;
  ASSERT_EQ(d->Terminate(10s), 0) << d->log();
}

grpc::Status Playback(const RheodProcess& d, const v1::ControlPlaybackRequest* control,
                      v1::Playback* out) {
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  if (control) return Recordings(d)->ControlPlayback(&ctx, *control, out);
  return Recordings(d)->GetPlayback(&ctx, v1::GetPlaybackRequest(), out);
}

// rheod --replay: a recording played back to WatchFrames as the loop would send it (the
// recorded positions bit for bit, the surfaces, the tool), the scene following it, changes to
// the scene refused in words, and pause, step, seek, speed and the end for every client.
TEST(RheodReplay, RheodPlaysARecordingBackWithPauseStepSeekAndSpeed) {
  TempDir dir;
  std::string file;
  uint32_t instance_id = 0;
  std::map<uint64_t, v1::Frame> recorded;  // by tick
  {
    auto d = std::make_unique<RheodProcess>(
        Args(dir.path, {"--device", "sim-spidar-g", "--watchdog-timeout", "100"}));
    ASSERT_TRUE(d->started()) << d->log();
    const std::string object_id = StoreSample(*d, "heart");
    v1::Recording started, done;
    ASSERT_TRUE(Start(*d, "to play back", 50.0, &started).ok());
    v1::SceneObject so;
    ASSERT_TRUE(AddToScene(*d, object_id, &so).ok());
    instance_id = so.instance_id();
    EXPECT_TRUE(PressUntilTouching(*d));
    std::this_thread::sleep_for(1s);
    ASSERT_TRUE(Stop(*d, &done).ok());
    file = done.file();
    // Not playing back: the playback calls say so.
    v1::Playback none;
    EXPECT_EQ(Playback(*d, nullptr, &none).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    ASSERT_EQ(d->Terminate(10s), 0) << d->log();
    auto reader = McapReader::OpenFile(file);
    ASSERT_TRUE(reader.ok());
    Contents c = ReadContents(*reader);
    for (auto& [t, f] : c.frames) recorded[f.stamp().tick()] = f;
  }
  ASSERT_GT(recorded.size(), 100u);

  // A file that is not there: rheod does not start, and says why.
  {
    RheodProcess bad(Args(dir.path + "/b", {"--replay", dir.path + "/none.mcap"}));
    EXPECT_FALSE(bad.started());
    EXPECT_NE(bad.log().find("--replay"), std::string::npos) << bad.log();
  }
  TempDir dir2;
  RheodProcess d(Args(dir2.path, {"--replay", file}));
  ASSERT_TRUE(d.started()) << d.log();
  v1::Playback pb;
  ASSERT_TRUE(Playback(d, nullptr, &pb).ok());
  EXPECT_EQ(pb.file(), file);
  EXPECT_EQ(pb.frames(), recorded.size());
  EXPECT_GT(pb.duration_s(), 2.0);
  EXPECT_FALSE(pb.paused());

  // Frames as WatchFrames sends them: the heart's recorded positions, its surface first.
  {
    auto frames = v1::FrameService::NewStub(d.channel());
    grpc::ClientContext fctx;
    SetDeadline(fctx, 20s);
    v1::WatchFramesRequest w;
    w.set_rate_hz(100);
    w.set_positions(true);
    w.set_max_frames(60);
    auto reader = frames->WatchFrames(&fctx, w);
    v1::Frame f;
    int got = 0, same = 0, with_topology = 0, with_tool = 0;
    while (reader->Read(&f)) {
      ++got;
      with_topology += f.topology_size() > 0;
      with_tool += f.tool().present();
      auto it = recorded.find(f.stamp().tick());
      if (it == recorded.end() || f.objects_size() != it->second.objects_size()) continue;
      bool all = true;
      for (int i = 0; i < f.objects_size(); ++i) {
        const auto& a = f.objects(i).positions();
        const auto& b = it->second.objects(i).positions();
        all = all && f.objects(i).instance_id() == it->second.objects(i).instance_id() &&
              a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin());
      }
      same += all;
    }
    ASSERT_TRUE(reader->Finish().ok());
    EXPECT_EQ(got, 60);
    EXPECT_GE(with_topology, 1);
    EXPECT_EQ(same, got) << "frames that are not the recording's";
    EXPECT_GT(with_tool, 50);
    std::printf("played back: %d frames, %d as recorded, %d with the tool\n", got, same, with_tool);
  }
  // The scene follows the recording; changing it is refused, in words.
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::Scene scene;
    ASSERT_TRUE(
        v1::SceneService::NewStub(d.channel())->GetScene(&ctx, v1::GetSceneRequest(), &scene).ok());
    ASSERT_EQ(scene.objects_size(), 1);
    EXPECT_EQ(scene.objects(0).instance_id(), instance_id);
    EXPECT_EQ(scene.objects(0).preset(), "hard-jelly");
  }
  v1::SceneObject so;
  grpc::Status s = AddToScene(d, "anything", &so);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("playing back"), std::string::npos) << s.error_message();
  EXPECT_EQ(SetParameter(d, instance_id, "k_v", 1.0).error_code(),
            grpc::StatusCode::FAILED_PRECONDITION);
  v1::Recording rec;
  EXPECT_EQ(Start(d, "x", 10.0, &rec).error_code(), grpc::StatusCode::FAILED_PRECONDITION);

  // Pause holds the frame; step shows the next; seek goes there; speed 4 plays four times as
  // fast; past the end it stops there; Control PAUSE/RESUME/RESET act on the playback too.
  v1::ControlPlaybackRequest req;
  req.set_paused(true);
  ASSERT_TRUE(Playback(d, &req, &pb).ok());
  EXPECT_TRUE(pb.paused());
  std::this_thread::sleep_for(200ms);  // the player takes the pause at its next frame
  ASSERT_TRUE(Playback(d, nullptr, &pb).ok());
  const uint64_t held = pb.tick();
  std::this_thread::sleep_for(400ms);
  ASSERT_TRUE(Playback(d, nullptr, &pb).ok());
  EXPECT_EQ(pb.tick(), held) << "a paused playback moved";
  req.Clear();
  req.set_step(true);
  ASSERT_TRUE(Playback(d, &req, &pb).ok());
  std::this_thread::sleep_for(200ms);
  ASSERT_TRUE(Playback(d, nullptr, &pb).ok());
  auto next = recorded.upper_bound(held);
  ASSERT_NE(next, recorded.end());
  EXPECT_EQ(pb.tick(), next->first) << "a step shows the next recorded frame";
  req.Clear();
  req.set_seek_s(1.0);
  ASSERT_TRUE(Playback(d, &req, &pb).ok());
  std::this_thread::sleep_for(300ms);
  ASSERT_TRUE(Playback(d, nullptr, &pb).ok());
  EXPECT_NEAR(pb.position_s(), 1.0, 0.05);
  EXPECT_TRUE(pb.paused());
  req.Clear();
  req.set_speed(4.0);
  req.set_paused(false);
  ASSERT_TRUE(Playback(d, &req, &pb).ok());
  std::this_thread::sleep_for(500ms);  // playing, not synchronising
  ASSERT_TRUE(Playback(d, nullptr, &pb).ok());
  EXPECT_GT(pb.position_s(), 1.8) << "speed 4 for 0.5 s from 1 s";
  EXPECT_EQ(pb.speed(), 4.0);
  req.Clear();
  req.set_speed(0.0);
  EXPECT_EQ(Playback(d, &req, &pb).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  req.Clear();
  req.set_seek_s(1e9);
  ASSERT_TRUE(Playback(d, &req, &pb).ok());
  std::this_thread::sleep_for(500ms);
  ASSERT_TRUE(Playback(d, nullptr, &pb).ok());
  EXPECT_TRUE(pb.ended());
  EXPECT_TRUE(pb.paused());
  EXPECT_NEAR(pb.position_s(), pb.duration_s(), 1e-9);
  ASSERT_TRUE(Control(d, v1::RUN_COMMAND_RESET).ok());  // to the start (still paused)
  std::this_thread::sleep_for(300ms);
  ASSERT_TRUE(Playback(d, nullptr, &pb).ok());
  EXPECT_LT(pb.position_s(), 0.05);
  EXPECT_FALSE(pb.ended());
  ASSERT_TRUE(Control(d, v1::RUN_COMMAND_RESUME).ok());
  std::this_thread::sleep_for(500ms);
  ASSERT_TRUE(Playback(d, nullptr, &pb).ok());
  EXPECT_FALSE(pb.paused());
  EXPECT_GT(pb.position_s(), 0.5);  // still at speed 4
  EXPECT_EQ(d.Terminate(10s), 0) << d.log();
}

TEST(RheodRecord, ASigkilledRecordingIsListedTruncatedWithItsCompleteChunks) {
  TempDir dir;
  auto d = std::make_unique<RheodProcess>(Args(dir.path));
  ASSERT_TRUE(d->started()) << d->log();
  const std::string object_id = StoreSample(*d);
  v1::SceneObject so;
  ASSERT_TRUE(AddToScene(*d, object_id, &so).ok());
  v1::Recording r;
  grpc::Status s = Start(*d, "killed", 500.0, &r);
  ASSERT_TRUE(s.ok()) << s.error_message();
  // Until two chunks are on disk (read from the file as it grows), at most 60 s.
  const auto end = std::chrono::steady_clock::now() + 60s;
  uint64_t on_disk = 0;
  while (std::chrono::steady_clock::now() < end) {
    std::error_code ec;
    on_disk = fs::file_size(r.file(), ec);
    auto reader = McapReader::OpenFile(r.file());
    if (reader.ok() && reader->chunks().size() >= 2) break;
    std::this_thread::sleep_for(100ms);  // polling the file, not synchronising
  }
  d->Signal(SIGKILL);
  d->WaitForExit(10s);

  d = std::make_unique<RheodProcess>(Args(dir.path));
  ASSERT_TRUE(d->started()) << d->log();
  const auto listed = Find(*d, r.id());
  ASSERT_TRUE(listed);
  EXPECT_EQ(listed->state(), v1::RECORDING_STATE_TRUNCATED) << listed->DebugString();
  EXPECT_EQ(listed->name(), "killed");
  EXPECT_NE(listed->error().find("no footer"), std::string::npos) << listed->error();

  auto reader = McapReader::OpenFile(r.file());
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  ASSERT_TRUE(reader->truncation());
  EXPECT_GE(reader->chunks().size(), 2u) << on_disk << " bytes on disk";
  Contents c = ReadContents(*reader);
  EXPECT_TRUE(c.error.empty()) << c.error;
  EXPECT_GT(c.tool.size(), 500u);
  EXPECT_GT(c.frames.size(), 10u);
  EXPECT_GE(c.scene.size(), 1u);  // the bean, present at the start
  for (const auto& [topic, n] : c.counts) EXPECT_EQ(listed->message_counts().at(topic), n) << topic;
  // Consecutive ticks in what was kept.
  for (size_t i = 1; i < c.tool.size(); ++i)
    ASSERT_EQ(c.tool[i].second.tick(), c.tool[i - 1].second.tick() + 1) << i;
  std::printf("killed after %llu bytes: %zu complete chunks, %zu /tool samples, %zu frames kept\n",
              static_cast<unsigned long long>(on_disk), reader->chunks().size(), c.tool.size(),
              c.frames.size());
  // A second restart lists it the same (counted once: the side file keeps what the scan found).
  ASSERT_EQ(d->Terminate(10s), 0) << d->log();
  d = std::make_unique<RheodProcess>(Args(dir.path));
  ASSERT_TRUE(d->started()) << d->log();
  const auto again = Find(*d, r.id());
  ASSERT_TRUE(again);
  EXPECT_EQ(again->state(), v1::RECORDING_STATE_TRUNCATED);
  EXPECT_EQ(again->bytes(), listed->bytes());
  for (const auto& [topic, n] : c.counts) EXPECT_EQ(again->message_counts().at(topic), n) << topic;
  // The truncated file exports as it is and can be deleted.
  std::string bytes;
  ASSERT_TRUE(Export(*d, r.id(), &bytes).ok());
  EXPECT_EQ(bytes, ReadText(r.file()));
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::DeleteRecordingRequest del;
  del.set_id(r.id());
  v1::DeleteRecordingResponse out;
  s = Recordings(*d)->DeleteRecording(&ctx, del, &out);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_FALSE(fs::exists(r.file()));
  EXPECT_FALSE(Find(*d, r.id()));
  ASSERT_EQ(d->Terminate(10s), 0) << d->log();
}

TEST(RheodRecord, AFullDiskEndsTheRecordingAsFailedAndTheDaemonGoesOn) {
  TempDir dir;
  const std::string small = dir.path + "/small";
  fs::create_directories(small);
  // A 6 MiB file system for the recordings (tmpfs needs CAP_SYS_ADMIN: root in CI's container).
  if (::mount("tmpfs", small.c_str(), "tmpfs", 0, "size=6m") != 0)
    GTEST_SKIP() << "cannot mount a small tmpfs (" << std::strerror(errno)
                 << "); the full-disk case needs root";
  struct Unmount {
    std::string at;
    ~Unmount() { ::umount2(at.c_str(), MNT_DETACH); }
  } unmount{small};
  auto d = std::make_unique<RheodProcess>(Args(dir.path, {"--recording-dir", small}));
  ASSERT_TRUE(d->started()) << d->log();
  v1::SceneObject so;
  ASSERT_TRUE(AddToScene(*d, StoreSample(*d), &so).ok());
  v1::Recording r;
  grpc::Status s = Start(*d, "fills the disk", 1000.0, &r);
  ASSERT_TRUE(s.ok()) << s.error_message();
  std::optional<v1::Recording> now;
  const auto end = std::chrono::steady_clock::now() + 90s;
  while (std::chrono::steady_clock::now() < end) {
    now = Find(*d, r.id());
    if (now && now->state() != v1::RECORDING_STATE_RECORDING) break;
    std::this_thread::sleep_for(200ms);  // polling the daemon's state, not synchronising
  }
  ASSERT_TRUE(now);
  ASSERT_EQ(now->state(), v1::RECORDING_STATE_FAILED) << now->DebugString();
  EXPECT_NE(now->error().find(r.file()), std::string::npos) << now->error();
  EXPECT_NE(now->error().find("MiB free"), std::string::npos) << now->error();
  // Logged once.
  const std::string log = d->log();
  size_t n = 0;
  for (size_t at = log.find("failed and was ended"); at != std::string::npos;
       at = log.find("failed and was ended", at + 1))
    ++n;
  EXPECT_EQ(n, 1u) << log;
  // The daemon goes on: it answers, the loop ticks, and Stop says what happened.
  grpc::ClientContext ctx;
  SetDeadline(ctx);
  v1::DaemonStatus status;
  ASSERT_TRUE(v1::DaemonService::NewStub(d->channel())
                  ->GetStatus(&ctx, v1::GetStatusRequest(), &status)
                  .ok());
  v1::Recording stopped;
  s = Stop(*d, &stopped);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(s.error_message().find("failed"), std::string::npos) << s.error_message();
  // The complete chunks of the failed file are readable.
  auto reader = McapReader::OpenFile(r.file());
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  EXPECT_TRUE(reader->truncation());
  EXPECT_GE(reader->chunks().size(), 1u);
  // A new recording on the full disk is refused, saying how much space there is.
  v1::Recording again;
  s = Start(*d, "", 0.0, &again);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("free"), std::string::npos) << s.error_message();
  EXPECT_GT(LoopTickRate(*d, 1s), kSanitizerBuild ? 50.0 : 500.0);
  ASSERT_EQ(d->Terminate(10s), 0) << d->log();
}

TEST(RheodRecord, BadRequestsGetTheRightStatus) {
  TempDir dir;
  RheodProcess d(Args(dir.path));
  ASSERT_TRUE(d.started()) << d.log();
  v1::Recording r;
  for (double hz : {-1.0, 0.5, 1000.5, 1e9}) {
    grpc::Status s = Start(d, "", hz, &r);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << hz;
    EXPECT_NE(s.error_message().find("frames_hz"), std::string::npos) << s.error_message();
  }
  grpc::Status s = Start(d, "two\nlines", std::nullopt, &r);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << s.error_message();
  s = Start(d, std::string(300, 'x'), std::nullopt, &r);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << s.error_message();
  s = Stop(d, &r);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << s.error_message();
  EXPECT_NE(s.error_message().find("no recording is running"), std::string::npos);
  std::string bytes;
  for (const std::string& id : {std::string(""), std::string("../objects.db"), std::string(".x")})
    EXPECT_EQ(Export(d, id, &bytes).error_code(), grpc::StatusCode::INVALID_ARGUMENT) << id;
  s = Export(d, "rec-19700101-000000-0000", &bytes);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::NOT_FOUND) << s.error_message();
  EXPECT_NE(s.error_message().find("rheoctl record list"), std::string::npos);
  {
    grpc::ClientContext ctx;
    SetDeadline(ctx);
    v1::DeleteRecordingRequest del;
    del.set_id("rec-19700101-000000-0000");
    v1::DeleteRecordingResponse out;
    EXPECT_EQ(Recordings(d)->DeleteRecording(&ctx, del, &out).error_code(),
              grpc::StatusCode::NOT_FOUND);
  }
  // No frames (0): a recording without a /frames channel.
  s = Start(d, "", 0.0, &r);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(r.name(), r.id());
  std::this_thread::sleep_for(300ms);  // a few hundred ticks, not synchronising
  v1::Recording done;
  ASSERT_TRUE(Stop(d, &done).ok());
  EXPECT_EQ(done.state(), v1::RECORDING_STATE_COMPLETE);
  EXPECT_EQ(done.message_counts().count("/frames"), 0u);
  EXPECT_GT(done.message_counts().at("/tool"), 100u);
  ASSERT_EQ(d.Terminate(10s), 0) << d.log();
  // SIGTERM during a recording closes it cleanly.
  RheodProcess again(Args(dir.path));
  ASSERT_TRUE(again.started()) << again.log();
  ASSERT_TRUE(Start(again, "until sigterm", 30.0, &r).ok());
  std::this_thread::sleep_for(300ms);
  ASSERT_EQ(again.Terminate(10s), 0) << again.log();
  auto reader = McapReader::OpenFile(r.file());
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  EXPECT_TRUE(reader->has_summary());
  EXPECT_FALSE(reader->truncation());
}

}  // namespace
}  // namespace rheo::testing
