// Multi-rate stepping for an object whose full step does not fit the tick: the region near the
// tool steps every tick, the whole object at its own, longer period.
//
//   Patch: the whole's tetrahedra that touch a node within `radius` of a point, as a SimObject of
//   its own. Its inner nodes (those within the radius) carry every element they belong to, so
//   they feel exactly the forces they feel in the whole; the other nodes of those tetrahedra are
//   its boundary, held on the whole's trajectory (positions and velocities taken at each sync,
//   moving on linearly until the next). The global volume condition (eq. 4) stays implicit in the
//   patch, on the whole's volume: what the patch's faces enclose plus the rest taken at each sync.
//
//   The coupling (server/sim/README.md, Multi-rate): every tick the tool's contact forces act on
//   the patch and are summed into a ForceWindow; at each sync the whole takes their average over
//   the window as its load for its next step, and the patch's boundary takes the whole's new state.
//   So the hand and the object exchange the same forces (equal and opposite, up to the window's
//   delay), and the inner nodes follow the whole wherever the tool does not reach.
//
// Pure, like the rest of rheo::sim: Build allocates; Follow, the force setters and Step do not.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"
#include "sim/sim.h"

namespace rheo::sim {

/// The substep of a whole that would run behind real time at the loop's tick: fewer, longer
/// substeps, so that it falls behind less. With the floor in the implicit solve, the 15.4k-tet
/// bean dropped 2 cm onto the floor restored 0 times in 0.6 s at 1, 2 and 2.5 ms substeps with
/// each of hard-jelly, soft-jelly and organ (hard-jelly restored once at 5 ms); its peak
/// compression at 2 ms is 3-8 % over 1 ms's (`rheo simulate --dt 0.01 --set
/// implicit_substeps=5`). BDF2 at 2 ms ticks costs 0.60-0.88 of 1 ms's CPU per simulated second
/// at 4.6k and 21.6k tets, shape error 0.12-0.67 % (bench/sim/results/precision_sizes.txt).
/// Before the floor joined the solve, 2 and 2.5 ms substeps restored 51-52 times in that drop.
/// A step that has to be restored doubles the substeps (rheod's MultiRateObject), as at any
/// substep. rheod takes it for such a whole; tick_cost_bench measures it.
constexpr double kBehindWholeSubstep = 2e-3;

struct PatchOptions {
  double radius = 0.015;  ///< inner nodes lie within this distance of the centre [m], (0, 1]
  double tick = 1e-3;     ///< the patch's tick [s], (0, 0.1]: its BDF2 history is made for it
  /// Longest substep of the whole's step [s], (0, 0.1]. The implicit integrator is stable at any
  /// step, but its nonlinear elements are not accurate beyond a few ms: on an organ-preset box
  /// under a tool load, one 5 ms step swings the loaded node by +-5 mm where 1 ms steps hold it;
  /// 2.5 ms substeps stay within 0.4 mm (tests/sim/multirate_test.cc).
  double whole_substep = 2.5e-3;
  /// At most this many inner nodes (0: no limit): on a finer mesh the radius shrinks to the
  /// distance of the nearest max_inner_nodes free nodes, so the patch's tick costs about the
  /// same at any resolution. A fixed 15 mm took 1,468 tets of the bean at 21.6k tets and 6,898 at
  /// 100.7k, whose ticks (0.85 and 6.7 ms) did not fit the 1 ms loop (sim_bench multirate).
  int32_t max_inner_nodes = 64;
};

/// INVALID_ARGUMENT naming the first option out of its range. Patch::Build and MultiRate::Create
/// both check.
Status CheckPatchOptions(const PatchOptions& options);

class Patch {
 public:
  /// The patch of `whole` around `center` at the whole's current state (positions, velocities,
  /// Voigt ratios and tensions copied). Allocates. INVALID_ARGUMENT for a bad radius or one that
  /// takes no node. The patch steps with `params` (validated by the whole; null: the whole's).
  static Result<Patch> Build(const SimObject& whole, const Vec3& center,
                             const PatchOptions& options, const Parameters* params = nullptr);

  /// The whole has reached a new state: boundary nodes take its positions and velocities, and the
  /// whole's volume outside the patch's faces is taken again. A pass over the whole's faces; does
  /// not allocate. `inner_nodes_too`: the inner nodes take the whole's state as well (a patch
  /// that did not step since the last sync, the tool away; their history restarts).
  void Follow(const SimObject& whole, bool inner_nodes_too = false);

  /// The boundary stops where it is (zero velocity) until the next Follow: for a whole that runs
  /// late, whose last velocities would otherwise carry the boundary on past where the whole is
  /// (a falling object's boundary through the floor). Does not allocate.
  void HoldBoundary();

  /// Tool force on a node of the whole [N], held until ClearToolForces. Returns false (and does
  /// nothing) when the node is not an inner node of the patch.
  /// `stiffness` as in SimObject::SetExternalForce.
  bool SetToolForce(int32_t whole_node, const Vec3& force, double stiffness = 0.0);
  void ClearToolForces();

  /// One tick of the patch.
  StepResult Step(double dt) { return object_->Step(dt); }

  /// Writes the inner nodes' positions over `whole_positions` (the whole's node array).
  void Overlay(std::span<Vec3> whole_positions) const;

  bool IsInner(int32_t whole_node) const {
    return whole_node >= 0 && whole_node < static_cast<int32_t>(local_.size()) &&
           local_[whole_node] >= 0 && local_[whole_node] < inner_;
  }
  const Vec3& center() const { return center_; }
  double radius() const { return radius_; }
  int32_t inner_nodes() const { return inner_; }
  /// Whole-node ids of the patch's nodes, inner ones first.
  std::span<const int32_t> nodes() const { return global_; }
  const SimObject& object() const { return *object_; }
  SimObject& object() { return *object_; }

 private:
  Patch() = default;

  std::unique_ptr<SimObject> object_;
  std::vector<int32_t> global_;  // patch node -> whole node; inner nodes first
  std::vector<int32_t> local_;   // whole node -> patch node, or -1
  int32_t inner_ = 0;
  std::vector<uint8_t> tool_;        // 1: the inner node has a tool force
  std::vector<int32_t> tool_nodes_;  // inner nodes with a tool force (capacity reserved)
  Vec3 center_ = Vec3::Zero();
  double radius_ = 0.0;
};

/// Sums node forces over a window of ticks in fixed memory (open addressing): Add never
/// allocates. A window holds `capacity` distinct nodes (a tool touches at most 24 per tick); a
/// force on a node past that is dropped and counted.
class ForceWindow {
 public:
  explicit ForceWindow(int32_t capacity = 2048);
  /// Adds force x duration [N s] on `node`, with the force's stiffness [N/m] (its -dF/dx) and
  /// the node's position `at` when the force was taken [m]; false when the window is full
  /// (counted).
  bool Add(int32_t node, const Vec3& force, double dt, double stiffness = 0.0,
           const Vec3& at = Vec3::Zero());
  /// Entries so far; their averages over the window's duration are force_sum / duration().
  struct Entry {
    int32_t node = -1;
    Vec3 impulse = Vec3::Zero();  // [N s]
    double k_dt = 0.0;            // stiffness x duration [N s/m]
    Vec3 kx_dt = Vec3::Zero();    // stiffness x position x duration [N s]
  };
  std::span<const Entry> entries() const { return {used_.data(), used_count_}; }
  double duration() const { return duration_; }
  void AddDuration(double dt) { duration_ += dt; }
  /// The window's average load on each node becomes the whole's external force (all other
  /// external forces cleared): the load of its next step. A load with stiffness is averaged as
  /// the linear model F_t - k_t (x - x_t) it stands for, and reaches the whole as a spring
  /// (SimObject::SetExternalForce), which its implicit step takes into its system: against a
  /// coupling stiffer than the object, a constant average force over a step of N ticks
  /// overshoots and the exchange diverges (sim_bench multirate: N >= 5 at 500 N/m).
  void ApplyAverage(SimObject& whole) const;
  void Clear();
  int64_t overflowed() const { return overflowed_; }  // since the last Clear

 private:
  std::vector<int32_t> slot_;  // hash slot -> index into used_, or -1
  std::vector<Entry> used_;
  size_t used_count_ = 0;
  double duration_ = 0.0;
  int64_t overflowed_ = 0;
};

/// A tool force on one node of the whole [N].
struct NodeLoad {
  int32_t node = 0;
  Vec3 force = Vec3::Zero();
  double stiffness = 0.0;  ///< -dF/dx of the load [N/m] (isotropic), e.g. a coupling spring's
};

struct MultiRateCounts {
  int64_t ticks = 0;
  int64_t syncs = 0;          // whole steps taken
  int64_t rebuilds = 0;       // patches built (the first included)
  int64_t outside_loads = 0;  // tool loads on nodes outside the patch (the whole alone felt them)
  int64_t window_overflow = 0;
  int64_t patch_restores = 0;
};

/// The coupling itself: the whole stepped every `period` ticks by `period` x dt with the average
/// of the tool loads over the window before, the patch every tick. Tick() runs both in sequence
/// (offline, tests, benchmarks); a caller that runs the whole on its own thread calls Sync() and
/// FastTick() on the tick's thread and StepWhole() on the other, one whole step in flight.
class MultiRate {
 public:
  /// Takes the whole over. Allocates. INVALID_ARGUMENT for a period outside [1, 1000].
  static Result<MultiRate> Create(std::unique_ptr<SimObject> whole, int32_t period,
                                  const PatchOptions& options);

  /// One tick of dt with this tick's loads, the tool near `focus` (the proxy) [m].
  StepResult Tick(std::span<const NodeLoad> loads, const Vec3& focus, double dt);

  /// The whole has reached its next state: the patch follows it (built again around `focus` when
  /// the focus has left the inner half of its radius: that allocates), the render positions take
  /// its state, and the window just closed becomes the load of the whole's next step.
  void Sync(const Vec3& focus);
  /// The whole's step over the period (the slow part).
  StepResult StepWhole(double dt);

  /// The same split for a tick's thread that must not allocate (the daemon's loop): the patch is
  /// built on the whole's thread, between its steps, and handed over at the sync.
  ///
  /// Whether the patch should be built again for `focus`: there is none, or the focus has moved
  /// more than half its radius from where it was built. Tick's thread.
  bool WantsPatch(const Vec3& focus) const;
  /// A patch of the whole's current state around `focus` (allocates; the whole's thread, while
  /// the whole is not stepping). INVALID_ARGUMENT when no free node lies near the focus.
  Result<Patch> BuildPatch(const Vec3& focus) const;
  /// Sync without building: with `replace`, the patch and `exchange` swap (an empty `exchange`
  /// drops the patch), so `exchange` then holds the old patch, to be freed on another thread;
  /// without, the patch follows the whole. Does not allocate. Tick's thread, whole not stepping.
  /// `refresh`: the patch did not step since the last sync (no tool load): all its nodes take the
  /// whole's state (Patch::Follow with inner nodes).
  void Sync(std::optional<Patch>& exchange, bool replace, bool refresh = false);
  /// The patch's boundary holds still until the next sync (Patch::HoldBoundary). Tick's thread.
  void HoldPatchBoundary() {
    if (patch_) patch_->HoldBoundary();
  }
  /// Duration of the window that the whole's next step takes as its load [s]: the ticks since
  /// the sync before the last. A whole that runs late steps over the time it missed.
  double window_duration() const { return closed_.duration(); }
  /// `given` with the implicit substeps of one whole step: `period` ticks of options.tick in
  /// substeps of at most options.whole_substep (and no fewer than a tick takes).
  static Parameters WholeParameters(const Parameters& given, int32_t period,
                                    const PatchOptions& options);
  /// New parameters for the whole (its substeps made for its period again) and for the patches
  /// built from now on. The whole's thread; allocates.
  /// Taken by value: Create passes the whole's own parameters, which this changes.
  Status SetParameters(Parameters params);
  /// Twice the whole's substeps per step (at most `max_substeps`), e.g. after its step had to be
  /// restored (a drop onto the floor that its substeps did not hold). Kept until SetParameters.
  /// The whole's thread; returns the substeps now.
  int32_t RefineWholeSubsteps(int32_t max_substeps);
  int32_t whole_substeps() const { return whole_substeps_; }
  /// The patch's tick with the tool's loads.
  StepResult FastTick(std::span<const NodeLoad> loads, double dt);
  /// A tick in which the patch waits (no tool load): the window's duration grows, nothing steps;
  /// the next Sync should refresh the patch.
  void IdleTick(double dt) {
    ++counts_.ticks;
    filling_.AddDuration(dt);
  }

  /// The surface to render against: the whole at its last sync, the patch's inner nodes over it.
  std::span<const Vec3> positions() const { return render_; }
  const SimObject& whole() const { return *whole_; }
  SimObject& whole() { return *whole_; }
  const Patch* patch() const { return patch_ ? &*patch_ : nullptr; }
  int32_t period() const { return period_; }
  const MultiRateCounts& counts() const { return counts_; }

 private:
  MultiRate() = default;

  std::unique_ptr<SimObject> whole_;
  std::optional<Patch> patch_;
  PatchOptions options_;
  Parameters patch_params_;  // the whole's as given (its substeps per tick)
  int32_t period_ = 1;
  int32_t whole_substeps_ = 1;
  std::vector<Vec3> render_;
  ForceWindow filling_, closed_;  // this window's loads; the last window's, the whole's load
  MultiRateCounts counts_;
};

}  // namespace rheo::sim
