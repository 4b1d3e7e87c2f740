// rheod --replay FILE: a session recording played back to every client as if the loop were
// producing it. A thread of its own reads the file's /frames at the recorded pace (or faster,
// slower, paused, stepped, sought) and hands each frame, with the tool as /tool recorded it at
// that tick, to the frame hub, so WatchFrames, the studio and every viewer show it unchanged.
#pragma once

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
#include "rheo/v1/frames.pb.h"
#include "rheo/v1/recording.pb.h"

namespace rheo::daemon {

/// Where the playback is.
struct PlaybackState {
  std::string file;
  double duration_s = 0.0;  // from the first frame to the last [s]
  double position_s = 0.0;  // the frame shown now, from the first [s]
  bool paused = false;
  bool ended = false;  // at the last frame (paused there)
  double speed = 1.0;
  uint64_t tick = 0;  // the loop tick of the frame shown
  uint64_t frames = 0;
  uint64_t frames_shown = 0;  // published since the start
  uint64_t seeks = 0;
};

class RecordingPlayer {
 public:
  /// The objects of the frame about to be published changed (entered, left, or a seek): their
  /// /scene events (KIND_PRESENT or KIND_ADDED, with mesh and parameters), for the scene
  /// registry. Called on the player thread before that frame is published.
  using SceneFn = std::function<void(const std::vector<const v1::SceneEvent*>& objects)>;

  /// Reads the file's index (its scene events and the span of its frames). Errors: not MCAP, no
  /// /frames (recorded with frames_hz 0: nothing to show), a message that does not parse.
  static Result<std::unique_ptr<RecordingPlayer>> Open(const std::string& path, FrameHub& hub,
                                                       SceneFn on_scene);
  ~RecordingPlayer();  // Stop()

  /// Starts the thread; playback begins at the first frame, playing.
  void Start();
  void Stop();

  PlaybackState state() const;
  void SetPaused(bool paused);
  /// Shows the frame at or after `seconds` from the first (clamped to the recording) at once,
  /// and carries on from there (paused stays paused).
  void Seek(double seconds);
  /// While paused: shows the next frame.
  void StepFrame();
  /// Playback speed, (0, 100]: 1 is the recorded pace.
  Status SetSpeed(double speed);

 private:
  RecordingPlayer() = default;
  void Run();
  // Publishes one recorded frame (hub snapshot), syncing the scene first when its objects
  // changed. Player thread.
  void Show(const v1::Frame& f, const v1::ToolSample* tool);

  std::string path_;
  FrameHub* hub_ = nullptr;
  SceneFn on_scene_;
  std::map<uint32_t, v1::SceneEvent> objects_;  // by instance id: every object the file has
  uint64_t first_ns_ = 0, last_ns_ = 0;         // log times of the first and last frame
  uint64_t frame_count_ = 0;

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  bool paused_ = false;
  bool ended_ = false;
  double speed_ = 1.0;
  std::optional<uint64_t> seek_to_;  // log time asked for
  int steps_ = 0;                    // frames to show while paused
  uint64_t shown_ns_ = 0;            // log time of the frame shown
  uint64_t shown_tick_ = 0;
  uint64_t frames_shown_ = 0;
  uint64_t seeks_ = 0;
  std::thread thread_;

  // Player thread.
  std::vector<uint32_t> scene_now_;  // instance ids of the frame last shown
  LoopFrame scratch_;
};

/// The tool of one /tool sample as the loop's telemetry (what frames carry).
void ToolFromSample(const v1::ToolSample& s, ToolTelemetry* out);

}  // namespace rheo::daemon
