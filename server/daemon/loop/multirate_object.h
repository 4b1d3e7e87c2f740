// A scene object too fine for the 1 ms tick, stepped multi-rate (sim/multirate.h): the patch
// around the tool on the loop, every tick; the whole object on a thread of its own, one step in
// flight, each step covering the ticks since the last.
//
// The loop's side never allocates, locks or waits. The hand-over is one atomic phase:
//   kDone: the whole's thread is idle and has left its results (the whole's new state, a patch it
//          built, the state it reports). At a sync the loop takes them (MultiRate::Sync: the
//          patch follows the whole or is swapped for the new one), hands over the focus, the
//          requests and the window of loads just closed, and sets kRunning.
//   kRunning: the whole's thread frees what the loop gave back (the old patch, parameters it
//          replaced), applies a reset or new parameters, steps the whole over the closed
//          window's duration with its average load, builds a patch when asked, and sets kDone.
// A sync is due every `period` ticks; while the whole is still running the loop goes on with the
// patch (its boundary, which moved on along the whole's last velocities for a period, now held
// still) and counts the late ticks.
// Each whole step covers `period` ticks of simulated time, with the average load of however many
// ticks its window had: a whole that cannot keep up runs behind real time (whole_lag_s says by
// how much) rather than taking steps longer than its substeps were chosen for. The hand keeps
// its 1 kHz either way.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <thread>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"
#include "sim/multirate.h"
#include "sim/sim.h"

namespace rheo::daemon {

/// Counters from any thread (relaxed atomics).
struct MultiRateStats {
  uint64_t syncs = 0;       // whole steps taken in
  uint64_t late_ticks = 0;  // ticks past a due sync while the whole was still stepping
  uint64_t rebuilds = 0;    // patches taken in (the first included)
  uint64_t whole_restores = 0;
  uint64_t patch_restores = 0;
  int64_t whole_step_ns = 0;      // the last whole step's duration [ns]
  int64_t whole_step_max_ns = 0;  // the longest so far [ns]
  double whole_window_s = 0.0;    // the last step's window: the ticks its load averaged [s]
  double whole_lag_s = 0.0;       // how far the whole's time is behind the loop's [s]
  int32_t patch_inner_nodes = 0;
  int32_t patch_tets = 0;
  int32_t period = 0;          // ticks between syncs when the whole keeps up
  int32_t whole_substeps = 0;  // implicit substeps per whole step (doubled after a restore)
};

class MultiRateObject {
 public:
  /// Most tool loads per tick (the renderer touches at most 24 nodes).
  static constexpr int kMaxLoads = 64;

  /// Takes `whole` over (implicit integrator), builds the first patch around `focus` [m] and
  /// starts the whole's thread. INVALID_ARGUMENT for a bad period or options, an explicit
  /// integrator, or a focus that takes no node.
  static Result<std::unique_ptr<MultiRateObject>> Create(std::unique_ptr<sim::SimObject> whole,
                                                         int32_t period,
                                                         const sim::PatchOptions& options,
                                                         const Vec3& focus);
  ~MultiRateObject();  // stops and joins the whole's thread (never on the loop)
  MultiRateObject(const MultiRateObject&) = delete;
  MultiRateObject& operator=(const MultiRateObject&) = delete;

  // ---- The loop's thread. None of these allocate, lock or wait.
  /// One tick: a sync when due and the whole is done, then the patch's step with the loads set
  /// since the last tick.
  sim::StepResult Tick(double dt);
  /// Positions to render and publish: the whole at its last sync, the patch's inner nodes over it.
  std::span<const Vec3> positions() const { return mr_.positions(); }
  /// A tool load for the next tick (false when kMaxLoads are set already).
  bool AddLoad(const sim::NodeLoad& load);
  void ClearLoads() { load_count_ = 0; }
  /// Where the tool is (the proxy) [m]: the patch is built around it.
  void SetFocus(const Vec3& focus) { focus_ = focus; }
  /// Back to rest at the whole's next step (the patch built again then).
  void RequestReset() { reset_requested_ = true; }
  /// New parameters at the whole's next step; returns a set given earlier and not yet taken in
  /// (to be retired by the caller), else null. Ownership of `params` passes here.
  sim::PreparedParameters* RequestParameters(sim::PreparedParameters* params);
  /// As of the last sync.
  bool sleeping() const { return sleeping_; }
  double kinetic_energy() const { return kinetic_energy_; }
  uint64_t restores() const {
    return patch_restores_.load(std::memory_order_relaxed) +
           whole_restores_.load(std::memory_order_relaxed);
  }

  // ---- Any thread.
  MultiRateStats stats() const;
  /// The whole's model (topology, rest shape, masses: fixed after Create) for Prepare and cost
  /// predictions on other threads.
  const sim::SimObject& whole() const { return mr_.whole(); }

 private:
  enum Phase : uint32_t { kDone = 0, kRunning = 1, kStop = 2 };
  explicit MultiRateObject(sim::MultiRate mr) : mr_(std::move(mr)) {}
  void Run();  // the whole's thread

  sim::MultiRate mr_;
  std::atomic<uint32_t> phase_{kDone};
  std::atomic<bool> stop_{false};
  std::thread thread_;

  // Loop-only.
  std::array<sim::NodeLoad, kMaxLoads> loads_{};
  int load_count_ = 0;
  Vec3 focus_ = Vec3::Zero();
  int32_t since_sync_ = 0;
  bool boundary_held_ = false;
  bool stepped_since_sync_ = false;  // the patch stepped (the tool touched) since the last sync  //
                                     // the whole is late and the patch's boundary holds still
  double tick_s_ = 1e-3;             // the patch's tick, and the loop's [s]
  bool reset_requested_ = false;
  sim::PreparedParameters* params_requested_ = nullptr;
  bool sleeping_ = false;
  bool whole_sleeping_ = false;  // as of the last sync
  double kinetic_energy_ = 0.0;

  // Handed over at a sync (written by one side before the phase changes, read by the other
  // after it: the phase's release and acquire order them).
  Vec3 focus_in_ = Vec3::Zero();
  bool wants_patch_in_ = false;
  bool reset_in_ = false;
  sim::PreparedParameters* params_in_ = nullptr;
  double lag_s_ = 0.0;                   // the whole's thread
  std::optional<sim::Patch> patch_out_;  // built by the whole's thread / the old one given back
  bool replace_out_ = false;
  bool sleeping_out_ = false;
  double kinetic_energy_out_ = 0.0;

  // Counters.
  std::atomic<uint64_t> syncs_{0}, late_ticks_{0}, rebuilds_{0}, whole_restores_{0},
      patch_restores_{0};
  std::atomic<int64_t> whole_step_ns_{0}, whole_step_max_ns_{0};
  std::atomic<double> whole_window_s_{0.0}, whole_lag_s_{0.0};
  std::atomic<int32_t> patch_inner_{0}, patch_tets_{0}, whole_substeps_{0};
};

}  // namespace rheo::daemon
