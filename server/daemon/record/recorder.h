// The session recorder: one recording at a time, written by a thread of its own into an MCAP file
// (rheo_record) from what the loop hands over through the tick ring, the frames of the frame hub,
// and the events the services post. The loop itself only pushes one plain record per tick.
#pragma once

#include <google/protobuf/message.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/status.h"
#include "daemon/loop/engine.h"
#include "daemon/loop/frame_hub.h"
#include "daemon/loop/tick_ring.h"
#include "rheo/v1/daemon.pb.h"
#include "rheo/v1/frames.pb.h"
#include "rheo/v1/recording.pb.h"

namespace rheo::daemon {

/// The MCAP topics a recording holds.
inline constexpr const char* kToolTopic = "/tool";
inline constexpr const char* kFramesTopic = "/frames";
inline constexpr const char* kSceneTopic = "/scene";
inline constexpr const char* kParametersTopic = "/parameters";
inline constexpr const char* kCommandsTopic = "/commands";
inline constexpr const char* kLoopTopic = "/loop";

/// The device counters of one tick's tool telemetry, as DeviceStatus and the recording's
/// `/tool` channel both carry them.
void FillDeviceCounters(const ToolTelemetry& t, v1::DeviceCounters* out);

struct RecorderOptions {
  std::string dir;                // where <id>.mcap and <id>.json go (created when missing)
  std::string library = "rheod";  // the MCAP header's library field
  /// The frame as WatchFrames sends it (positions as floats); with `topology`, each object's
  /// surface too. Called on the recorder thread.
  std::function<void(const LoopFrame& frame, bool topology, v1::Frame* out)> fill_frame;
  /// The loop's health as GetStatus reports it. Called on the recorder thread once a second.
  std::function<void(v1::LoopStatus* out)> fill_loop_status;
  /// Events waiting for the recorder thread, at most this many and this many bytes; a post
  /// past either is dropped and counted (Recording.dropped_events).
  size_t max_pending_events = 4096;
  size_t max_pending_bytes = size_t{256} << 20;
  uint64_t chunk_size = uint64_t{1} << 20;  // MCAP chunk [bytes] (zstd)
  /// Start refuses when the directory's file system has less free space than this [bytes].
  uint64_t min_free_bytes = uint64_t{4} << 20;
};

/// Thread-safe. Start/Stop/List/Delete come from the services, Post* from any handler; the
/// recorder thread owns the file while a recording runs.
class Recorder {
 public:
  Recorder(Engine& engine, FrameHub& hub, TickRing& ring, RecorderOptions options);
  ~Recorder();  // Shutdown()
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  /// Lists the directory: every <id>.mcap is opened with McapReader (its counts and times come
  /// from the file) and its <id>.json side file read for what the file does not hold (name,
  /// state, error, drop counts). A file without footer that was still recording is TRUNCATED.
  /// @return the number of recordings found; an error only when the directory cannot be made.
  Result<size_t> Load();

  /// Starts a recording. `frames_hz` 0 (no frames) or 1..1000; `name` a label ("" = the id);
  /// `initial` the /scene events of the objects in the scene now (KIND_PRESENT). Errors:
  /// FAILED_PRECONDITION naming the running recording, INVALID_ARGUMENT, RESOURCE_EXHAUSTED (too
  /// little free space), the file's own (cannot create), UNAVAILABLE after Shutdown.
  Result<v1::Recording> Start(const std::string& name, double frames_hz,
                              std::vector<v1::SceneEvent> initial);
  /// Stops the running recording: everything the loop and the services handed over is written,
  /// then the summary and the footer. FAILED_PRECONDITION when none is running (and, when the
  /// last one failed, why).
  Result<v1::Recording> Stop();
  /// Every recording, oldest first (the running one with its counts so far).
  std::vector<v1::Recording> List();
  /// The file of recording `id` for export. NOT_FOUND, INVALID_ARGUMENT (not an id),
  /// FAILED_PRECONDITION while it is being recorded.
  Result<std::string> FileFor(const std::string& id);
  /// Deletes the file and its side file. As FileFor for the errors.
  Status Delete(const std::string& id);
  /// Stops a running recording cleanly and refuses new ones (rheod's shutdown). What it stopped.
  std::optional<v1::Recording> Shutdown();

  /// True while a recording runs: a handler checks this before building an event.
  bool recording() const { return recording_.load(std::memory_order_acquire); }
  /// Hands an event to the recorder thread (log time: now). Never blocks beyond a short lock;
  /// dropped and counted when the queue is full; ignored when no recording runs.
  void Post(v1::SceneEvent event);
  void Post(v1::ParameterChange event);
  /// `received_unix_ns` is the command's log time.
  void Post(v1::CommandEvent event, int64_t received_unix_ns);

  const std::string& dir() const { return options_.dir; }
  /// Wall clock [ns since the Unix epoch].
  static int64_t UnixNowNs();

  struct Session;  // one recording being written (recorder.cc)

 private:
  // Queues an event for the running session (drop + count when its queue is full).
  void Enqueue(int channel, int64_t log_time_ns, std::unique_ptr<google::protobuf::Message> m);
  // Joins a session whose thread has ended (failed) and files it under index_. Holds mutex_.
  void ReapLocked();
  bool ValidId(const std::string& id) const;

  Engine& engine_;
  FrameHub& hub_;
  TickRing& ring_;
  RecorderOptions options_;

  // Start, Stop and Shutdown one at a time; held while a stopping session's thread is joined.
  std::mutex control_mutex_;
  std::mutex mutex_;  // index_, session_, closed_: held briefly (Post, List)
  std::map<std::string, v1::Recording> index_;  // finished recordings by id
  std::unique_ptr<Session> session_;            // the running (or just failed) one
  std::string last_failure_;  // "rec-...: why", of the last recording that failed, until Start
  bool closed_ = false;
  std::atomic<bool> recording_{false};
};

}  // namespace rheo::daemon
