// The engine: the 1 kHz loop, the queue of scene commands into it and the frames out of it.
#pragma once

#include <array>
#include <atomic>
#include <boost/lockfree/spsc_queue.hpp>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "daemon/loop/multirate_object.h"
#include "daemon/loop/seq_slot.h"
#include "rt/command_queue.h"
#include "rt/loop.h"
#include "rt/triple_buffer.h"
#include "sim/sim.h"

namespace rheo::daemon {

/// Most objects one scene holds at once.
inline constexpr int kMaxSceneObjects = 16;

class TickRing;  // daemon/loop/tick_ring.h: what a session recording takes from each tick

/// Per-object state of the haptic side (the device link's renderer), opaque to the engine. It is
/// built outside the loop, handed over with kAddObject and retired with the object.
class ObjectContact {
 public:
  virtual ~ObjectContact() = default;
};

/// A scene command, plain data so the queue never allocates. Payloads that need memory are
/// allocated by the sender and handed over by pointer; the loop gives them back through the
/// retire queue, and they are freed outside the loop.
struct Command {
  enum class Type : uint8_t {
    kNone,
    kPause,
    kResume,
    kReset,
    kStep,
    kAddObject,        // object or multirate: ownership passes to the loop
    kRemoveObject,     // instance_id
    kSetParameters,    // instance_id, params (prepared off the loop): applied, then retired
    kDeviceCalibrate,  // the device link calibrates on the loop thread
    kDeviceClear,      // clear an emergency stop and latched faults
    kSetToolOrigin,    // vec: scene position of the device frame's origin [m]
  };
  Type type = Type::kNone;
  uint64_t seq = 0;  // assigned by Engine::Submit; the loop acknowledges it in applied_seq
  uint32_t instance_id = 0;
  sim::SimObject* object = nullptr;
  MultiRateObject* multirate = nullptr;  // kAddObject: instead of `object`, stepped multi-rate
  sim::PreparedParameters* params = nullptr;
  ObjectContact* contact = nullptr;  // kAddObject: ownership passes to the loop (may be null)
  std::array<double, 3> vec{};       // kSetToolOrigin [m]
};

/// Most commands the loop applies in one tick (a flood is spread over ticks).
inline constexpr int kMaxCommandsPerTick = 16;

/// A command as the loop applied it, without its payload: the session recording lists each
/// tick's, so that a replay applies the same commands at the same ticks.
struct AppliedCommand {
  Command::Type type = Command::Type::kNone;
  uint64_t seq = 0;
  uint32_t instance_id = 0;
};

/// Memory the loop no longer uses, to be freed by another thread.
struct Retired {
  sim::SimObject* object = nullptr;
  sim::PreparedParameters* params = nullptr;  // holds the object's previous tet flags
  ObjectContact* contact = nullptr;
  MultiRateObject* multirate = nullptr;  // its destructor joins the whole's thread
};

/// The haptic tool as the loop saw it in one tick: plain data, published in every frame and in a
/// lock-free slot that any thread may read (status, the network tool's feedback).
struct ToolTelemetry {
  uint64_t tick = 0;
  bool present = false;  // a device is attached
  bool connected = false;
  bool calibrated = false;
  bool in_contact = false;
  bool emergency_stopped = false;
  bool watchdog_tripped = false;
  uint32_t faults = 0;            // drivers::Fault bits
  uint32_t contact_instance = 0;  // scene instance the tool renders against (0: none)
  int32_t num_motors = 0;         // entries used in tensions and lengths
  /// No device fault this tick: the object under the tool took the renderer's node forces.
  bool object_loaded = false;
  std::array<double, 3> device_position{};               // grip centre, scene frame [m]
  std::array<double, 3> device_velocity{};               // grip velocity, scene frame [m/s]
  std::array<double, 4> device_orientation{1, 0, 0, 0};  // unit quaternion w, x, y, z
  std::array<double, 3> proxy{};                         // proxy centre, scene frame [m]
  std::array<double, 3> tool_origin{};       // scene position of the device frame's origin [m]
  std::array<double, 3> requested_force{};   // after the device's limits [N]
  std::array<double, 3> requested_torque{};  // [N m]
  std::array<double, 3> displayed_force{};   // what the device displays on the hand [N]
  std::array<double, 3> displayed_torque{};  // [N m]
  std::array<double, 3> object_force{};      // sum of the node forces put on the object [N]
  std::array<double, 8> tensions{};          // commanded string tensions (num_motors) [N]
  std::array<double, 8> lengths{};           // measured string lengths (num_motors) [m]
  double tip_radius = 0.0;                   // [m]
  double stiffness = 0.0;                    // coupling stiffness in use [N/m]
  uint64_t exchanges = 0;                    // successful device exchanges
  uint64_t device_errors = 0;                // exchanges that failed
  uint64_t protocol_errors = 0;              // the driver's count of bad or missing replies
  uint64_t deadline_misses = 0;  // ticks whose device command left after the next deadline
  uint64_t watchdog_trips = 0;
  uint64_t recoveries = 0;       // automatic restarts after a watchdog trip
  uint64_t renderer_errors = 0;  // renderer updates that failed (no force that tick)
  uint64_t calibrations = 0;     // successful calibrations
  uint64_t calibration_failures = 0;
  uint64_t input_seq = 0;  // network tool: the last input sequence number the loop used
  // The serial line (SPIDAR-G): times it went away, reopen attempts and reopens since start; the
  // wait before the next attempt and how long it has been away (both 0 while it is up) [s]; when
  // the last attempt was made (CLOCK_MONOTONIC [ns], 0 before any).
  uint64_t line_losses = 0;
  uint64_t reconnect_attempts = 0;
  int64_t reconnect_attempt_ns = 0;
  uint64_t reconnects = 0;
  double reconnect_backoff_s = 0.0;
  double disconnected_s = 0.0;
};

/// One scene object as the loop holds it: a SimObject stepped whole every tick, or (`multirate`
/// set, `object` null) one too fine for that, stepped multi-rate.
struct EngineSlot {
  uint32_t instance_id = 0;
  sim::SimObject* object = nullptr;
  ObjectContact* contact = nullptr;
  MultiRateObject* multirate = nullptr;

  // What the loop asks of either kind (loop thread only).
  /// One tick.
  sim::StepResult Step(double dt) { return multirate ? multirate->Tick(dt) : object->Step(dt); }
  /// Back to rest (a multi-rate object at its whole's next step).
  void Reset() {
    if (multirate) {
      multirate->RequestReset();
    } else {
      object->Reset();
    }
  }
  /// Node positions to render and publish.
  std::span<const Vec3> positions() const {
    return multirate ? multirate->positions() : object->positions();
  }
  bool sleeping() const { return multirate ? multirate->sleeping() : object->sleeping(); }
  uint64_t restores() const {
    return multirate ? multirate->restores() : static_cast<uint64_t>(object->events().restores);
  }
  double kinetic_energy() const {
    return multirate ? multirate->kinetic_energy() : object->kinetic_energy();
  }
  // An object whose state keeps going non-finite or exploding is stopped (no longer stepped,
  // shown in its last good state) after kRestoresBeforeStop restores within kRestoreWindowTicks,
  // until its parameters change or the scene is reset: restoring it forever costs every tick.
  uint64_t restore_window_start = 0;  // tick the current count began
  uint32_t restores_in_window = 0;
  bool unstable = false;
};

inline constexpr uint32_t kRestoresBeforeStop = 5;
inline constexpr uint64_t kRestoreWindowTicks = 1000;

/// The haptic side of each tick (DeviceLink, in rheod_device). Every method runs on the loop
/// thread and must not allocate, log or block.
class TickDevice {
 public:
  virtual ~TickDevice() = default;
  /// After the simulation step (which reads nothing from the device): exchange with the device,
  /// contact against `slots`, node forces for the next step, the device command; fills `out`.
  virtual void Tick(const rt::TickInfo& info, std::span<EngineSlot> slots, ToolTelemetry* out) = 0;
  /// Device commands (kDeviceCalibrate, kDeviceClear, kSetToolOrigin).
  virtual void Apply(const Command& command) = 0;
  /// The object in `slot` is leaving the loop: forget any pointer into it.
  virtual void Forget(const EngineSlot& slot) = 0;
};

/// One object's part of a frame.
struct FrameObject {
  uint32_t instance_id = 0;
  uint32_t first = 0;  // index of its first vertex in LoopFrame::positions / 3
  uint32_t vertex_count = 0;
  bool sleeping = false;
  uint64_t restores = 0;        // recoveries from a non-finite or exploding state so far
  double kinetic_energy = 0.0;  // [J]
  bool unstable = false;        // stopped after repeated restores (EngineSlot::unstable)
  bool multi_rate = false;      // stepped multi-rate (MultiRateObject)
};

/// What the loop publishes every tick. Preallocated; the loop fills it without allocating.
struct LoopFrame {
  uint64_t tick = 0;
  double sim_time = 0.0;          // [s]
  int64_t published_unix_ns = 0;  // wall clock when the loop published it (for latency)
  bool paused = false;
  int64_t work_ns = 0;  // time spent in the previous tick [ns]
  uint64_t late_ticks = 0;
  uint64_t ticks = 0;
  uint64_t scene_revision = 0;  // bumps when objects are added or removed, or the scene reset
  uint32_t object_count = 0;
  std::array<FrameObject, kMaxSceneObjects> objects{};
  std::vector<float> positions;  // x, y, z per vertex [m]; capacity fixed at start
  ToolTelemetry tool;
};

struct EngineOptions {
  rt::LoopOptions loop;
  uint32_t max_frame_vertices = 400000;  // vertices over all scene objects
};

/// Owns the real-time loop thread. Everything inside Tick() is allocation-free and lock-free;
/// other threads talk to it only through Submit(), the retire queue and the frame triple buffer.
class Engine {
 public:
  explicit Engine(EngineOptions options);
  ~Engine();

  /// Attaches the haptic side; call before Start(). The engine does not own it.
  void AttachDevice(TickDevice* device) { device_ = device; }
  /// Attaches the session recorder's ring; call before Start(). While the ring has a session,
  /// every tick offers it one plain record (no allocation, no lock; dropped when it is full).
  void AttachTickRing(TickRing* ring) { tick_ring_ = ring; }
  void Start();
  void Stop();
  /// Runs one tick on the calling thread, exactly as the loop thread runs it, for a caller that
  /// owns the timing (a test counting the tick's allocations, an offline replay). Never while
  /// the loop runs (between Start() and Stop()).
  void TickOnce(const rt::TickInfo& info) { Tick(info); }

  /// Queues a command for the next tick. Returns its sequence number, or 0 when the queue is full
  /// (the caller keeps ownership of any payload then).
  uint64_t Submit(Command command);
  /// Sequence number of the last command whose tick has completed.
  uint64_t applied_seq() const { return applied_seq_.load(std::memory_order_acquire); }
  /// Waits (polling, off the loop) until the loop applied `seq` or `timeout_ns` passed.
  bool WaitApplied(uint64_t seq, int64_t timeout_ns) const;
  /// Frees what the loop handed back. Any one thread at a time (the frame hub does it).
  void DrainRetired();

  /// Frame reader side: only one thread (the frame hub) may call these.
  bool AcquireFrame() { return frames_.Acquire(); }
  const LoopFrame& frame() const { return frames_.front(); }

  /// The tool as of the last tick, from any thread.
  ToolTelemetry tool() const { return tool_.Load(); }

  const rt::Loop& loop() const { return loop_; }
  const EngineOptions& options() const { return options_; }
  uint64_t commands_applied() const { return commands_applied_.load(std::memory_order_relaxed); }
  uint64_t commands_rejected() const { return commands_rejected_.load(std::memory_order_relaxed); }
  uint64_t restores() const { return restores_.load(std::memory_order_relaxed); }
  /// Objects stopped after repeated restores, now.
  uint32_t unstable_objects() const { return unstable_objects_.load(std::memory_order_relaxed); }
  bool paused() const { return paused_.load(std::memory_order_relaxed); }
  double sim_time() const { return sim_time_.load(std::memory_order_relaxed); }
  int object_count() const { return object_count_.load(std::memory_order_relaxed); }

 private:
  void Tick(const rt::TickInfo& info);
  void Apply(const Command& c);
  void Retire(Retired r);
  int FindSlot(uint32_t instance_id) const;
  void MarkStable(EngineSlot& slot);

  EngineOptions options_;
  rt::Loop loop_;
  rt::CommandQueue<Command, 1024> commands_;
  std::array<AppliedCommand, kMaxCommandsPerTick> applied_{};  // this tick's (loop thread)
  int applied_count_ = 0;
  boost::lockfree::spsc_queue<Retired, boost::lockfree::capacity<2048>> retired_;
  rt::TripleBuffer<LoopFrame> frames_;
  std::atomic<uint64_t> next_seq_{1};
  std::atomic<uint64_t> applied_seq_{0};
  std::atomic<uint64_t> commands_applied_{0};
  std::atomic<uint64_t> commands_rejected_{0};
  std::atomic<uint64_t> restores_{0};
  std::atomic<uint32_t> unstable_objects_{0};
  std::atomic<bool> paused_{false};
  std::atomic<double> sim_time_{0.0};
  std::atomic<int> object_count_{0};

  TickDevice* device_ = nullptr;
  TickRing* tick_ring_ = nullptr;
  SeqSlot<ToolTelemetry> tool_;

  // Loop-thread state.
  std::array<EngineSlot, kMaxSceneObjects> slots_{};
  ToolTelemetry tool_scratch_;
  int slot_count_ = 0;
  bool step_once_ = false;
  uint64_t last_applied_seq_ = 0;
  uint64_t sim_ticks_ = 0;  // ticks simulated since the last reset (time = ticks x dt)
  int64_t last_work_ns_ = 0;
  uint64_t scene_revision_ = 1;
};

}  // namespace rheo::daemon
