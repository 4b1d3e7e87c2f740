#include "daemon/replay/player.h"

#include <pthread.h>

#include <algorithm>
#include <chrono>

#include "record/mcap.h"
#include "rheo/v1/frames.pb.h"

namespace rheo::daemon {
namespace {

using Clock = std::chrono::steady_clock;

std::array<double, 3> A3(const v1::Vec3& v) {
  return {v.x(), v.y(), v.z()};
}

int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

void ToolFromSample(const v1::ToolSample& s, ToolTelemetry* t) {
  *t = ToolTelemetry{};
  t->tick = s.tick();
  t->present = s.present();
  if (!s.present()) return;
  t->connected = s.connected();
  t->calibrated = s.calibrated();
  t->in_contact = s.in_contact();
  t->emergency_stopped = s.emergency_stopped();
  t->watchdog_tripped = s.watchdog_tripped();
  t->faults = s.fault_bits();
  t->contact_instance = s.contact_instance_id();
  t->object_loaded = s.object_loaded();
  t->device_position = A3(s.device_pose().position());
  const v1::Quat& q = s.device_pose().orientation();
  t->device_orientation = {q.w(), q.x(), q.y(), q.z()};
  t->device_velocity = A3(s.device_velocity());
  t->proxy = A3(s.proxy_position());
  t->tool_origin = A3(s.tool_origin());
  t->requested_force = A3(s.requested().force());
  t->requested_torque = A3(s.requested().torque());
  t->displayed_force = A3(s.displayed().force());
  t->displayed_torque = A3(s.displayed().torque());
  t->object_force = A3(s.object_force());
  t->num_motors = std::min(s.string_tensions_size(), static_cast<int>(t->tensions.size()));
  for (int i = 0; i < t->num_motors; ++i) {
    t->tensions[i] = s.string_tensions(i);
    t->lengths[i] = i < s.string_lengths_size() ? s.string_lengths(i) : 0.0;
  }
  t->tip_radius = s.tip_radius();
  t->stiffness = s.stiffness();
  t->input_seq = s.input_seq();
}

Result<std::unique_ptr<RecordingPlayer>> RecordingPlayer::Open(const std::string& path,
                                                               FrameHub& hub, SceneFn on_scene) {
  auto reader = record::McapReader::OpenFile(path);
  if (!reader.ok()) return reader.error();
  std::unique_ptr<RecordingPlayer> p(new RecordingPlayer());
  p->path_ = path;
  p->hub_ = &hub;
  p->on_scene_ = std::move(on_scene);
  bool any = false;
  for (auto cursor = reader->Messages();;) {
    auto m = cursor.Next();
    if (!m.ok()) {
      if (reader->truncation()) break;  // played up to its last complete chunk
      return m.error();
    }
    if (!*m) break;
    const std::string& topic = (*m)->channel->topic;
    if (topic == "/frames") {
      if (!any) p->first_ns_ = (*m)->log_time;
      p->last_ns_ = (*m)->log_time;
      any = true;
      ++p->frame_count_;
    } else if (topic == "/scene") {
      v1::SceneEvent ev;
      const auto d = (*m)->data;
      if (!ev.ParseFromArray(d.data(), static_cast<int>(d.size())))
        return InvalidArgument(path + ": a /scene message does not parse");
      if (ev.kind() == v1::SceneEvent::KIND_PRESENT || ev.kind() == v1::SceneEvent::KIND_ADDED)
        p->objects_[ev.object().instance_id()] = std::move(ev);
    }
  }
  if (!any)
    return InvalidArgument(path +
                           " holds no frames (recorded with frames_hz 0): there is nothing to "
                           "play back; `rheo replay` re-runs it offline instead");
  p->shown_ns_ = p->first_ns_;
  return p;
}

RecordingPlayer::~RecordingPlayer() {
  Stop();
}

void RecordingPlayer::Start() {
  thread_ = std::thread([this] { Run(); });
}

void RecordingPlayer::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

PlaybackState RecordingPlayer::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  PlaybackState s;
  s.file = path_;
  s.duration_s = static_cast<double>(last_ns_ - first_ns_) * 1e-9;
  s.position_s = static_cast<double>(shown_ns_ - first_ns_) * 1e-9;
  s.paused = paused_;
  s.ended = ended_;
  s.speed = speed_;
  s.tick = shown_tick_;
  s.frames = frame_count_;
  s.frames_shown = frames_shown_;
  s.seeks = seeks_;
  return s;
}

void RecordingPlayer::SetPaused(bool paused) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    // Play at the end starts again from the beginning.
    if (!paused && ended_) seek_to_ = first_ns_;
    paused_ = paused;
  }
  cv_.notify_all();
}

void RecordingPlayer::Seek(double seconds) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const double s = std::clamp(seconds, 0.0, static_cast<double>(last_ns_ - first_ns_) * 1e-9);
    seek_to_ = first_ns_ + static_cast<uint64_t>(s * 1e9);
  }
  cv_.notify_all();
}

void RecordingPlayer::StepFrame() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (paused_ && !ended_) ++steps_;
  }
  cv_.notify_all();
}

Status RecordingPlayer::SetSpeed(double speed) {
  if (!(speed > 0.0 && speed <= 100.0))
    return InvalidArgument("speed must be in (0, 100] (1 is the recorded pace); got " +
                           std::to_string(speed));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    speed_ = speed;
  }
  cv_.notify_all();
  return Status::Ok();
}

void RecordingPlayer::Show(const v1::Frame& f, const v1::ToolSample* tool) {
  LoopFrame& lf = scratch_;
  lf.tick = f.stamp().tick();
  lf.sim_time = f.stamp().sim_time();
  lf.published_unix_ns = UnixNowNs();
  lf.paused = f.paused();
  lf.ticks = f.loop().ticks();
  lf.late_ticks = f.loop().late_ticks();
  lf.work_ns = static_cast<int64_t>(f.loop().last_work_us() * 1e3);
  lf.positions.clear();
  lf.object_count = 0;
  std::vector<uint32_t> ids;
  for (const v1::ObjectState& os : f.objects()) {
    if (lf.object_count >= lf.objects.size()) break;
    if (objects_.find(os.instance_id()) == objects_.end()) continue;  // its event was dropped
    FrameObject& fo = lf.objects[lf.object_count++];
    fo.instance_id = os.instance_id();
    fo.first = static_cast<uint32_t>(lf.positions.size() / 3);
    fo.vertex_count = static_cast<uint32_t>(os.positions_size() / 3);
    fo.sleeping = os.sleeping();
    fo.restores = os.restores();
    fo.kinetic_energy = os.kinetic_energy();
    fo.unstable = os.unstable();
    fo.multi_rate = os.multi_rate();
    lf.positions.insert(lf.positions.end(), os.positions().begin(),
                        os.positions().begin() + 3 * fo.vertex_count);
    ids.push_back(os.instance_id());
  }
  uint64_t seeks;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    seeks = seeks_;
  }
  // A seek is a new scene for every client: each gets the surfaces again.
  lf.scene_revision = f.topology_revision() + (seeks << 32);
  if (tool) {
    ToolFromSample(*tool, &lf.tool);
  } else {
    lf.tool = ToolTelemetry{};
  }
  if (ids != scene_now_ || frames_shown_ == 0) {
    std::vector<const v1::SceneEvent*> events;
    for (uint32_t id : ids) events.push_back(&objects_.at(id));
    if (on_scene_) on_scene_(events);
    scene_now_ = std::move(ids);
  }
  hub_->Publish(lf);
  std::lock_guard<std::mutex> lock(mutex_);
  shown_tick_ = lf.tick;
  ++frames_shown_;
}

void RecordingPlayer::Run() {
  pthread_setname_np(pthread_self(), "rheo-playback");
  auto reader = record::McapReader::OpenFile(path_);
  if (!reader.ok()) return;  // Open read it a moment ago; nothing to show if it is gone
  bool seeking = true;       // skip to `target`, then show that frame at once
  uint64_t target = first_ns_;
  while (true) {
    // From the beginning of the file (the start, or a seek): messages before `target` are
    // skipped without pacing, the frame at or after it is shown at once.
    auto cursor = reader->Messages();
    std::string tool_bytes;
    Clock::time_point anchor_wall = Clock::now();
    uint64_t anchor_log = target;
    bool restart = false;
    while (!restart) {
      auto m = cursor.Next();
      if (!m.ok() || !*m) {
        // The end: pause on the last frame until a seek, a play (from the start) or the stop.
        std::unique_lock<std::mutex> lock(mutex_);
        ended_ = true;
        paused_ = true;
        cv_.wait(lock, [&] { return stop_ || seek_to_.has_value(); });
        if (stop_) return;
        target = *seek_to_;
        seeking = true;
        seek_to_.reset();
        ended_ = false;
        ++seeks_;
        restart = true;
        break;
      }
      const std::string& topic = (*m)->channel->topic;
      const uint64_t log = (*m)->log_time;
      if (topic == "/tool") {
        tool_bytes.assign(reinterpret_cast<const char*>((*m)->data.data()), (*m)->data.size());
        continue;
      }
      if (topic != "/frames") continue;
      if (seeking && log < target) continue;
      if (seeking) {
        seeking = false;
        anchor_wall = Clock::now();
        anchor_log = log;
      } else {
        // Wait until the frame is due at the playback's speed; a pause waits for play or a
        // step, a seek starts over, a change of speed or a play re-anchors the pace here.
        std::unique_lock<std::mutex> lock(mutex_);
        double speed = speed_;
        bool was_paused = paused_;
        while (true) {
          if (stop_) return;
          if (seek_to_) {
            target = *seek_to_;
            seeking = true;
            seek_to_.reset();
            ++seeks_;
            restart = true;
            break;
          }
          if (paused_) {
            was_paused = true;
            if (steps_ > 0) {
              --steps_;
              break;
            }
            cv_.wait(lock);
            continue;
          }
          if (was_paused || speed != speed_) {
            // Re-anchored at the frame shown: the next one is due one frame interval on.
            anchor_wall = Clock::now();
            anchor_log = shown_ns_;
            speed = speed_;
            was_paused = false;
          }
          const auto due = anchor_wall + std::chrono::nanoseconds(static_cast<int64_t>(
                                             static_cast<double>(log - anchor_log) / speed));
          if (Clock::now() >= due) break;
          cv_.wait_until(lock, due);
        }
        if (restart) break;
      }
      v1::Frame f;
      const auto d = (*m)->data;
      if (!f.ParseFromArray(d.data(), static_cast<int>(d.size()))) continue;
      v1::ToolSample tool;
      const bool have_tool =
          !tool_bytes.empty() &&
          tool.ParseFromArray(tool_bytes.data(), static_cast<int>(tool_bytes.size()));
      {
        std::lock_guard<std::mutex> lock(mutex_);
        shown_ns_ = log;
      }
      Show(f, have_tool ? &tool : nullptr);
    }
  }
}

}  // namespace rheo::daemon
