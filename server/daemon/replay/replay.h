// Offline replay of a session recording: the loop's own engine, ticked by hand, given the
// recorded inputs (each object's mesh, preset, integrator and parameters, every command at the
// tick the loop applied it, the tool's pose and velocity every tick) and compared against what
// the recording says came out (the frames' positions, the tool's proxy and object force).
//
// On the build that made the recording the replay is bit-identical: the same objects built from
// the same doubles, the same commands at the same ticks, the same renderer code (ToolContact)
// fed the same pose. What the recording cannot give back is reported as a caveat instead:
// objects already in the scene when it started (replayed from their rest shape), multi-rate
// objects (their whole stepped on a thread of its own, so their syncs fall where the machine's
// timing put them), ticks the recorder's ring dropped, events its queue dropped, a file cut off.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "common/status.h"

namespace rheo::daemon {

struct ReplayOptions {
  /// Parameter values put over every object's (on entering the scene and on every change): a
  /// what-if replay ("the same hand on a harder object"), measured against the recording.
  std::vector<std::pair<std::string, double>> set;
  /// Called after every replayed tick with its number (progress for a long file).
  std::function<void(uint64_t tick)> on_tick;
};

struct ReplayReport {
  std::string file;
  uint64_t first_tick = 0, last_tick = 0;
  uint64_t ticks = 0;     // replayed
  uint64_t objects = 0;   // that entered the replayed scene
  uint64_t commands = 0;  // applied
  // Frames: each recorded frame against the replay's positions at its tick (floats, as sent).
  uint64_t frames_compared = 0;
  uint64_t frames_identical = 0;  // every coordinate bit for bit
  double max_position_diff_m = 0.0;
  uint64_t max_position_tick = 0;
  // Tool: each /tool sample's proxy and object force against the replay's.
  uint64_t samples_compared = 0;
  uint64_t samples_identical = 0;  // proxy, object force and contact bit for bit
  uint64_t contact_ticks = 0;      // samples in contact (as recorded)
  double max_proxy_diff_m = 0.0;
  double max_force_diff_n = 0.0;
  uint64_t max_force_tick = 0;
  uint64_t first_difference_tick = 0;  // 0: none
  /// Why this replay is not a check of determinism (empty when it is one).
  std::vector<std::string> caveats;
  double wall_s = 0.0;  // time the replay took [s]

  /// Every frame and every sample bit for bit, with nothing in the caveats.
  bool bit_identical() const {
    return caveats.empty() && frames_identical == frames_compared &&
           samples_identical == samples_compared && samples_compared > 0;
  }
};

/// Replays the recording at `path`. Errors: the file cannot be read as MCAP, it has no /tool
/// channel (not a rheod recording), an object's mesh or parameters do not build (the message
/// names the object and why), an option names no parameter.
Result<ReplayReport> ReplayRecording(const std::string& path, const ReplayOptions& options = {});

}  // namespace rheo::daemon
