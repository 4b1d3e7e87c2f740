#include "daemon/record/recorder.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>
#include <google/protobuf/util/time_util.h>
#include <spdlog/spdlog.h>
#include <sys/statvfs.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>

#include "common/format.h"
#include "record/mcap.h"

namespace rheo::daemon {
namespace {

namespace fs = std::filesystem;
namespace pb = google::protobuf;
using pb::util::TimeUtil;

Error Unavailable(std::string m) {
  return Error{ErrorCode::kUnavailable, std::move(m)};
}

constexpr int kTool = 0, kFrames = 1, kScene = 2, kParameters = 3, kCommands = 4, kLoop = 5;
constexpr int kChannels = 6;
constexpr const char* kTopics[kChannels] = {kToolTopic,       kFramesTopic,   kSceneTopic,
                                            kParametersTopic, kCommandsTopic, kLoopTopic};

// The recorder thread wakes at least this often to drain the ring and the events [ms].
constexpr auto kDrainInterval = std::chrono::milliseconds(10);

int64_t ThreadCpuNs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

// The FileDescriptorSet of `d`'s file and everything it imports, dependencies first.
std::string DescriptorSet(const pb::Descriptor* d) {
  pb::FileDescriptorSet set;
  std::set<std::string> seen;
  auto add = [&](auto&& self, const pb::FileDescriptor* f) -> void {
    if (!seen.insert(f->name()).second) return;
    for (int i = 0; i < f->dependency_count(); ++i) self(self, f->dependency(i));
    f->CopyTo(set.add_file());
  };
  add(add, d->file());
  return set.SerializeAsString();
}

std::span<const uint8_t> Bytes(const std::string& s) {
  return {reinterpret_cast<const uint8_t*>(s.data()), s.size()};
}

void SetTime(int64_t unix_ns, pb::Timestamp* out) {
  *out = TimeUtil::NanosecondsToTimestamp(unix_ns);
}
int64_t UnixNs(const pb::Timestamp& t) {
  return TimeUtil::TimestampToNanoseconds(t);
}

void SetVec(const std::array<double, 3>& a, v1::Vec3* out) {
  out->set_x(a[0]);
  out->set_y(a[1]);
  out->set_z(a[2]);
}

v1::AppliedCommand::Type AppliedType(Command::Type t) {
  using T = v1::AppliedCommand;
  switch (t) {
    case Command::Type::kPause: return T::TYPE_PAUSE;
    case Command::Type::kResume: return T::TYPE_RESUME;
    case Command::Type::kReset: return T::TYPE_RESET;
    case Command::Type::kStep: return T::TYPE_STEP;
    case Command::Type::kAddObject: return T::TYPE_ADD_OBJECT;
    case Command::Type::kRemoveObject: return T::TYPE_REMOVE_OBJECT;
    case Command::Type::kSetParameters: return T::TYPE_SET_PARAMETERS;
    case Command::Type::kDeviceCalibrate: return T::TYPE_DEVICE_CALIBRATE;
    case Command::Type::kDeviceClear: return T::TYPE_DEVICE_CLEAR;
    case Command::Type::kSetToolOrigin: return T::TYPE_SET_TOOL_ORIGIN;
    case Command::Type::kNone: break;
  }
  return T::TYPE_UNSPECIFIED;
}

// One tick of the loop as /tool carries it.
void FillToolSample(const TickRecord& r, v1::ToolSample* s) {
  s->Clear();
  s->set_tick(r.tick);
  s->set_sim_time(r.sim_time);
  s->set_paused(r.paused);
  s->set_wake_latency_ns(r.start_ns - r.deadline_ns);
  for (uint32_t i = 0; i < r.applied_count && i < r.applied.size(); ++i) {
    v1::AppliedCommand* a = s->add_applied();
    a->set_type(AppliedType(r.applied[i].type));
    a->set_command_seq(r.applied[i].seq);
    a->set_instance_id(r.applied[i].instance_id);
  }
  const ToolTelemetry& t = r.tool;
  s->set_present(t.present);
  if (!t.present) return;
  s->set_connected(t.connected);
  s->set_calibrated(t.calibrated);
  s->set_in_contact(t.in_contact);
  s->set_emergency_stopped(t.emergency_stopped);
  s->set_watchdog_tripped(t.watchdog_tripped);
  s->set_fault_bits(t.faults);
  s->set_contact_instance_id(t.contact_instance);
  SetVec(t.device_position, s->mutable_device_pose()->mutable_position());
  SetVec(t.device_velocity, s->mutable_device_velocity());
  s->set_object_loaded(t.object_loaded);
  v1::Quat* q = s->mutable_device_pose()->mutable_orientation();
  q->set_w(t.device_orientation[0]);
  q->set_x(t.device_orientation[1]);
  q->set_y(t.device_orientation[2]);
  q->set_z(t.device_orientation[3]);
  SetVec(t.proxy, s->mutable_proxy_position());
  SetVec(t.tool_origin, s->mutable_tool_origin());
  SetVec(t.requested_force, s->mutable_requested()->mutable_force());
  SetVec(t.requested_torque, s->mutable_requested()->mutable_torque());
  SetVec(t.displayed_force, s->mutable_displayed()->mutable_force());
  SetVec(t.displayed_torque, s->mutable_displayed()->mutable_torque());
  SetVec(t.object_force, s->mutable_object_force());
  const int motors = std::clamp(t.num_motors, 0, static_cast<int>(t.tensions.size()));
  for (int i = 0; i < motors; ++i) {
    s->add_string_tensions(t.tensions[i]);
    s->add_string_lengths(t.lengths[i]);
  }
  s->set_tip_radius(t.tip_radius);
  s->set_stiffness(t.stiffness);
  FillDeviceCounters(t, s->mutable_counters());
  s->mutable_counters()->set_tick(r.tick);
  s->set_input_seq(t.input_seq);
}

const char* StateWord(v1::RecordingState s) {
  switch (s) {
    case v1::RECORDING_STATE_RECORDING: return "recording";
    case v1::RECORDING_STATE_COMPLETE: return "complete";
    case v1::RECORDING_STATE_FAILED: return "failed";
    case v1::RECORDING_STATE_TRUNCATED: return "truncated";
    default: return "unknown";
  }
}
v1::RecordingState StateFromWord(const std::string& w) {
  if (w == "recording") return v1::RECORDING_STATE_RECORDING;
  if (w == "complete") return v1::RECORDING_STATE_COMPLETE;
  if (w == "failed") return v1::RECORDING_STATE_FAILED;
  if (w == "truncated") return v1::RECORDING_STATE_TRUNCATED;
  return v1::RECORDING_STATE_UNSPECIFIED;
}

// The side file <id>.json: what the MCAP file does not hold (written at start and at the end).
Status WriteSideFile(const std::string& path, const v1::Recording& r) {
  nlohmann::json j;
  j["id"] = r.id();
  j["name"] = r.name();
  j["state"] = StateWord(r.state());
  j["started_unix_ns"] = UnixNs(r.started());
  j["ended_unix_ns"] = r.has_ended() ? UnixNs(r.ended()) : 0;
  j["frames_hz"] = r.frames_hz();
  j["dropped_ticks"] = r.dropped_ticks();
  j["dropped_events"] = r.dropped_events();
  j["error"] = r.error();
  j["first_tick"] = r.first_tick();
  j["last_tick"] = r.last_tick();
  j["recorder_cpu_s"] = r.recorder_cpu_s();
  j["ring_peak"] = r.ring_peak();
  // A file without footer is counted by decompressing it; these spare the next start that scan
  // while the file keeps this size.
  j["bytes"] = r.bytes();
  nlohmann::json counts = nlohmann::json::object();
  for (const auto& [topic, n] : r.message_counts()) counts[topic] = n;
  j["message_counts"] = counts;
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << j.dump(2) << "\n";
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      return Unavailable("cannot write " + tmp + ": " + std::strerror(errno));
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) return Unavailable("cannot rename " + tmp + " to " + path + ": " + ec.message());
  return Status::Ok();
}

void ReadSideFields(const nlohmann::json& j, v1::Recording* r);

void ReadSideFile(const std::string& path, v1::Recording* r) {
  std::ifstream in(path);
  if (!in) return;
  nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) {
    spdlog::warn("recordings: {} is not JSON; the recording is listed from its file alone", path);
    return;
  }
  try {
    ReadSideFields(j, r);
  } catch (const nlohmann::json::exception& e) {
    spdlog::warn(
        "recordings: {} has a field of the wrong type ({}); the recording is listed "
        "from its file alone",
        path, e.what());
    const std::string id = r->id(), file = r->file();
    r->Clear();
    r->set_id(id);
    r->set_file(file);
  }
}

void ReadSideFields(const nlohmann::json& j, v1::Recording* r) {
  r->set_name(j.value("name", std::string()));
  r->set_state(StateFromWord(j.value("state", std::string())));
  if (int64_t ns = j.value("started_unix_ns", int64_t{0}); ns > 0)
    SetTime(ns, r->mutable_started());
  if (int64_t ns = j.value("ended_unix_ns", int64_t{0}); ns > 0) SetTime(ns, r->mutable_ended());
  r->set_frames_hz(j.value("frames_hz", 0.0));
  r->set_dropped_ticks(j.value("dropped_ticks", uint64_t{0}));
  r->set_dropped_events(j.value("dropped_events", uint64_t{0}));
  r->set_error(j.value("error", std::string()));
  r->set_first_tick(j.value("first_tick", uint64_t{0}));
  r->set_last_tick(j.value("last_tick", uint64_t{0}));
  r->set_recorder_cpu_s(j.value("recorder_cpu_s", 0.0));
  r->set_ring_peak(j.value("ring_peak", uint64_t{0}));
  r->set_bytes(j.value("bytes", uint64_t{0}));
  if (auto c = j.find("message_counts"); c != j.end() && c->is_object())
    for (const auto& [topic, n] : c->items())
      (*r->mutable_message_counts())[topic] = n.get<uint64_t>();
}

std::string NewId(const std::string& dir) {
  std::random_device rd;
  for (;;) {
    const time_t now = time(nullptr);
    tm utc{};
    gmtime_r(&now, &utc);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", &utc);
    char id[64];
    std::snprintf(id, sizeof id, "rec-%s-%04x", stamp, static_cast<unsigned>(rd() & 0xffff));
    std::error_code ec;
    if (!fs::exists(fs::path(dir) / (std::string(id) + ".mcap"), ec)) return id;
  }
}

std::string MiB(double bytes) {
  return Format("%.1f MiB", bytes / (1024.0 * 1024.0));
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// One recording being written.

struct Recorder::Session {
  struct Pending {
    int channel = 0;
    int64_t log_time_ns = 0;
    std::unique_ptr<pb::Message> message;
  };

  Session(Engine& e, FrameHub& h, TickRing& r, const RecorderOptions& o, std::atomic<bool>& flag)
      : engine(e), hub(h), ring(r), options(o), recording_flag(flag) {}

  Engine& engine;
  FrameHub& hub;
  TickRing& ring;
  const RecorderOptions& options;
  std::atomic<bool>& recording_flag;  // the Recorder's: cleared when this session fails

  // Fixed at start.
  std::string id, name, path, side_path;
  double frames_hz = 0.0;
  int64_t started_unix_ns = 0;
  int64_t period_ns = 1'000'000;
  uint32_t ring_session = 0;
  uint64_t dropped_base = 0;
  std::unique_ptr<record::FileSink> sink;
  record::McapWriter writer;
  uint16_t schema[kChannels] = {};
  std::thread thread;
  std::atomic<bool> stop{false};
  std::atomic<bool> finished{false};

  // Events from the services.
  std::mutex events_mutex;
  std::condition_variable events_cv;
  std::deque<Pending> events;
  size_t events_bytes = 0;
  uint64_t dropped_events = 0;

  // The recorder thread's own.
  uint16_t channel[kChannels] = {};
  uint32_t seq[kChannels] = {};
  std::map<std::string, uint64_t> counts;
  int64_t mono_to_unix_ns = 0;  // CLOCK_REALTIME - CLOCK_MONOTONIC at start
  int64_t epoch_unix_ns = 0;    // wall-clock time of tick 0 (loop_epoch_unix_ns)
  bool have_epoch = false;
  bool have_tick = false;
  uint64_t first_tick = 0, last_tick = 0;
  uint64_t ring_peak = 0;
  uint64_t frame_seq = 0;       // the hub's, of the last frame taken
  uint64_t frame_revision = 0;  // scene revision of the last topology written
  bool wrote_frame = false;
  double next_frame_tick = 0.0;  // the next frame is due at this tick
  int64_t cpu_start_ns = 0;
  double cpu_s = 0.0;
  int64_t ended_unix_ns = 0;
  Status error = Status::Ok();
  std::string buffer;  // serialized message, reused
  std::vector<TickRecord> batch;
  v1::ToolSample sample;
  v1::Frame frame;

  // Published by the thread for List (under stats_mutex).
  mutable std::mutex stats_mutex;
  std::map<std::string, uint64_t> published_counts;
  uint64_t published_bytes = 0, published_first = 0, published_last = 0, published_peak = 0;
  double published_cpu_s = 0.0;

  void Run();
  bool AddChannels();
  bool WriteMessage(int ch, int64_t log_time_ns, int64_t publish_time_ns, const pb::Message& m);
  bool WriteTick(const TickRecord& r);
  bool DrainRing();
  bool DrainEvents();
  bool WriteFrame(const LoopFrame& f);
  bool WriteLoopSample();
  void Fail(const Status& s);
  void Publish();
  uint64_t dropped_ticks() const { return ring.dropped() - dropped_base; }
  uint64_t dropped_events_now() {
    std::lock_guard<std::mutex> l(events_mutex);
    return dropped_events;
  }
  int64_t TickTimeNs(uint64_t tick) const {
    return epoch_unix_ns + static_cast<int64_t>(tick) * period_ns;
  }
  /// The recording as List reports it; `final` after the thread ended.
  v1::Recording Describe(bool final);
};

void Recorder::Session::Fail(const Status& s) {
  if (!error.ok()) return;
  error = s;
  // Logged once; the loop stops offering ticks, and the daemon goes on.
  ring.End();
  recording_flag.store(false, std::memory_order_release);
  spdlog::error("recording {} ('{}') failed and was ended: {}", id, name, s.error().message);
}

bool Recorder::Session::WriteMessage(int ch, int64_t log_time_ns, int64_t publish_time_ns,
                                     const pb::Message& m) {
  if (!error.ok()) return false;
  buffer.clear();
  if (!m.SerializeToString(&buffer)) {
    Fail(Internal(std::string("cannot serialize a ") + m.GetTypeName() + " for " + kTopics[ch]));
    return false;
  }
  Status s =
      writer.Write(channel[ch], seq[ch]++, static_cast<uint64_t>(std::max<int64_t>(0, log_time_ns)),
                   static_cast<uint64_t>(std::max<int64_t>(0, publish_time_ns)), Bytes(buffer));
  if (!s.ok()) {
    Fail(s);
    return false;
  }
  ++counts[kTopics[ch]];
  return true;
}

bool Recorder::Session::AddChannels() {
  const std::map<std::string, std::string> timing = {
      {"log_time", have_epoch ? "loop_epoch_unix_ns + tick * period_ns" : "wall clock"},
      {"loop_epoch_unix_ns", std::to_string(epoch_unix_ns)},
      {"period_ns", std::to_string(period_ns)},
  };
  std::map<std::string, std::string> about = timing;
  about["recording_id"] = id;
  about["recording_name"] = name;
  about["frames_hz"] = Format("%g", frames_hz);
  const std::map<std::string, std::string> wall = {{"log_time", "wall clock"}};
  for (int ch = 0; ch < kChannels; ++ch) {
    if (ch == kFrames && frames_hz <= 0.0) continue;
    const auto& meta = ch == kTool ? about : ch == kFrames ? timing : ch == kLoop ? about : wall;
    auto c = writer.AddChannel(schema[ch], kTopics[ch], "protobuf", meta);
    if (!c.ok()) {
      Fail(c.error());
      return false;
    }
    channel[ch] = *c;
    counts[kTopics[ch]] = 0;
  }
  return true;
}

bool Recorder::Session::WriteTick(const TickRecord& r) {
  if (!have_tick) {
    have_tick = true;
    first_tick = r.tick;
  }
  last_tick = r.tick;
  FillToolSample(r, &sample);
  const int64_t started = mono_to_unix_ns + r.start_ns;
  return WriteMessage(kTool, have_epoch ? TickTimeNs(r.tick) : started, started, sample);
}

bool Recorder::Session::DrainRing() {
  ring_peak = std::max<uint64_t>(ring_peak, ring.waiting());
  // A dropped tick means the ring was full, whether or not this thread looked just then (at a
  // million ticks a second it saw 726-1,616 of 8,192 waiting while 148k were dropped).
  if (ring.dropped() > dropped_base) ring_peak = TickRing::kCapacity;
  for (;;) {
    const size_t n = ring.Pop(batch.data(), batch.size());
    if (n == 0) return true;
    for (size_t i = 0; i < n; ++i) {
      if (batch[i].session != ring_session) continue;  // a tick of an earlier recording
      if (!WriteTick(batch[i])) return false;
    }
  }
}

bool Recorder::Session::DrainEvents() {
  std::deque<Pending> mine;
  {
    std::lock_guard<std::mutex> l(events_mutex);
    mine.swap(events);
    events_bytes = 0;
  }
  for (const Pending& p : mine)
    if (!WriteMessage(p.channel, p.log_time_ns, p.log_time_ns, *p.message)) return false;
  return true;
}

bool Recorder::Session::WriteFrame(const LoopFrame& f) {
  const double ticks_per_frame = 1e9 / (frames_hz * static_cast<double>(period_ns));
  const double tick = static_cast<double>(f.tick);
  // Frames at the asked rate by tick number, whatever rate the hub copies at (other clients
  // may ask for more): a frame within half a period of its due tick is taken.
  if (wrote_frame && tick + 0.5 * ticks_per_frame < next_frame_tick) return true;
  next_frame_tick = std::max(next_frame_tick + ticks_per_frame, tick + 0.5 * ticks_per_frame);
  const bool topology = !wrote_frame || f.scene_revision != frame_revision;
  frame.Clear();
  options.fill_frame(f, topology, &frame);
  wrote_frame = true;
  frame_revision = f.scene_revision;
  const int64_t log_time = have_epoch ? TickTimeNs(f.tick) : f.published_unix_ns;
  return WriteMessage(kFrames, log_time, f.published_unix_ns, frame);
}

bool Recorder::Session::WriteLoopSample() {
  v1::LoopSample s;
  const int64_t now = UnixNowNs();
  SetTime(now, s.mutable_wall_time());
  s.set_last_tick(last_tick);
  if (options.fill_loop_status) options.fill_loop_status(s.mutable_loop());
  s.set_dropped_ticks(dropped_ticks());
  s.set_dropped_events(dropped_events_now());
  s.set_ring_peak(ring_peak);
  s.set_bytes(writer.bytes_written());
  return WriteMessage(kLoop, now, now, s);
}

void Recorder::Session::Publish() {
  std::lock_guard<std::mutex> l(stats_mutex);
  published_counts = counts;
  published_bytes = writer.bytes_written();
  published_first = first_tick;
  published_last = last_tick;
  published_peak = ring_peak;
  published_cpu_s = static_cast<double>(ThreadCpuNs() - cpu_start_ns) * 1e-9;
}

void Recorder::Session::Run() {
  cpu_start_ns = ThreadCpuNs();
  batch.resize(256);
  // The channels are added around this recording's first tick: its deadline gives the
  // wall-clock time of tick 0 (the channels' loop_epoch_unix_ns), and a tick's log time is that
  // plus tick x period, so /tool samples lie exactly one period apart.
  // A loop that does not tick (stalled) leaves the recording waiting here, with its events
  // queued, until it ticks or the recording is stopped.
  for (;;) {
    TickRecord r;
    if (ring.Pop(&r, 1) == 1) {
      if (r.session != ring_session) continue;  // a tick of an earlier recording
      epoch_unix_ns = mono_to_unix_ns + r.deadline_ns - static_cast<int64_t>(r.tick) * period_ns;
      have_epoch = true;
      if (AddChannels() && DrainEvents() && WriteLoopSample()) (void)WriteTick(r);
      break;
    }
    if (stop.load()) {
      // Stopped before the loop ticked: wall-clock times (the channels' metadata says so).
      epoch_unix_ns = UnixNowNs();
      if (AddChannels() && DrainEvents()) (void)WriteLoopSample();
      break;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  const int hub_handle = frames_hz > 0.0 ? hub.Register(frames_hz) : 0;
  auto next_loop = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  while (error.ok()) {
    const bool stopping = stop.load(std::memory_order_acquire);
    if (stopping) {
      // The tick under way when the ring was ended may still push one record: let two ticks
      // pass, then take everything.
      const uint64_t ticks = engine.loop().stats().ticks.load();
      const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(50);
      while (engine.loop().running() && engine.loop().stats().ticks.load() < ticks + 2 &&
             std::chrono::steady_clock::now() < until)
        std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    if (!DrainRing() || !DrainEvents()) break;
    if (std::chrono::steady_clock::now() >= next_loop) {
      if (!WriteLoopSample()) break;
      next_loop += std::chrono::seconds(1);
    }
    Publish();
    if (stopping) break;
    if (frames_hz > 0.0 && !hub.stopping()) {
      auto snap = hub.WaitNewer(frame_seq, std::chrono::steady_clock::now() + kDrainInterval,
                                [this] { return stop.load(std::memory_order_acquire); });
      if (snap) {
        frame_seq = snap->seq;
        if (!DrainRing()) break;  // the ticks up to the frame first
        if (!WriteFrame(snap->frame)) break;
      }
    } else {
      std::unique_lock<std::mutex> l(events_mutex);
      events_cv.wait_for(l, kDrainInterval, [this] { return stop.load(); });
    }
  }
  if (hub_handle) hub.Unregister(hub_handle);
  // Ticks dropped after the last one the ring held still belong to the recording's span.
  if (have_tick) last_tick = std::max(last_tick, ring.last_offered());
  if (error.ok()) {
    (void)WriteLoopSample();
    if (Status s = writer.Close(); !s.ok()) Fail(s);
  }
  if (error.ok()) {
    if (Status s = sink->Close(); !s.ok()) Fail(s);
  } else {
    (void)sink->Close();  // what reached the disk stays readable up to its last chunk
  }
  ended_unix_ns = UnixNowNs();
  cpu_s = static_cast<double>(ThreadCpuNs() - cpu_start_ns) * 1e-9;
  Publish();
  if (Status s = WriteSideFile(side_path, Describe(true)); !s.ok())
    spdlog::warn("recording {}: {}; after a restart it is listed from {} alone", id,
                 s.error().message, path);
  finished.store(true, std::memory_order_release);
}

v1::Recording Recorder::Session::Describe(bool final) {
  v1::Recording r;
  r.set_id(id);
  r.set_name(name);
  r.set_file(path);
  r.set_frames_hz(frames_hz);
  SetTime(started_unix_ns, r.mutable_started());
  {
    std::lock_guard<std::mutex> l(events_mutex);
    r.set_dropped_events(dropped_events);
  }
  r.set_dropped_ticks(dropped_ticks());
  if (final) {
    r.set_state(error.ok() ? v1::RECORDING_STATE_COMPLETE : v1::RECORDING_STATE_FAILED);
    if (!error.ok()) r.set_error(error.error().message);
    SetTime(ended_unix_ns, r.mutable_ended());
    r.set_duration_s(static_cast<double>(ended_unix_ns - started_unix_ns) * 1e-9);
    std::error_code ec;
    const auto size = fs::file_size(path, ec);
    r.set_bytes(ec ? writer.bytes_written() : size);
    for (const auto& [topic, n] : counts) (*r.mutable_message_counts())[topic] = n;
    r.set_first_tick(first_tick);
    r.set_last_tick(last_tick);
    r.set_recorder_cpu_s(cpu_s);
    r.set_ring_peak(ring_peak);
    return r;
  }
  r.set_state(v1::RECORDING_STATE_RECORDING);
  r.set_duration_s(static_cast<double>(UnixNowNs() - started_unix_ns) * 1e-9);
  std::lock_guard<std::mutex> l(stats_mutex);
  r.set_bytes(published_bytes);
  for (const auto& [topic, n] : published_counts) (*r.mutable_message_counts())[topic] = n;
  r.set_first_tick(published_first);
  r.set_last_tick(published_last);
  r.set_recorder_cpu_s(published_cpu_s);
  r.set_ring_peak(published_peak);
  return r;
}

// ---------------------------------------------------------------------------------------------

Recorder::Recorder(Engine& engine, FrameHub& hub, TickRing& ring, RecorderOptions options)
    : engine_(engine), hub_(hub), ring_(ring), options_(std::move(options)) {}

Recorder::~Recorder() {
  Shutdown();
}

int64_t Recorder::UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

bool Recorder::ValidId(const std::string& id) const {
  if (id.empty() || id.size() > 64 || !std::isalnum(static_cast<unsigned char>(id[0])))
    return false;
  return std::all_of(id.begin(), id.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_';
  });
}

Result<size_t> Recorder::Load() {
  std::error_code ec;
  fs::create_directories(options_.dir, ec);
  if (ec)
    return Unavailable("cannot create the recordings directory " + options_.dir + ": " +
                       ec.message());
  std::map<std::string, v1::Recording> found;
  fs::directory_iterator it(options_.dir, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    const fs::directory_entry& entry = *it;
    if (entry.path().extension() != ".mcap") continue;
    const std::string id = entry.path().stem().string();
    if (!ValidId(id)) continue;
    v1::Recording r;
    r.set_id(id);
    r.set_file(entry.path().string());
    ReadSideFile((fs::path(options_.dir) / (id + ".json")).string(), &r);
    if (r.name().empty()) r.set_name(id);
    const v1::RecordingState side_state = r.state();
    const uint64_t side_bytes = r.bytes();
    const auto side_counts = r.message_counts();
    r.clear_message_counts();
    auto reader = record::McapReader::OpenFile(entry.path().string());
    std::error_code size_ec;
    r.set_bytes(entry.file_size(size_ec));
    if (!reader.ok()) {
      r.set_state(v1::RECORDING_STATE_FAILED);
      r.set_error("the file cannot be read: " + reader.error().message);
      found[id] = std::move(r);
      continue;
    }
    std::map<std::string, uint64_t> counts;
    for (const auto& [cid, c] : reader->channels()) counts[c.topic] = 0;
    uint64_t t0 = 0, t1 = 0;
    bool scanned = false;
    if (reader->statistics()) {
      const record::Statistics& st = *reader->statistics();
      for (const auto& [cid, n] : st.channel_message_counts) {
        auto c = reader->channels().find(cid);
        if (c != reader->channels().end()) counts[c->second.topic] = n;
      }
      t0 = st.message_start_time;
      t1 = st.message_end_time;
    } else if (!side_counts.empty() && side_bytes == r.bytes() &&
               (side_state == v1::RECORDING_STATE_TRUNCATED ||
                side_state == v1::RECORDING_STATE_FAILED)) {
      // Counted at an earlier start (or when it failed), and the file has not changed since.
      for (const auto& [topic, n] : side_counts) counts[topic] = n;
    } else {
      // No summary: count what the complete chunks hold (stops at a damaged one).
      (void)reader->ForEachMessage([&](const record::Message& m) {
        ++counts[m.channel->topic];
        if (t0 == 0 || m.log_time < t0) t0 = m.log_time;
        t1 = std::max(t1, m.log_time);
        return Status::Ok();
      });
      scanned = true;
    }
    for (const auto& [topic, n] : counts) (*r.mutable_message_counts())[topic] = n;
    if (!r.has_started() && t0 > 0) SetTime(static_cast<int64_t>(t0), r.mutable_started());
    if (reader->truncation()) {
      if (side_state != v1::RECORDING_STATE_FAILED) {
        r.set_state(v1::RECORDING_STATE_TRUNCATED);
        r.set_error(
            "rheod ended without stopping it; the file has no footer and holds every "
            "complete chunk: " +
            reader->truncation()->reason);
      }
      if (!r.has_ended() && t1 > 0) SetTime(static_cast<int64_t>(t1), r.mutable_ended());
    } else if (side_state == v1::RECORDING_STATE_UNSPECIFIED ||
               side_state == v1::RECORDING_STATE_RECORDING) {
      r.set_state(v1::RECORDING_STATE_COMPLETE);
      if (!r.has_ended() && t1 > 0) SetTime(static_cast<int64_t>(t1), r.mutable_ended());
    }
    if (r.has_started() && r.has_ended())
      r.set_duration_s(static_cast<double>(UnixNs(r.ended()) - UnixNs(r.started())) * 1e-9);
    if (scanned) {
      if (Status st = WriteSideFile((fs::path(options_.dir) / (id + ".json")).string(), r);
          !st.ok())
        spdlog::warn("recordings: {} (it is counted again at the next start)", st.error().message);
    }
    found[id] = std::move(r);
  }
  if (ec)
    return Unavailable("cannot list the recordings directory " + options_.dir + ": " +
                       ec.message());
  std::lock_guard<std::mutex> l(mutex_);
  for (auto& [id, r] : found) index_[id] = std::move(r);
  return found.size();
}

void Recorder::ReapLocked() {
  if (!session_ || !session_->finished.load(std::memory_order_acquire)) return;
  if (session_->thread.joinable()) session_->thread.join();
  index_[session_->id] = session_->Describe(true);
  if (!session_->error.ok())
    last_failure_ = session_->id + ", failed: " + session_->error.error().message;
  session_.reset();
}

Result<v1::Recording> Recorder::Start(const std::string& name, double frames_hz,
                                      std::vector<v1::SceneEvent> initial) {
  if (!std::isfinite(frames_hz) || !(frames_hz == 0.0 || (frames_hz >= 1.0 && frames_hz <= 1000.0)))
    return InvalidArgument(
        Format("frames_hz must be 0 (no frames) or 1 to 1000 (unset: 60); got %g", frames_hz));
  std::lock_guard<std::mutex> control(control_mutex_);
  {
    std::lock_guard<std::mutex> l(mutex_);
    if (closed_) return Unavailable("rheod is shutting down; no new recording starts");
    ReapLocked();
    if (session_) {
      const Session& s = *session_;
      return FailedPrecondition(
          "recording " + s.id + " ('" + s.name + "') is running since " +
          TimeUtil::ToString(TimeUtil::NanosecondsToTimestamp(s.started_unix_ns)) +
          "; one recording at a time: stop it first (rheoctl record stop)");
    }
  }
  std::error_code ec;
  fs::create_directories(options_.dir, ec);
  if (ec)
    return Unavailable("cannot create the recordings directory " + options_.dir + ": " +
                       ec.message());
  struct statvfs vfs {};
  if (::statvfs(options_.dir.c_str(), &vfs) == 0) {
    const double free_bytes = static_cast<double>(vfs.f_bavail) * static_cast<double>(vfs.f_frsize);
    if (free_bytes < static_cast<double>(options_.min_free_bytes))
      return ResourceExhausted("only " + MiB(free_bytes) + " free on the file system of " +
                               options_.dir + " (a recording needs at least " +
                               MiB(static_cast<double>(options_.min_free_bytes)) +
                               "); delete recordings (rheoctl record delete) or free space");
  }
  auto s = std::make_unique<Session>(engine_, hub_, ring_, options_, recording_);
  s->id = NewId(options_.dir);
  s->name = name.empty() ? s->id : name;
  s->path = (fs::path(options_.dir) / (s->id + ".mcap")).string();
  s->side_path = (fs::path(options_.dir) / (s->id + ".json")).string();
  s->frames_hz = frames_hz;
  s->period_ns = engine_.loop().options().period_ns;
  auto sink = record::FileSink::Create(s->path);
  if (!sink.ok()) return sink.error();
  s->sink = std::move(sink).value();
  record::WriterOptions wo;
  wo.compression = record::Compression::kZstd;
  wo.chunk_size = options_.chunk_size;
  auto fail_open = [&](const Error& e) {
    s->sink.reset();
    fs::remove(s->path, ec);
    return e;
  };
  if (Status st = s->writer.Open(*s->sink, "", options_.library, wo); !st.ok())
    return fail_open(st.error());
  const pb::Descriptor* types[kChannels] = {
      v1::ToolSample::descriptor(),   v1::Frame::descriptor(),
      v1::SceneEvent::descriptor(),   v1::ParameterChange::descriptor(),
      v1::CommandEvent::descriptor(), v1::LoopSample::descriptor()};
  for (int ch = 0; ch < kChannels; ++ch) {
    if (ch == kFrames && frames_hz <= 0.0) continue;
    auto id =
        s->writer.AddSchema(types[ch]->full_name(), "protobuf", Bytes(DescriptorSet(types[ch])));
    if (!id.ok()) return fail_open(id.error());
    s->schema[ch] = *id;
  }
  s->started_unix_ns = UnixNowNs();
  s->mono_to_unix_ns = s->started_unix_ns - rt::Loop::NowNs();
  for (v1::SceneEvent& e : initial) {
    Session::Pending p;
    p.channel = kScene;
    p.log_time_ns = s->started_unix_ns;
    p.message = std::make_unique<v1::SceneEvent>(std::move(e));
    s->events.push_back(std::move(p));
  }
  if (Status st = WriteSideFile(s->side_path, s->Describe(false)); !st.ok())
    return fail_open(st.error());
  s->dropped_base = ring_.dropped();
  s->ring_session = ring_.Begin();
  Session* raw = s.get();
  {
    std::lock_guard<std::mutex> l(mutex_);
    session_ = std::move(s);
    last_failure_.clear();
    recording_.store(true, std::memory_order_release);
  }
  raw->thread = std::thread([raw] { raw->Run(); });
  spdlog::info("recording {} ('{}') started: {} (frames {})", raw->id, raw->name, raw->path,
               frames_hz > 0.0 ? Format("%g Hz", frames_hz) : std::string("off"));
  return raw->Describe(false);
}

Result<v1::Recording> Recorder::Stop() {
  std::lock_guard<std::mutex> control(control_mutex_);
  Session* s = nullptr;
  {
    std::lock_guard<std::mutex> l(mutex_);
    ReapLocked();
    if (!session_)
      return FailedPrecondition(
          "no recording is running" +
          (last_failure_.empty() ? std::string() : "; the last one, " + last_failure_));
    s = session_.get();
    recording_.store(false, std::memory_order_release);
  }
  ring_.End();
  s->stop.store(true, std::memory_order_release);
  s->events_cv.notify_all();
  if (s->thread.joinable()) s->thread.join();
  std::lock_guard<std::mutex> l(mutex_);
  v1::Recording done = s->Describe(true);
  index_[s->id] = done;
  session_.reset();
  if (done.state() == v1::RECORDING_STATE_COMPLETE)
    spdlog::info("recording {} stopped: {:.1f} s, {} bytes, {} ticks dropped ({})", done.id(),
                 done.duration_s(), done.bytes(), done.dropped_ticks(), done.file());
  return done;
}

std::optional<v1::Recording> Recorder::Shutdown() {
  {
    std::lock_guard<std::mutex> l(mutex_);
    closed_ = true;
    ReapLocked();
    if (!session_) return std::nullopt;
  }
  auto r = Stop();
  if (!r.ok()) return std::nullopt;
  return *r;
}

std::vector<v1::Recording> Recorder::List() {
  std::lock_guard<std::mutex> l(mutex_);
  ReapLocked();
  std::vector<v1::Recording> out;
  for (const auto& [id, r] : index_) out.push_back(r);
  if (session_) out.push_back(session_->Describe(false));
  std::sort(out.begin(), out.end(), [](const v1::Recording& a, const v1::Recording& b) {
    const int64_t ta = UnixNs(a.started()), tb = UnixNs(b.started());
    return ta != tb ? ta < tb : a.id() < b.id();
  });
  return out;
}

Result<std::string> Recorder::FileFor(const std::string& id) {
  if (id.empty()) return InvalidArgument("id is empty; rheoctl record list shows the recordings");
  if (!ValidId(id))
    return InvalidArgument("'" + id.substr(0, 64) +
                           "' is not a recording id (letters, digits, '-' and '_', as rheoctl "
                           "record list shows them)");
  std::lock_guard<std::mutex> l(mutex_);
  ReapLocked();
  if (session_ && session_->id == id)
    return FailedPrecondition("recording " + id +
                              " is still being recorded; stop it first (rheoctl record stop)");
  auto it = index_.find(id);
  if (it == index_.end())
    return NotFound("no recording with id '" + id + "' (rheoctl record list shows them)");
  return it->second.file();
}

Status Recorder::Delete(const std::string& id) {
  auto file = FileFor(id);
  if (!file.ok()) return file.error();
  std::lock_guard<std::mutex> l(mutex_);
  std::error_code ec;
  if (!fs::remove(*file, ec) && ec)
    return Unavailable("cannot delete " + *file + ": " + ec.message());
  fs::remove(fs::path(options_.dir) / (id + ".json"), ec);
  index_.erase(id);
  spdlog::info("recording {} deleted ({})", id, *file);
  return Status::Ok();
}

void Recorder::Enqueue(int channel, int64_t log_time_ns, std::unique_ptr<pb::Message> message) {
  std::lock_guard<std::mutex> l(mutex_);
  if (!session_ || !recording()) return;
  Session& s = *session_;
  const size_t bytes = message->ByteSizeLong();
  std::lock_guard<std::mutex> e(s.events_mutex);
  if (s.events.size() >= options_.max_pending_events ||
      s.events_bytes + bytes > options_.max_pending_bytes) {
    ++s.dropped_events;
    return;
  }
  s.events_bytes += bytes;
  s.events.push_back(Session::Pending{channel, log_time_ns, std::move(message)});
}

void Recorder::Post(v1::SceneEvent event) {
  if (!recording()) return;
  if (!event.has_wall_time()) SetTime(UnixNowNs(), event.mutable_wall_time());
  const int64_t t = UnixNs(event.wall_time());
  Enqueue(kScene, t, std::make_unique<v1::SceneEvent>(std::move(event)));
}

void Recorder::Post(v1::ParameterChange event) {
  if (!recording()) return;
  if (!event.has_wall_time()) SetTime(UnixNowNs(), event.mutable_wall_time());
  const int64_t t = UnixNs(event.wall_time());
  Enqueue(kParameters, t, std::make_unique<v1::ParameterChange>(std::move(event)));
}

void Recorder::Post(v1::CommandEvent event, int64_t received_unix_ns) {
  if (!recording()) return;
  Enqueue(kCommands, received_unix_ns, std::make_unique<v1::CommandEvent>(std::move(event)));
}

void FillDeviceCounters(const ToolTelemetry& t, v1::DeviceCounters* c) {
  c->set_exchanges(t.exchanges);
  c->set_device_errors(t.device_errors);
  c->set_protocol_errors(t.protocol_errors);
  c->set_deadline_misses(t.deadline_misses);
  c->set_watchdog_trips(t.watchdog_trips);
  c->set_recoveries(t.recoveries);
  c->set_renderer_errors(t.renderer_errors);
  c->set_calibrations(t.calibrations);
  c->set_calibration_failures(t.calibration_failures);
  c->set_tick(t.tick);
  c->set_line_losses(t.line_losses);
  c->set_reconnect_attempts(t.reconnect_attempts);
  c->set_reconnects(t.reconnects);
  c->set_reconnect_backoff_s(t.reconnect_backoff_s);
  c->set_disconnected_s(t.disconnected_s);
}

}  // namespace rheo::daemon
